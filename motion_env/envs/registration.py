"""Registers the Gymnasium environments when `motion_env` is imported."""

from __future__ import annotations

import gymnasium as gym

# id -> (entry point, vector entry point or None, max_episode_steps)
ENVIRONMENTS: dict[str, tuple[str, str | None, int]] = {
    "motion_env/Waypoints-v0": (
        "motion_env.envs.waypoints:WaypointsEnv",
        "motion_env.envs.vector:WaypointsVectorEnv",
        1000,
    ),
    "motion_env/GoalReach-v0": ("motion_env.envs.goal_reach:GoalReachEnv", None, 200),
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
