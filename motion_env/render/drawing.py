"""What a picture shows around the figure, shared by the 3-D frames, the inset map and the path plot.

- the colours (left limbs blue, right limbs orange, red only for highlighted frames);
- the checks that turn caller inputs (joints, paths, waypoints, obstacles) into float arrays;
- small geometry helpers: floor rings, NaN-separated polylines, convex hulls.

World conventions (see :mod:`motion_env.motion.skeleton`): metres, Y up, floor at y = 0, the
character faces +Z at heading 0 and its left is +X. Floor points are given as (x, z).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from motion_env.motion.skeleton import NUM_JOINTS

# Left limbs blue, right limbs orange (a colour-blind-safe pair); red is reserved for
# highlighted frames so that it never means "right side".
LEFT_COLOR = "#1f6fd1"
RIGHT_COLOR = "#f08c1a"
SPINE_COLOR = "#3b4252"
HIGHLIGHT_COLOR = "#e03131"
TRAIL_COLOR = "#5c7cfa"
WAYPOINT_COLOR = "#9c36b5"
TARGET_COLOR = "#d6336c"
OBSTACLE_COLOR = "#868e96"
PASSED_COLOR = "#adb5bd"

MAX_LABELLED_WAYPOINTS = 30  # more waypoints than this are a dense trajectory: draw a line
RING_SEGMENTS = 24
MIN_SIZE = 64  # pixels: the smallest stick-figure picture


def hex_rgb(color: str) -> np.ndarray:
    """'#rrggbb' -> (3,) floats in [0, 1]."""
    return np.array([int(color[i : i + 2], 16) / 255 for i in (1, 3, 5)])


def check_size(width: Any, height: Any, minimum: int = MIN_SIZE) -> tuple[int, int]:
    """(width, height) if each is an int of at least `minimum` pixels, else ValueError naming it."""
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
            raise ValueError(f"{name} must be an int of at least {minimum} pixels, got {value!r}")
    return int(width), int(height)


def as_joints(joints: np.ndarray, what: str = "joints") -> np.ndarray:
    """A finite (22, 3) float64 pose, or ValueError."""
    arr = np.asarray(joints, dtype=np.float64)
    if arr.shape != (NUM_JOINTS, 3):
        raise ValueError(f"{what} must have shape ({NUM_JOINTS}, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} has NaN or infinite values")
    return arr


def as_xz(points: np.ndarray | Sequence | None, what: str) -> np.ndarray | None:
    """(N, 2) or (N, 3) points -> (N, 2) float x, z (a third column is a heading or a time)."""
    if points is None:
        return None
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"{what} must have shape (N, 2) or (N, 3), got {arr.shape}")
    if not np.isfinite(arr[:, :2]).all():
        raise ValueError(f"{what} has NaN or infinite coordinates")
    return arr[:, :2]


def as_waypoints(waypoints: np.ndarray | Sequence | None) -> np.ndarray | None:
    """(K, 2) / (K, 3) -> (K, 3) with the time column NaN for untimed waypoints."""
    if as_xz(waypoints, "waypoints") is None:  # shape and finite x, z
        return None
    arr = np.asarray(waypoints, dtype=np.float64)
    if arr.shape[1] == 2:
        arr = np.concatenate([arr, np.full((len(arr), 1), np.nan)], axis=1)
    bad = np.flatnonzero(np.isinf(arr[:, 2]) | (arr[:, 2] < 0))
    if len(bad):
        raise ValueError(
            f"waypoints have infinite or negative times (column 2: frame indices, NaN = untimed) at rows "
            f"{bad[:10].tolist()}"
        )
    return arr


def waypoint_time(frame: float, fps: float) -> str:
    """How every picture labels a timed waypoint: the frame index it was given in (as the API and
    the command line take it), then that time in seconds at `fps`: ``"f40 (2.0 s)"``."""
    return f"f{np.format_float_positional(float(frame), trim='-')} ({frame / fps:.1f} s)"


def as_obstacles(obstacles: np.ndarray | Sequence | None) -> np.ndarray | None:
    """(N, 3) circles x, z, radius."""
    if obstacles is None:
        return None
    arr = np.asarray(obstacles, dtype=np.float64)
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"obstacles must have shape (N, 3) as (x, z, radius), got {arr.shape}")
    if not np.isfinite(arr).all() or (arr[:, 2] <= 0).any():
        raise ValueError("obstacles need finite coordinates and positive radii")
    return arr


def obstacle_extent(obs: np.ndarray) -> np.ndarray:
    """(2N, 2) x, z corners of the squares around (N, 3) obstacle circles."""
    return np.concatenate([obs[:, :2] - obs[:, 2:], obs[:, :2] + obs[:, 2:]])


def with_breaks(pieces: Iterable[np.ndarray]) -> np.ndarray:
    """Join (n_i, D) polylines into one (N, D) array separated by NaN rows (one artist)."""
    out = []
    for p in pieces:
        out.append(p)
        out.append(np.full((1, p.shape[1]), np.nan))
    return np.concatenate(out[:-1]) if out else np.empty((0, 2))


def floor_ring(center_xz: np.ndarray, radius: float, y: float = 0.0) -> np.ndarray:
    """(RING_SEGMENTS + 1, 3) closed circle on the horizontal plane at height y."""
    a = np.linspace(0.0, 2 * np.pi, RING_SEGMENTS + 1)
    return np.stack(
        [center_xz[0] + radius * np.sin(a), np.full_like(a, y), center_xz[1] + radius * np.cos(a)], -1
    )


def convex_hull(points: np.ndarray) -> np.ndarray:
    """(N, 2) -> (M, 2) convex hull, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(map(tuple, points))
    if len(pts) < 3:
        return np.asarray(pts)

    def half(seq: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.asarray(lower[:-1] + upper[:-1])
