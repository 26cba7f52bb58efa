"""`motion_env/GoalReach-v0`: the goal-conditioned form of Waypoints-v0, for hindsight relabelling (HER)."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from motion_env.envs.arena import obstacle_distance
from motion_env.envs.waypoints import WaypointsEnv
from motion_env.motion.skeleton import NUM_JOINTS

REWARD_TYPES = ("sparse", "dense")
_GOAL_DISTANCE = (1.5, 4.0)  # random goals lie this far (m) from the start
_OBSERVATION_DIM = 4 + 3 + NUM_JOINTS * 3


class GoalReachEnv(WaypointsEnv):
    """Walk a generated human to a goal on the floor; the GoalEnv form, ready for HER.

    ## Description
    The same character, generator and actions as :class:`motion_env.envs.WaypointsEnv`, with a
    route of one waypoint, the goal. The observation follows the ``GoalEnv`` convention (as
    gymnasium-robotics' Fetch tasks): ``observation``, ``achieved_goal`` and ``desired_goal``, and
    :meth:`compute_reward` works on batches of goals, so a replay buffer can relabel goals in
    hindsight (stable-baselines3's ``HerReplayBuffer``).

    ## Action Space
    As Waypoints-v0: ``Box(-arena_size, arena_size, (2,))`` world (x, z) target the character walks
    to (``action_mode="relative"``: (dx, dz) in its heading frame); issuing the goal itself walks
    straight to it. NaN/inf raise ``ValueError`` (or ``invalid_action="hold"``); finite values
    outside the Box are clipped.

    ## Observation Space
    ``Dict`` of float32 Boxes:

    - ``"observation"`` (73,): Waypoints-v0's ``root`` (4), ``velocity`` (3) and ``pose`` (66), concatenated;
    - ``"achieved_goal"`` (2,): pelvis world x, z;
    - ``"desired_goal"`` (2,): goal world x, z.

    ## Rewards
    ``compute_reward(achieved_goal, desired_goal, info)``: ``reward_type="sparse"`` gives -1 per step
    until the pelvis is within ``arrive_radius`` of the goal, then 0; ``"dense"`` gives minus the
    distance in metres. ``info["reward_goal"]`` holds it.

    ## Starting State
    ``options["start"]`` (x, z, heading) or the origin facing +Z (``random_start=True``: random);
    ``options["goal"]`` (x, z) or a goal drawn from ``self.np_random`` 1.5-4 m away in any
    direction, clear of obstacles and inside the arena; ``options["text"]`` or a caption drawn from
    ``text_pool``.

    ## Episode End
    Terminated when the pelvis is within ``arrive_radius`` of the goal (``terminate_on_arrival``);
    truncated by the registration's ``TimeLimit`` (200 steps).

    ## Arguments
    Those of Waypoints-v0, plus ``reward_type`` ("sparse" or "dense").
    """

    reset_options: tuple[str, ...] = ("text", "goal", "start")

    def __init__(self, *args: Any, reward_type: str = "sparse", **kwargs: Any) -> None:
        if reward_type not in REWARD_TYPES:
            raise ValueError(f"reward_type must be one of {REWARD_TYPES}, got {reward_type!r}")
        self.reward_type = reward_type
        super().__init__(*args, **kwargs)
        inf = np.float32(np.inf)
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(-inf, inf, (_OBSERVATION_DIM,), np.float32),
                "achieved_goal": spaces.Box(-inf, inf, (2,), np.float32),
                "desired_goal": spaces.Box(-inf, inf, (2,), np.float32),
            }
        )

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None
    ) -> np.ndarray | float:
        """Reward for goals (..., 2) achieved vs desired; works on batches (HER relabelling).

        Returns a float32 array of shape (...,) (a float for single (2,) goals).
        """
        achieved = np.asarray(achieved_goal, dtype=np.float64)
        desired = np.asarray(desired_goal, dtype=np.float64)
        if achieved.shape[-1:] != (2,) or desired.shape[-1:] != (2,):
            raise ValueError(f"goals must have shape (..., 2), got {achieved.shape} and {desired.shape}")
        d = np.linalg.norm(achieved - desired, axis=-1)
        if self.reward_type == "sparse":
            reward = -(d >= self.config.arrive_radius).astype(np.float32)
        else:
            reward = -d.astype(np.float32)
        return float(reward) if reward.ndim == 0 else reward

    def _route(self, options: dict[str, Any], start: np.ndarray) -> np.ndarray:
        goal = options.get("goal")
        if goal is not None:
            arr = np.array(goal, dtype=np.float64).reshape(-1)
            if arr.shape != (2,) or not np.isfinite(arr).all():
                raise ValueError(f"options['goal'] must be a finite (x, z) pair, got {goal!r}")
            return np.array([[arr[0], arr[1], np.nan]], np.float32)
        return self._sample_goal(start)[None]

    def _sample_goal(self, start: np.ndarray) -> np.ndarray:
        limit = self.config.arena_size - 0.5
        for _ in range(100):
            angle = self.np_random.uniform(-np.pi, np.pi)
            point = start[:2] + self.np_random.uniform(*_GOAL_DISTANCE) * np.array(
                [np.sin(angle), np.cos(angle)]
            )
            if (np.abs(point) <= limit).all() and obstacle_distance(point, self.obstacles) > 0.6:
                break
        point = np.clip(point, -limit, limit)
        return np.array([point[0], point[1], np.nan], np.float32)

    def _reward_terms(self) -> dict[str, np.ndarray]:
        batch = self._batch
        return {"reward_goal": np.atleast_1d(self.compute_reward(batch.pos, batch.route_target))}

    def _observation(self) -> dict[str, np.ndarray]:
        obs = self._batch.observations()
        return {
            "observation": np.concatenate([obs["root"][0], obs["velocity"][0], obs["pose"][0]]),
            "achieved_goal": self._batch.pos[0].astype(np.float32),
            "desired_goal": self._batch.route_target[0].astype(np.float32),
        }

    @property
    def goal(self) -> np.ndarray:
        """(2,) world x, z of the goal."""
        self._require_episode()
        return self._batch.routes[0][-1, :2].copy()
