"""The Gymnasium environments: Waypoints-v0, GoalReach-v0 and the natively batched vector env."""

from motion_env.envs.config import DEFAULT_TEXT_POOL, EnvConfig
from motion_env.envs.goal_reach import GoalReachEnv, GoalReachVectorEnv
from motion_env.envs.vector import WaypointsVectorEnv
from motion_env.envs.waypoints import WaypointsEnv

__all__ = [
    "DEFAULT_TEXT_POOL",
    "EnvConfig",
    "GoalReachEnv",
    "GoalReachVectorEnv",
    "WaypointsEnv",
    "WaypointsVectorEnv",
]
