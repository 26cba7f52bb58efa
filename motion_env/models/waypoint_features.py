"""What the path controller reads of its route: the waypoint features, the queue of waypoints
and the heading-frame transforms (:mod:`motion_env.models.controller` runs them every frame).

The features split in two: the part that depends on the route and the queue only
(:func:`route_view`, made again only when a waypoint is passed) and the part that depends on
where the character is (:func:`slot_features`, every frame), so that a roll-out does not index
and re-pad the route at every frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from motion_env.models.frame_ops import TORCH, Array, Constants, TorchOps
from motion_env.motion.trajectory import validate_waypoints

# Features per waypoint slot (see PathController.waypoint_features).
WAYPOINT_FEATURES = 9


def step_input_dim(text_proj: int, num_slots: int) -> int:
    """Width of what the controller reads each frame: the projected caption, the waypoint slots
    and its own previous step (lateral, forward, turn)."""
    return text_proj + num_slots * WAYPOINT_FEATURES + 3


def to_heading_frame_torch(vec: Array, theta: Array, ops: TorchOps = TORCH) -> Array:
    """Torch twin of :func:`motion_env.motion.to_heading_frame`: world (..., 2) -> (lateral, forward)
    (on numpy arrays with ``ops`` a :class:`~motion_env.models.frame_ops.NumpyOps`)."""
    c, s = ops.cos(theta), ops.sin(theta)
    return ops.stack([vec[..., 0] * c - vec[..., 1] * s, vec[..., 0] * s + vec[..., 1] * c], -1)


def from_heading_frame_torch(vec: Array, theta: Array, ops: TorchOps = TORCH) -> Array:
    """Torch twin of :func:`motion_env.motion.from_heading_frame`: (lateral, forward) -> world (..., 2)."""
    c, s = ops.cos(theta), ops.sin(theta)
    return ops.stack([vec[..., 0] * c + vec[..., 1] * s, -vec[..., 0] * s + vec[..., 1] * c], -1)


@dataclass
class RouteView:
    """What the controller reads of each character's route from its current target on: the part
    of the waypoint features that depends on the route and the queue only (:func:`route_view`).

    Attributes:
        xy: (B, S, 2) world x, z of the S slots (the target and the waypoints after it, the last
            one repeated); xy_prev: (B, S - 1, 2) its first S - 1 rows.
        time: (B, S) their frame index; -inf where untimed (their time to go is 0).
        timed: (B, S) bool; timed_flag, is_last, valid: (B, S) float flags (valid: any route).
        final: (B,) bool, the current target is the last waypoint; any_final: whether any is.
        due: (B,) the frame at which the current target is passed (+inf: untimed, or the last).
        near: (B,) bool, the current target is passed by coming within the arrive radius
            (untimed, not the last); any_near: whether any is.
        all_valid: every character has a route.
    """

    xy: torch.Tensor
    xy_prev: torch.Tensor
    time: torch.Tensor
    timed: torch.Tensor
    timed_flag: torch.Tensor
    is_last: torch.Tensor
    valid: torch.Tensor
    final: torch.Tensor
    due: torch.Tensor
    near: torch.Tensor
    any_final: bool
    any_near: bool
    all_valid: bool


def route_view(
    waypoints: torch.Tensor, count: torch.Tensor, queue: torch.Tensor, num_slots: int
) -> RouteView:
    """The :class:`RouteView` of (B, K, 3) waypoints with (B,) counts and queues."""
    b = waypoints.shape[0]
    dev = waypoints.device
    slots = queue[:, None] + torch.arange(num_slots, device=dev)[None]
    slots = torch.minimum(slots, (count - 1).clamp(min=0)[:, None])  # (B, S)
    wp = waypoints[torch.arange(b, device=dev)[:, None], slots]  # (B, S, 3)
    timed = ~torch.isnan(wp[..., 2])
    time = torch.where(timed, wp[..., 2], -torch.inf)
    has_route = count > 0
    final = has_route & (queue == count - 1)
    can_move = queue < count - 1
    near = ~timed[:, 0] & can_move
    return RouteView(
        xy=wp[..., :2],
        xy_prev=wp[:, :-1, :2],
        time=time,
        timed=timed,
        timed_flag=timed.float(),
        is_last=(slots == (count - 1)[:, None]).float(),
        valid=has_route[:, None].expand(b, num_slots).float(),
        final=final,
        due=torch.where(timed[:, 0] & can_move, wp[:, 0, 2], torch.inf),
        near=near,
        any_final=bool(final.any()),
        any_near=bool(near.any()),
        all_valid=bool(has_route.all()),
    )


def slot_features(
    view: RouteView,
    pos: Array,
    theta: Array,
    frame: Array,
    max_time_to_go: float,
    const: Constants,
    ops: TorchOps = TORCH,
) -> tuple[Array, Array]:
    """The waypoint features of characters at (B, 2) `pos`, (B,) `theta` and (B, 1) float `frame`
    (see :meth:`PathController.waypoint_features`): ((B, S * 9) features, (B, 2) offset to the
    current target in the heading frame). On numpy arrays with `ops` and `view` from
    :class:`~motion_env.models.frame_ops.NumpyOps`."""
    b = view.xy.shape[0]
    # (pos[:, None] is made twice: one shared node would sum the gradients in another order.)
    offset = to_heading_frame_torch(view.xy - pos[:, None], theta[:, None], ops)  # (B, S, 2)
    dist = ops.norm(offset)  # (B, S)
    ttg = ops.clip((view.time - frame) / const.fps, min=0.0, max=max_time_to_go)  # untimed: 0
    speed = ops.clip(ops.where(view.timed, dist / (ttg + const.quarter), 0.0), max=10.0)
    seg = ops.norm(view.xy - ops.cat([pos[:, None], view.xy_prev], 1))
    feats = ops.stack(
        [
            offset[..., 0] / ops.clip(dist, min=1.0),
            offset[..., 1] / ops.clip(dist, min=1.0),
            ops.log1p(dist),
            view.timed_flag,
            ttg,
            speed,
            view.is_last,
            view.valid,
            ops.log1p(seg),
        ],
        -1,
    )  # (B, S, 9)
    if not view.all_valid:
        feats = feats * view.valid[..., None]
    return feats.reshape(b, -1), offset[:, 0]


def next_queue(
    waypoints: torch.Tensor,
    count: torch.Tensor,
    queue: torch.Tensor,
    pos: torch.Tensor,
    frame: torch.Tensor,
    arrive_radius: float,
) -> torch.Tensor:
    """(B,) long: each character's target moved past the waypoints it has reached (timed: their
    frame reached; untimed: within `arrive_radius`), never past its last one. The target stops
    at the first waypoint from the current one on that is not reached."""
    k = waypoints.shape[1]
    times = waypoints[..., 2]
    timed = ~torch.isnan(times)
    passed_time = timed & (times.nan_to_num(0.0) <= frame.to(torch.float32)[:, None])
    near = ~timed & ((waypoints[..., :2] - pos.detach()[:, None]).norm(dim=-1) < arrive_radius)
    index = torch.arange(k, device=queue.device)[None]
    stop = ~(passed_time | near) | (index >= (count - 1)[:, None])
    stop = stop & (index >= queue[:, None])  # always true somewhere: the last index is >= count - 1
    return stop.to(torch.uint8).argmax(dim=1)  # the first stop


def pack_waypoints(
    waypoints: list[np.ndarray | list | None] | None, batch: int, device: torch.device | str = "cpu"
) -> tuple[torch.Tensor, torch.Tensor]:
    """Validate per-character waypoints and pad them into one tensor.

    Args:
        waypoints: None (no route for anyone) or a list of B entries, each None or a (K, 2)/(K, 3)
            array accepted by :func:`motion_env.motion.trajectory.validate_waypoints`.
        batch: B.

    Returns:
        ((B, Kmax, 3) float32 padded by repeating the last row, (B,) long counts).
    """
    if waypoints is None:
        waypoints = [None] * batch
    if len(waypoints) != batch:
        raise ValueError(f"got {len(waypoints)} waypoint lists for {batch} characters")
    rows = [None if w is None else validate_waypoints(w) for w in waypoints]
    kmax = max([1] + [len(r) for r in rows if r is not None])
    out = np.zeros((batch, kmax, 3), np.float32)
    counts = np.zeros(batch, np.int64)
    for b, r in enumerate(rows):
        if r is None:
            continue
        out[b, : len(r)] = r
        out[b, len(r) :] = r[-1]
        counts[b] = len(r)
    return torch.from_numpy(out).to(device), torch.from_numpy(counts).to(device)
