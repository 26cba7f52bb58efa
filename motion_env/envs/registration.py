"""Registers the Gymnasium environments when `motion_env` is imported."""

from __future__ import annotations

import gymnasium as gym

# id -> (entry point, vector entry point, max_episode_steps). The episode lengths are in steps of
# the default four frames (0.2 s): 150 steps = 30 s, twice what the slowest caption needs for the
# longest random route (4 legs of 3.5 m); 100 steps = 20 s for a goal at most 4 m away.
ENVIRONMENTS: dict[str, tuple[str, str, int]] = {
    "motion_env/Waypoints-v0": (
        "motion_env.envs.waypoints:WaypointsEnv",
        "motion_env.envs.vector:WaypointsVectorEnv",
        150,
    ),
    "motion_env/GoalReach-v0": (
        "motion_env.envs.goal_reach:GoalReachEnv",
        "motion_env.envs.goal_reach:GoalReachVectorEnv",
        100,
    ),
}


def register_envs() -> None:
    """Register every `motion_env/...` id with Gymnasium (idempotent).

    Entry points are strings, so registering imports neither torch nor the generator.
    """
    for env_id, (entry_point, vector_entry_point, max_steps) in ENVIRONMENTS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=entry_point,
            vector_entry_point=vector_entry_point,
            max_episode_steps=max_steps,
        )
