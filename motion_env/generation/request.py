"""Requests, checked once at the boundary: captions, routes, starts, clip length and seed.

Every public entry point of the generator (whole clips, the stream, the environments through the
stream) passes its arguments through these functions and hands the validated values inward; the
stages of :mod:`motion_env.generation.pipeline` trust them.

Bounds (``docs/conventions.md``, "Limits"):

- a clip has 1 to :data:`MAX_FRAMES` frames (the cost of a request grows with what it asks);
- waypoint and start coordinates lie within :data:`~motion_env.motion.trajectory.MAX_COORDINATE`
  metres of the origin (float32 keeps millimetres there);
- a seed is an integer in [0, 2**64);
- timed waypoints must be reachable: the speed they ask for (along the route, from the start or
  the previous timed waypoint) is at most :data:`MAX_SPEED`. An impossible request raises a
  ValueError naming the waypoint and the speed (times are frames at 20 fps: seconds given as
  frames are the usual cause); with ``infeasible="warn"`` it is retimed to the fastest feasible
  timing instead, with a warning that says which waypoint moved from which frame to which.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from motion_env.generation.request_controls import (
    check_joint_targets,
    check_objectives,
    per_row_controls,
)
from motion_env.joint_targets import JointTargets
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import MAX_COORDINATE, validate_waypoints
from motion_env.motion.validation import check_finite

MAX_FRAMES = 12_000
"""The longest clip a request may ask for: 10 minutes at 20 fps."""
MAX_SPEED = 8.0
"""Metres per second: the fastest a timed route may ask the pelvis to go (a sprint; the shipped
model runs at up to about 3.5 m/s, so faster routes are followed with sliding feet)."""
SPRINT_SPEED = 4.5
"""Metres per second: the fastest the training takes move (their fastest second: 4.7 m/s, the 99th
percentile 3.8). A timed route that asks for more is followed, with a warning naming the frames:
the body cannot keep pace with such a root, so its feet slide."""
MAX_SEED = 2**64
INFEASIBLE_MODES = ("raise", "warn")

__all__ = [
    "INFEASIBLE_MODES",
    "MAX_FRAMES",
    "MAX_SEED",
    "MAX_SPEED",
    "SPRINT_SPEED",
    "BatchRequest",
    "check_batch_request",
    "check_feasible",
    "check_request",
    "check_num_frames",
    "check_route",
    "check_start",
    "check_starts",
    "check_text",
    "check_texts",
    "per_row_waypoints",
    "resolve_seed",
]


def check_text(text: Any, what: str = "text") -> str:
    if not isinstance(text, str):
        raise TypeError(f"{what} must be a string caption, got {type(text).__name__}")
    if not text.strip():
        raise ValueError(f"{what} is empty: give a caption such as 'a person walks forward'")
    return text.strip()


def check_texts(texts: Sequence[str]) -> list[str]:
    if isinstance(texts, str):
        raise TypeError("texts must be a list of captions, not a single string")
    out = [check_text(t, f"texts[{i}]") for i, t in enumerate(texts)]
    if not out:
        raise ValueError("texts is empty: give at least one caption")
    return out


def check_num_frames(num_frames: Any) -> int:
    """A clip length: an integer number of frames in [1, MAX_FRAMES]."""
    if isinstance(num_frames, bool) or not isinstance(num_frames, int | float | np.integer | np.floating):
        raise TypeError(f"num_frames must be a whole number of frames, got {num_frames!r}")
    if not (math.isfinite(num_frames) and float(num_frames).is_integer()):
        raise ValueError(f"num_frames must be a whole number of frames, got {num_frames!r}")
    if not 1 <= int(num_frames) <= MAX_FRAMES:
        raise ValueError(
            f"num_frames must be between 1 and {MAX_FRAMES} ({MAX_FRAMES // FPS // 60} minutes at "
            f"{FPS} fps), got {int(num_frames)}"
        )
    return int(num_frames)


def check_start(start: Any, what: str = "start") -> np.ndarray:
    """(x, z, heading) of a first frame -> (3,) float32; finite, x and z within MAX_COORDINATE."""
    try:
        arr = np.asarray(start, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be three numbers (x, z, heading), got {start!r}") from None
    if arr.shape != (3,):
        raise ValueError(f"{what} must be (x, z, heading), shape (3,), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    _check_range(arr[None, :2], what)
    return arr.astype(np.float32)


def _check_range(xz: np.ndarray, what: str) -> None:
    far = np.nonzero(np.abs(xz).max(axis=-1) > MAX_COORDINATE)[0]
    if len(far):
        raise ValueError(
            f"{what}: x and z must lie within {MAX_COORDINATE:g} m of the origin, "
            f"rows {far[:10].tolist()} do not (largest {np.abs(xz).max():.4g} m)"
        )


def check_starts(starts: Any, batch: int) -> np.ndarray:
    """None (every character at the origin facing +Z) or (B, 3) x, z, heading -> (B, 3) float32."""
    if starts is None:
        return np.zeros((batch, 3), np.float32)
    try:
        arr = np.asarray(starts, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"starts must be numbers, shape ({batch}, 3) (x, z, heading per character)"
        ) from None
    if arr.shape != (batch, 3):
        raise ValueError(
            f"starts must have shape ({batch}, 3) (x, z, heading per character), got {arr.shape}"
        )
    check_finite(arr, "starts")
    _check_range(arr[:, :2], "starts")
    return arr.astype(np.float32)


def _is_route(waypoints: Any) -> bool:
    """True when `waypoints` is one (K, 2)/(K, 3) numeric array (rather than one entry per character)."""
    try:
        arr = np.asarray(waypoints, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return arr.ndim == 2


def per_row_waypoints(waypoints: Any, batch: int) -> list[np.ndarray | None]:
    """None, one route for every character, or B entries (each None or a route) -> B checked routes."""
    if waypoints is None:
        return [None] * batch
    if _is_route(waypoints):
        route = validate_waypoints(waypoints)
        return [route.copy() for _ in range(batch)]
    if isinstance(waypoints, np.ndarray) and waypoints.ndim != 3:
        raise ValueError(
            f"waypoints must have shape (K, 2) or (K, 3) (or one per character), got {waypoints.shape}"
        )
    if not isinstance(waypoints, Sequence | np.ndarray) or len(waypoints) != batch:
        n = len(waypoints) if isinstance(waypoints, Sequence) else type(waypoints).__name__
        raise ValueError(
            f"waypoints must be None, one (K, 2)/(K, 3) array, or a list of {batch} entries "
            f"(one per character, each None or an array); got {n}"
        )
    out = []
    for i, w in enumerate(waypoints):
        try:
            out.append(None if w is None else validate_waypoints(w))
        except ValueError as exc:
            raise ValueError(f"waypoints of character {i}: {exc}") from exc
    return out


def resolve_seed(seed: int | None) -> int:
    """None (a fresh random seed) or an integer in [0, 2**64) -> the seed."""
    if seed is None:
        return int(np.random.SeedSequence().generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        if not (isinstance(seed, float | np.floating) and math.isfinite(seed) and float(seed).is_integer()):
            raise TypeError(f"seed must be an integer or None, got {seed!r}")
    if not 0 <= int(seed) < MAX_SEED:
        raise ValueError(f"seed must be in [0, 2**64), got {int(seed)}")
    return int(seed)


def check_route(waypoints: Any) -> np.ndarray | None:
    """None (no route) or one (K, 2)/(K, 3) route -> None or the (K, 3) float32 route, NaN = untimed."""
    return None if waypoints is None else validate_waypoints(waypoints)


def check_feasible(
    route: np.ndarray | None,
    start_xz: np.ndarray,
    infeasible: str = "raise",
    first_frame: int = 0,
    what: str = "waypoints",
) -> np.ndarray | None:
    """Check that the timed waypoints of a route ask for a speed a person can reach.

    Between the start (at `first_frame`) or the previous timed waypoint and each timed waypoint,
    the distance along the route (through the untimed waypoints in between) over the time there
    must not ask for more than MAX_SPEED. Timed waypoints before `first_frame` (already passed)
    are not checked.

    Args:
        route: (K, 3) checked waypoints (NaN time = untimed) or None.
        start_xz: (2,) where the pelvis is at `first_frame`.
        infeasible: "raise" (ValueError) or "warn" (the waypoint is retimed to the fastest
            feasible frame, later ones keep their order, and a UserWarning says what moved).
        first_frame: the episode frame of `start_xz` (0 for a new clip).
        what: the argument's name in messages.

    Returns:
        The route, retimed where needed (a copy), or None.
    """
    if infeasible not in INFEASIBLE_MODES:
        raise ValueError(f"infeasible must be one of {INFEASIBLE_MODES}, got {infeasible!r}")
    if route is None:
        return None
    out = route.copy()
    anchor_xz, anchor_t, travelled = np.asarray(start_xz, np.float64)[:2], float(first_frame), 0.0
    prev_xz = anchor_xz
    for k, (x, z, t) in enumerate(out):
        travelled += float(np.hypot(x - prev_xz[0], z - prev_xz[1]))
        prev_xz = np.array([x, z], np.float64)
        if np.isnan(t) or t < first_frame:
            continue
        seconds = (t - anchor_t) / FPS
        speed = math.inf if seconds <= 0 else travelled / seconds
        if speed > MAX_SPEED and travelled > 0.05:
            fastest = anchor_t + math.ceil(travelled / MAX_SPEED * FPS)
            message = (
                f"{what}, row {k} (x={x:g}, z={z:g}, frame {route[k, 2]:g}) asks for {speed:.3g} m/s over "
                f"{travelled:.3g} m in {seconds:.3g} s; a person manages at most {MAX_SPEED:g} m/s. "
                f"Times are frame indices at {FPS} fps (seconds given as frames are the usual cause)"
            )
            if infeasible == "raise":
                raise ValueError(message + "; pass infeasible='warn' for a best effort.")
            warnings.warn(f"{message}: retimed to frame {fastest}.", UserWarning, stacklevel=4)
            out[k:, 2] += fastest - t  # later times keep their intervals (NaN stays NaN)
            t = float(out[k, 2])
        elif speed > SPRINT_SPEED and travelled > 0.05:
            warnings.warn(
                f"{what}, row {k} (x={x:g}, z={z:g}) asks for {speed:.3g} m/s between frames {anchor_t:g} "
                f"and {t:g}: faster than any motion the model learned (about {SPRINT_SPEED:g} m/s at most); "
                "the body will not keep pace with its path there and its feet will slide",
                UserWarning,
                stacklevel=4,
            )
        anchor_t, travelled = float(t), 0.0
    return out


def warn_past_the_end(route: np.ndarray | None, num_frames: int, what: str = "waypoints") -> None:
    """Warn about timed waypoints after a clip's last frame: the clip ends before they are reached."""
    if route is None:
        return
    late = np.nonzero(~np.isnan(route[:, 2]) & (route[:, 2] > num_frames - 1))[0]
    if len(late):
        k = int(late[0])
        warnings.warn(
            f"{what}, row {k}, is timed at frame {route[k, 2]:g}, after the clip's last frame "
            f"{num_frames - 1}: the clip ends before it is reached (ask for more frames, or times are "
            f"frames at {FPS} fps)",
            UserWarning,
            stacklevel=4,
        )


