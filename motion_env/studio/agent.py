"""The goal-seeking agent of the studio: the project's A* planner (:class:`policies.AStarPolicy`)
over the arena's obstacles (:mod:`motion_env.envs.arena`), its plan handed to the character as
a route.

The environments feed the planner's carrot to the generator step by step; the studio gives the
whole smoothed plan instead, so that the page can draw the route ahead and the generator's
path controller sees the corners coming. The planner re-plans when the goal or the obstacles
change, or when the character has drifted off its plan.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from motion_env.envs.arena import Obstacle

__all__ = ["GoalAgent"]


class GoalAgent:
    """Plans a route to `goal` around `obstacles` and notices when a new plan is needed.

    Args:
        goal: (x, z) to reach.
        obstacles: the arena's obstacles (circles (x, z, r) or polygons).
        resolution: planning grid cell (m); coarser than the planner's default 0.1 m, so that a
            re-plan over a 20 m arena fits between two frames.
    """

    def __init__(self, goal: Sequence[float], obstacles: Sequence[Obstacle] = (), resolution: float = 0.2):
        from policies.astar import AStarPolicy  # the project's planner, outside the package

        self._policy = AStarPolicy(goal, obstacles, resolution=resolution)
        self._plan_sent: np.ndarray | None = None

    @property
    def goal(self) -> np.ndarray:
        """(2,) the goal (x, z)."""
        return self._policy.goal.copy()

    def set_obstacles(self, obstacles: Sequence[Obstacle]) -> None:
        """New obstacles: the next :meth:`update` re-plans."""
        self._policy.set_obstacles(obstacles)

    def update(self, position_xz: np.ndarray) -> np.ndarray | None:
        """The new route (M, 2) when the planner made a new plan from `position_xz`, else None.

        Raises ValueError when no path leads to the goal (it is walled in, or inside an obstacle's
        margin with no way out).
        """
        self._policy.act({"root": np.asarray(position_xz, np.float64)})
        plan = self._policy.plan
        if plan is None or plan is self._plan_sent:
            return None
        self._plan_sent = plan
        # The plan starts where the character stands; the route is what lies ahead.
        return np.asarray(plan[1:] if len(plan) > 1 else plan, np.float64)
