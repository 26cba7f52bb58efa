"""The Gymnasium spaces of one motion_env character: its Dict observation and its action Box.

The vector environments batch these (``batch_space``); GoalReach-v0 builds its observation from
the same parts.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from motion_env.envs.config import OBS_BOUNDS, ROUTE_AHEAD, EnvConfig
from motion_env.motion.skeleton import NUM_JOINTS
from motion_env.motion.trajectory import MAX_COORDINATE

__all__ = ["action_space", "caption_size", "observation_space"]


def caption_size(generator: Any) -> int:
    """Width of the observation's "caption": the path controller's caption projection."""
    return int(generator.controller.config.text_proj)


def observation_space(caption_dim: int) -> spaces.Dict:
    """The Dict observation space of one character (see
    :class:`~motion_env.envs.waypoints.WaypointsEnv`).

    Every bound is finite (what the env checkers ask for);
    :meth:`~motion_env.envs.core.CharacterBatch.observations` clips into them.
    """

    def box(bound: float, size: int) -> spaces.Box:
        return spaces.Box(-np.float32(bound), np.float32(bound), (size,), np.float32)

    return spaces.Dict(
        {
            "root": spaces.Box(
                low=np.array([-MAX_COORDINATE, -MAX_COORDINATE, -1.0, -1.0], np.float32),
                high=np.array([MAX_COORDINATE, MAX_COORDINATE, 1.0, 1.0], np.float32),
                dtype=np.float32,
            ),
            "target": box(OBS_BOUNDS["target"], 2),
            "route_ahead": box(OBS_BOUNDS["route_ahead"], ROUTE_AHEAD * 2),
            "route_state": spaces.Box(0.0, 1.0, (3,), np.float32),
            "velocity": box(OBS_BOUNDS["velocity"], 3),
            "pose": box(OBS_BOUNDS["pose"], NUM_JOINTS * 3),
            "caption": box(OBS_BOUNDS["caption"], caption_dim),
        }
    )


def action_space(config: EnvConfig) -> spaces.Box:
    """The action Box of one character for `config` (see :class:`~motion_env.envs.waypoints.WaypointsEnv`)."""
    bound = np.float32(config.action_bound)
    return spaces.Box(-bound, bound, (config.action_size,), np.float32)