@dataclass(frozen=True)
class BatchRequest:
    """A validated request for B characters.

    Attributes:
        texts: B stripped, non-empty captions.
        routes: B entries, each None or a (K, 3) float32 route (NaN time = untimed), feasible.
        starts: (B, 3) float32 x, z, heading of frame 0.
        num_frames: frames per clip (1 to MAX_FRAMES).
        seed: the resolved seed (a fresh one when the caller gave None).
        joint_targets: per character, None or its :class:`~motion_env.joint_targets.JointTargets`
            (frames of the clip); None for the whole request when no character has joint targets
            or objectives.
        objectives: per character, a tuple of objectives (None as for `joint_targets`).
    """

    texts: list[str]
    routes: list[np.ndarray | None]
    starts: np.ndarray
    num_frames: int
    seed: int
    joint_targets: list[JointTargets | None] | None = None
    objectives: list[tuple[Any, ...]] | None = None


def check_batch_request(
    texts: Sequence[str],
    waypoints: Any,
    num_frames: Any,
    seed: int | None,
    starts: Any,
    infeasible: str = "raise",
    joint_targets: Any = None,
    objectives: Any = None,
) -> BatchRequest:
    """Check every argument of a batch request once and return the validated values (no model needed)."""
    texts = check_texts(texts)
    routes = per_row_waypoints(waypoints, len(texts))
    req = _route_request(texts, routes, check_starts(starts, len(texts)), num_frames, seed, infeasible)
    if joint_targets is None and objectives is None:
        return req
    targets, objs = per_row_controls(joint_targets, objectives, len(texts), req.num_frames)
    return _with_controls(req, targets, objs)


