"""Requests, checked once at the boundary: captions, routes, starts, clip length and seed.

Every public entry point of the generator (whole clips, the stream, the environments through the
stream) passes its arguments through these functions and hands the validated values inward; the
stages of :mod:`motion_env.generation.pipeline` trust them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from motion_env.motion.checks import check_finite
from motion_env.motion.trajectory import validate_waypoints

__all__ = [
    "BatchRequest",
    "check_batch_request",
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
    if isinstance(num_frames, bool) or not float(num_frames).is_integer():
        raise ValueError(f"num_frames must be a whole number of frames, got {num_frames!r}")
    if int(num_frames) < 1:
        raise ValueError(f"num_frames must be >= 1, got {num_frames}")
    return int(num_frames)


def check_start(start: Any, what: str = "start") -> np.ndarray:
    arr = np.asarray(start, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{what} must be (x, z, heading), shape (3,), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    return arr.astype(np.float32)


def check_starts(starts: Any, batch: int) -> np.ndarray:
    if starts is None:
        return np.zeros((batch, 3), np.float32)
    arr = np.asarray(starts, dtype=np.float64)
    if arr.shape != (batch, 3):
        raise ValueError(
            f"starts must have shape ({batch}, 3) (x, z, heading per character), got {arr.shape}"
        )
    check_finite(arr, "starts")
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
    if seed is None:
        return int(np.random.SeedSequence().generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))
    if isinstance(seed, bool) or int(seed) != seed:
        raise ValueError(f"seed must be an integer or None, got {seed!r}")
    return int(seed)


def check_route(waypoints: Any) -> np.ndarray | None:
    """None (no route) or one (K, 2)/(K, 3) route -> None or the (K, 3) float32 route, NaN = untimed."""
    return None if waypoints is None else validate_waypoints(waypoints)


@dataclass(frozen=True)
class BatchRequest:
    """A validated request for B characters.

    Attributes:
        texts: B stripped, non-empty captions.
        routes: B entries, each None or a (K, 3) float32 route (NaN time = untimed).
        starts: (B, 3) float32 x, z, heading of frame 0.
        num_frames: frames per clip (>= 1).
        seed: the resolved seed (a fresh one when the caller gave None).
    """

    texts: list[str]
    routes: list[np.ndarray | None]
    starts: np.ndarray
    num_frames: int
    seed: int


def check_batch_request(
    texts: Sequence[str], waypoints: Any, num_frames: Any, seed: int | None, starts: Any
) -> BatchRequest:
    """Check every argument of a batch request once and return the validated values."""
    texts = check_texts(texts)
    return BatchRequest(
        texts=texts,
        routes=per_row_waypoints(waypoints, len(texts)),
        starts=check_starts(starts, len(texts)),
        num_frames=check_num_frames(num_frames),
        seed=resolve_seed(seed),
    )
