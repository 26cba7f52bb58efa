"""One episode of an agent in a motion_env environment, every frame kept: how the examples judge
a trained agent, next to a random agent on the same episode (the role stable-baselines3's
``evaluate_policy`` plays, with the motion kept for the video and the plot).

    trained = run_episode(env, lambda obs: model.predict(obs, deterministic=True)[0], seed=0,
                          options={"text": "a person walks", "waypoints": route})
    baseline = run_episode(env, None, seed=0, options=...)   # random actions, seeded
    trained.joints, trained.total_return, trained.terminated, trained.info["is_success"]
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["Episode", "run_episode"]


@dataclass
class Episode:
    """What one episode showed.

    Attributes:
        joints: (T, 22, 3) world positions: the reset frame, then every frame each step emitted
            (``info["step_joints"]``), so T = 1 + steps * frames_per_step.
        total_return: the sum of the rewards.
        terminated: the episode ended at its goal (or last waypoint), not at the time limit.
        info: the last step's ``info`` (``is_success``, ``distance_to_goal``, ...).
    """

    joints: np.ndarray
    total_return: float
    terminated: bool
    info: dict[str, Any]


def run_episode(
    env: gym.Env,
    act: Callable[[Any], np.ndarray] | None,
    seed: int,
    options: dict[str, Any] | None = None,
) -> Episode:
    """Reset `env` with `seed` and `options`, then step it with `act(obs)` until the episode ends.

    Args:
        env: a motion_env environment (``Waypoints-v0``, ``GoalReach-v0``) with a time limit.
        act: observation -> action; None: a random agent, the action space's samples seeded with
            `seed` (the same actions on every call).
        seed: the episode's seed (the reset's, and the random agent's).
        options: the reset's options (``text``, ``waypoints`` or ``goal``, ...).
    """
    if act is None:
        env.action_space.seed(seed)
    policy = act if act is not None else (lambda _obs: env.action_space.sample())
    obs, info = env.reset(seed=seed, options=options)
    frames, total, terminated, truncated = [info["joints"][None]], 0.0, False, False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        frames.append(info["step_joints"])  # every frame of the step, not only the last
        total += float(reward)
    return Episode(np.concatenate(frames), total, bool(terminated), info)
