"""Random episodes: a start pose and a route of waypoints drawn from the env's random generator."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from motion_env.envs.arena import Obstacle, obstacle_distance
from motion_env.envs.config import EnvConfig

# Random routes: legs of this length (m), each turning at most this much from the previous one.
_LEG_LENGTH = (1.5, 3.5)
_MAX_TURN = 0.5 * np.pi
_ROUTE_CLEARANCE = 0.6  # random waypoints keep this far (m) from obstacles and the arena's edge


def sample_start(rng: np.random.Generator, config: EnvConfig, obstacles: Sequence[Obstacle]) -> np.ndarray:
    """(3,) start pose: the origin facing +Z, or (random_start) a free spot and heading in the arena."""
    if not config.random_start:
        return np.zeros(3)
    half = 0.5 * config.arena_size
    for _ in range(100):
        x, z = rng.uniform(-half, half, size=2)
        if obstacle_distance(np.array([x, z]), obstacles) > _ROUTE_CLEARANCE:
            break
    return np.array([x, z, rng.uniform(-np.pi, np.pi)])


def sample_route(
    rng: np.random.Generator,
    start: np.ndarray,
    config: EnvConfig,
    obstacles: Sequence[Obstacle],
    num: int | None = None,
) -> np.ndarray:
    """A random untimed route (K, 3) from `start`: legs of 1.5-3.5 m, turns of at most 90 degrees.

    Waypoints keep clear of obstacles and inside the arena (after a bounded number of tries the
    last candidate is used, pulled inside the arena).
    """
    if num is None:
        num = int(rng.integers(config.route_length[0], config.route_length[1] + 1))
    limit = max(config.arena_size - _ROUTE_CLEARANCE, 0.5 * config.arena_size)
    pos, direction = start[:2].astype(np.float64), float(start[2])
    out = np.full((num, 3), np.nan)
    for i in range(num):
        spread = _MAX_TURN if i else _MAX_TURN * 2.0 / 3.0
        for _ in range(50):
            heading = direction + rng.uniform(-spread, spread)
            point = pos + rng.uniform(*_LEG_LENGTH) * np.array([np.sin(heading), np.cos(heading)])
            inside = (np.abs(point) <= limit).all()
            if inside and obstacle_distance(point, obstacles) > _ROUTE_CLEARANCE:
                break
            spread = min(np.pi, spread * 1.1)  # widen the search when boxed in
        out[i, :2] = np.clip(point, -limit, limit)
        pos, direction = out[i, :2], heading
    return out.astype(np.float32)