def _with_controls(req: BatchRequest, targets: list, objs: list) -> BatchRequest:
    if all(t is None for t in targets) and not any(objs):
        return req
    return replace(req, joint_targets=targets, objectives=objs)


def check_request(
    text: Any,
    waypoints: Any,
    num_frames: Any,
    seed: int | None,
    start: Any,
    infeasible: str = "raise",
    joint_targets: Any = None,
    objectives: Any = None,
) -> BatchRequest:
    """:func:`check_batch_request` for one character, with messages naming `text`, `waypoints`,
    `start`, `joint_targets` and `objectives` (a batch of one)."""
    starts = np.zeros((1, 3), np.float32) if start is None else check_start(start)[None]
    req = _route_request([check_text(text)], [check_route(waypoints)], starts, num_frames, seed, infeasible)
    if joint_targets is None and objectives is None:
        return req
    targets = [check_joint_targets(joint_targets, req.num_frames)]
    return _with_controls(req, targets, [check_objectives(objectives, num_frames=req.num_frames)])


def _route_request(
    texts: list[str],
    routes: list[np.ndarray | None],
    starts: np.ndarray,
    num_frames: Any,
    seed: int | None,
    infeasible: str,
) -> BatchRequest:
    """The checks that need the whole request: clip length, seed, feasibility of each route."""
    num_frames = check_num_frames(num_frames)
    for i, route in enumerate(routes):
        what = "waypoints" if len(routes) == 1 else f"waypoints of character {i}"
        routes[i] = check_feasible(route, starts[i, :2], infeasible, what=what)
        warn_past_the_end(routes[i], num_frames, what)
    return BatchRequest(texts, routes, starts, num_frames, resolve_seed(seed))
