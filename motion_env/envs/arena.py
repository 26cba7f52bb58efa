"""The arena's obstacles: one model (circles and polygons on the floor) for the environments and the planner.

An obstacle is a circle ``(x, z, radius)`` or a polygon ``[(x, z), ...]`` of at least three
vertices, in world metres on the floor plane. :func:`validate_obstacles` checks a user's list once;
:func:`obstacle_distance` is the one signed distance (negative inside) that the environments'
collision term, their random routes and the A* planner (:mod:`policies.astar`) all use.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["Obstacle", "circles", "is_circle", "obstacle_distance", "validate_obstacles"]

Obstacle = tuple[float, float, float] | np.ndarray
"""A circle ``(x, z, radius)`` or a polygon, an (M, 2) float64 array of (x, z) vertices."""


def is_circle(obstacle: Any) -> bool:
    """True for three numbers ``(x, z, radius)``."""
    return len(obstacle) == 3 and all(np.ndim(v) == 0 for v in obstacle)


def validate_obstacles(obstacles: Sequence[Any] | np.ndarray | None) -> list[Obstacle]:
    """Check obstacles once: circles (x, z, r > 0) or polygons of >= 3 finite (x, z) vertices.

    Accepts None or an empty list (no obstacles), one circle ``(x, z, r)``, an (N, 3) array of
    circles, or a list mixing circles and polygons. Returns circles as float tuples and polygons
    as (M, 2) float64 arrays; a ValueError names the obstacle at fault.
    """
    if obstacles is None:
        return []
    if isinstance(obstacles, np.ndarray | Sequence) and len(obstacles) and is_circle(obstacles):
        obstacles = [obstacles]  # a single circle
    checked: list[Obstacle] = []
    for i, obstacle in enumerate(obstacles):
        try:
            circle = is_circle(obstacle)
        except TypeError:
            raise ValueError(
                f"obstacles[{i}]: expected a circle (x, z, radius) or a polygon [(x, z), ...], "
                f"got {obstacle!r}"
            ) from None
        if circle:
            try:
                x, z, r = (float(v) for v in obstacle)
            except (TypeError, ValueError):
                msg = f"obstacles[{i}]: a circle needs numbers (x, z, radius), got {obstacle!r}"
                raise ValueError(msg) from None
            if not (np.isfinite([x, z, r]).all() and r > 0):
                msg = f"obstacles[{i}]: a circle needs finite (x, z) and radius > 0, got {obstacle}"
                raise ValueError(msg)
            checked.append((x, z, r))
            continue
        try:
            poly = np.asarray(obstacle, dtype=np.float64)
        except (TypeError, ValueError):
            poly = np.zeros((0,))
        if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3 or not np.isfinite(poly).all():
            raise ValueError(
                f"obstacles[{i}]: expected a circle (x, z, radius) or a polygon of >= 3 finite (x, z) "
                f"vertices, got shape {poly.shape}"
            )
        checked.append(poly)
    return checked


def circles(obstacles: Sequence[Obstacle]) -> np.ndarray:
    """The circles among checked obstacles as an (N, 3) float64 array (x, z, radius)."""
    rows = [o for o in obstacles if is_circle(o)]
    return np.array(rows, dtype=np.float64).reshape(-1, 3)


def _points_in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule; points (N, 2), polygon (M, 2) -> (N,) bool."""
    x, z = points[:, 0:1], points[:, 1:2]
    x0, z0 = polygon[:, 0], polygon[:, 1]
    x1, z1 = np.roll(x0, -1), np.roll(z0, -1)
    crosses = (z0 > z) != (z1 > z)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = x0 + (z - z0) * (x1 - x0) / (z1 - z0)
    return (crosses & (x < x_at)).sum(axis=1) % 2 == 1


def _distance_to_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance from each point (N, 2) to the polygon's boundary (M, 2) -> (N,)."""
    a, b = polygon, np.roll(polygon, -1, axis=0)
    ab = b - a  # (M, 2)
    ap = points[:, None, :] - a[None]  # (N, M, 2)
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=-1).min(axis=1)


def obstacle_distance(points_xz: np.ndarray, obstacles: Sequence[Any] | np.ndarray | None) -> np.ndarray:
    """Signed distance (m) from points (..., 2) to the nearest obstacle: negative inside, +inf if none.

    `obstacles` as :func:`validate_obstacles` accepts them (already checked ones pass unchanged).
    """
    obstacles = validate_obstacles(obstacles)
    points = np.asarray(points_xz, dtype=np.float64)
    flat = points.reshape(-1, 2)
    best = np.full(len(flat), np.inf)
    for obstacle in obstacles:
        if is_circle(obstacle):
            x, z, r = obstacle
            d = np.linalg.norm(flat - np.array([x, z]), axis=1) - r
        else:
            d = _distance_to_polygon(flat, obstacle)
            d = np.where(_points_in_polygon(flat, obstacle), -d, d)
        best = np.minimum(best, d)
    return best.reshape(points.shape[:-1])
