"""The path controller's state: what a roll-out carries from one frame to the next, batched over
characters, with row-wise access (the stream advances, restores and resets some characters only).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
import torch


@dataclass
class ControllerState:
    """Everything a rollout carries from one frame to the next, batched over B characters.

    Attributes:
        pos: (B, 2) world x, z of the current frame.
        theta: (B,) heading of the current frame (unwrapped).
        vel: (B, 3) the last step as (lateral m/s, forward m/s, turn rad/s) in the heading frame.
        hidden: (B, hidden) GRU state.
        frame: (B,) long, index of the current frame in each character's episode.
        text: (B, text_dim) caption embeddings.
        waypoints: (B, K, 3) x, z, frame index (NaN = untimed), padded past ``count``.
        count: (B,) long, number of real waypoints (0 = no route: follow the caption).
        queue: (B,) long, index of the current target waypoint.
    """

    pos: torch.Tensor
    theta: torch.Tensor
    vel: torch.Tensor
    hidden: torch.Tensor
    frame: torch.Tensor
    text: torch.Tensor
    waypoints: torch.Tensor
    count: torch.Tensor
    queue: torch.Tensor

    def take(self, rows: torch.Tensor) -> ControllerState:
        """The state of `rows` only."""
        return ControllerState(**{f.name: getattr(self, f.name)[rows] for f in fields(ControllerState)})

    def put(self, rows: torch.Tensor, sub: ControllerState) -> ControllerState:
        """A copy of this state with `rows` replaced by the rows of `sub` (waypoints padded to the
        wider of the two by repeating the last slot, the controller's own padding)."""
        values = {}
        for f in fields(ControllerState):
            full, part = getattr(self, f.name), getattr(sub, f.name)
            if f.name == "waypoints":
                k = max(full.shape[1], part.shape[1])
                full, part = _pad_waypoints(full, k), _pad_waypoints(part, k)
            full = full.clone()
            full[rows] = part.to(full.dtype)
            values[f.name] = full
        return ControllerState(**values)

    @property
    def root(self) -> torch.Tensor:
        """(B, 3) x, z, heading of the current frame."""
        return torch.cat([self.pos, self.theta[:, None]], dim=-1)


@dataclass
class Trace:
    """Per-frame outputs of :meth:`PathController.run` over frames 1..n of the rollout.

    Attributes:
        roots: (B, n, 3) x, z, heading.
        vel, hidden, queue: (B, n, 3), (B, n, hidden), (B, n) long, or None unless traced.
    """

    roots: torch.Tensor
    vel: torch.Tensor | None = None
    hidden: torch.Tensor | None = None
    queue: torch.Tensor | None = None


def _pad_waypoints(wp: torch.Tensor, k: int) -> torch.Tensor:
    """(B, K, 3) -> (B, k, 3) by repeating the last slot (the controller's own padding)."""
    if wp.shape[1] >= k:
        return wp
    return torch.cat([wp, wp[:, -1:].expand(-1, k - wp.shape[1], -1)], dim=1)


# The fields of ControllerState a StateRing keeps per frame (the caption and the route stay as
# they are: a roll-back keeps the current ones).
_RECORDED = ("pos", "theta", "vel", "hidden", "queue")


class StateRing:
    """The controller's state of B characters at each of their last `size` frames, indexed by
    frame % size: the stream rolls a character back to its last decoded frame when its caption or
    route changes, and reads the controller's root path of the frames ahead.

    Attributes:
        hidden, pos, theta, vel, queue: (B, size, ...) tensors, the fields of
            :class:`ControllerState` per frame.
        roots: (B, size, 3) float32 numpy, the controller's x, z, heading per frame.
    """

    def __init__(self, batch: int, size: int, hidden: int, device: torch.device | str) -> None:
        self.size = size
        self.hidden = torch.zeros(batch, size, hidden, device=device)
        self.pos = torch.zeros(batch, size, 2, device=device)
        self.theta = torch.zeros(batch, size, device=device)
        self.vel = torch.zeros(batch, size, 3, device=device)
        self.queue = torch.zeros(batch, size, dtype=torch.long, device=device)
        self.roots = np.zeros((batch, size, 3), np.float32)

    def record(self, rows: torch.Tensor, state: ControllerState) -> None:
        """Store the state of `rows` (the rows of `state`) at their current frame."""
        slot = (state.frame % self.size).to(rows.device)
        self.hidden[rows, slot] = state.hidden
        self.pos[rows, slot] = state.pos
        self.theta[rows, slot] = state.theta
        self.vel[rows, slot] = state.vel
        self.queue[rows, slot] = state.queue
        self.roots[rows.cpu().numpy(), slot.cpu().numpy()] = state.root.cpu().numpy()

    def record_trace(self, rows: torch.Tensor, first: torch.Tensor, trace: Trace) -> None:
        """Store frames first+1 .. first+n of `rows` (a controller run's trace)."""
        n = min(trace.roots.shape[1], self.size)  # older frames would be overwritten anyway
        offsets = torch.arange(trace.roots.shape[1] - n + 1, trace.roots.shape[1] + 1, device=first.device)
        slot = ((first[:, None] + offsets[None]) % self.size).to(rows.device)  # (N, n)
        at = (rows[:, None], slot)
        self.hidden[at] = trace.hidden[:, -n:]
        self.pos[at] = trace.roots[:, -n:, :2]
        self.theta[at] = trace.roots[:, -n:, 2]
        self.vel[at] = trace.vel[:, -n:]
        self.queue[at] = trace.queue[:, -n:]
        self.roots[rows.cpu().numpy()[:, None], slot.cpu().numpy()] = trace.roots[:, -n:].cpu().numpy()

    def record_roots(self, rows: np.ndarray, after: np.ndarray, roots: np.ndarray, count: np.ndarray) -> None:
        """Store the roots only (not a controller state: a prediction, never restored) of frames
        after+1 .. after+count[n] of each row n: `roots` (N, H, 3), count (N,) <= H."""
        k = np.arange(roots.shape[1])
        keep = k[None] < count[:, None]  # (N, H)
        slots = (after[:, None] + 1 + k[None]) % self.size
        at = np.broadcast_to(rows[:, None], slots.shape)
        self.roots[at[keep], slots[keep]] = roots[keep]

    def restore(self, state: ControllerState, rows: torch.Tensor, frames: torch.Tensor) -> ControllerState:
        """`state` with `rows` rolled back to their recorded state at `frames` (one each)."""
        slots = frames % self.size
        recorded = {name: getattr(self, name)[rows, slots] for name in _RECORDED}  # gathered: new tensors
        in_order = torch.arange(len(rows), device=rows.device)
        # Every row in order (a vector env's learners): no take and put, the caption and route as they are.
        if len(rows) == len(state.frame) and bool((rows == in_order).all()):
            return replace(state, **recorded, frame=frames.to(state.frame.dtype))
        sub = state.take(rows)
        for name, value in recorded.items():
            setattr(sub, name, value)
        sub.frame = frames
        return state.put(rows, sub)
