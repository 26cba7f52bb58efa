"""Follow a fixed list of waypoints: the simplest route agent."""

from __future__ import annotations

import numpy as np


class WaypointPolicy:
    """Issue each waypoint (x, z) as the target until the character is within `radius` of it.

    Args:
        waypoints: (K, 2) or (K, 3) world waypoints; a time column is ignored (the env's route
            keeps timing; an agent only points at places).
        radius: distance in metres at which the next waypoint becomes the target.
    """

    def __init__(self, waypoints: np.ndarray, radius: float = 0.5) -> None:
        wp = np.asarray(waypoints, dtype=np.float32)
        if wp.ndim != 2 or wp.shape[1] not in (2, 3) or len(wp) == 0:
            raise ValueError(f"waypoints must have shape (K, 2) or (K, 3) with K >= 1, got {wp.shape}")
        if not np.isfinite(wp[:, :2]).all():  # a NaN time marks an untimed waypoint (docs/conventions.md)
            raise ValueError("waypoints contain NaN or infinite x/z values")
        if radius <= 0:
            raise ValueError(f"radius must be positive, got {radius}")
        self.waypoints = wp[:, :2].copy()
        self.radius = float(radius)
        self.index = 0

    def reset(self) -> None:
        self.index = 0

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        position = np.asarray(obs["root"][:2], dtype=np.float32)
        # Advance past every waypoint already reached (a fast character may pass two in a frame).
        while (
            self.index < len(self.waypoints) - 1
            and np.linalg.norm(self.waypoints[self.index] - position) < self.radius
        ):
            self.index += 1
        return self.waypoints[self.index].copy()
