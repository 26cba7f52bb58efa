"""A random agent: uniformly drawn targets, for smoke tests and baselines."""

from __future__ import annotations

import gymnasium as gym
import numpy as np


class RandomPolicy:
    """Sample a fresh target from `action_space` every `hold` steps.

    Holding a target for a while makes the character actually walk somewhere instead of
    jittering between targets each frame.
    """

    def __init__(self, action_space: gym.spaces.Box, hold: int = 40, seed: int | None = None) -> None:
        if hold < 1:
            raise ValueError(f"hold must be >= 1, got {hold}")
        self.action_space = action_space
        self.hold = int(hold)
        self._seed = seed
        self.reset()

    def reset(self) -> None:
        self.action_space.seed(self._seed)
        self._steps = 0
        self._action = self.action_space.sample()

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        if self._steps and self._steps % self.hold == 0:
            self._action = self.action_space.sample()
        self._steps += 1
        return np.asarray(self._action, dtype=np.float32)
