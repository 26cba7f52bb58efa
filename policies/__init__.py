"""Agents for the motion_env environments.

Every policy has the same tiny interface: ``reset()`` before an episode and ``act(obs) -> action``
(a float32 (2,) world target (x, z) for ``action_mode="absolute"``).
"""

from policies.astar import AStarPolicy, OccupancyGrid, astar, smooth_path
from policies.random import RandomPolicy
from policies.waypoints import WaypointPolicy

__all__ = ["AStarPolicy", "OccupancyGrid", "RandomPolicy", "WaypointPolicy", "astar", "smooth_path"]
