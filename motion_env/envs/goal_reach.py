"""`motion_env/GoalReach-v0`: the goal-conditioned form of Waypoints-v0, for hindsight relabelling (HER)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from motion_env.envs.arena import Obstacle, obstacle_distance
from motion_env.envs.config import EnvConfig
from motion_env.envs.core import CharacterBatch
from motion_env.envs.spaces import observation_space
from motion_env.envs.vector import WaypointsVectorEnv
from motion_env.envs.waypoints import WaypointsEnv
from motion_env.motion.trajectory import MAX_COORDINATE

REWARD_TYPES = ("sparse", "dense")
_GOAL_DISTANCE = (1.5, 4.0)  # random goals lie this far (m) from the start
# The parts of Waypoints-v0's observation that make GoalReach's "observation" (73 numbers).
_OBSERVATION_PARTS = ("root", "velocity", "pose")


def check_goal(goal: Any) -> np.ndarray:
    """A goal (x, z) as a one-waypoint untimed route (1, 3) (ValueError otherwise)."""
    arr = np.array(goal, dtype=np.float64).reshape(-1)
    if arr.shape != (2,) or not np.isfinite(arr).all():
        raise ValueError(f"options['goal'] must be a finite (x, z) pair, got {goal!r}")
    return np.array([[arr[0], arr[1], np.nan]], np.float32)


def sample_goal(
    rng: np.random.Generator, start: np.ndarray, config: EnvConfig, obstacles: Sequence[Obstacle]
) -> np.ndarray:
    """A random goal (1, 3) 1.5-4 m from `start`, clear of obstacles and inside the arena."""
    limit = config.arena_size - 0.5
    for _ in range(100):
        angle = rng.uniform(-np.pi, np.pi)
        point = start[:2] + rng.uniform(*_GOAL_DISTANCE) * np.array([np.sin(angle), np.cos(angle)])
        if (np.abs(point) <= limit).all() and obstacle_distance(point, obstacles) > 0.6:
            break
    point = np.clip(point, -limit, limit)
    return np.array([[point[0], point[1], np.nan]], np.float32)


class GoalReachEnv(WaypointsEnv):
    """Walk a generated human to a goal on the floor; the GoalEnv form, ready for HER.

    ## Description
    The same character, generator and actions as :class:`motion_env.envs.WaypointsEnv`, with a
    route of one waypoint, the goal. The observation follows the ``GoalEnv`` convention (as
    gymnasium-robotics' Fetch tasks): ``observation``, ``achieved_goal`` and ``desired_goal``, and
    :meth:`compute_reward` works on batches of goals, so a replay buffer can relabel goals in
    hindsight (stable-baselines3's ``HerReplayBuffer``). :attr:`goal` is the goal's world x, z.

    ## Action Space
    As Waypoints-v0: by default ``Box(-1, 1, (3,), float32)``, a point up to ``reach`` metres around
    the character in its heading frame, and a "follow" switch that walks straight to the goal
    (``follow_action=False`` leaves only the point, ``Box(-1, 1, (2,))``; ``action_mode="absolute"``
    or ``"relative"``: world or heading-frame metres). NaN/inf raise ``ValueError`` (or
    ``invalid_action="hold"``); finite values outside the Box are clipped.

    ## Observation Space
    ``Dict`` of float32 Boxes:

    | key | shape | meaning |
    |---|---|---|
    | ``"observation"`` | (73,) | Waypoints-v0's ``root`` (4), ``velocity`` (3) and ``pose`` (66) |
    | ``"achieved_goal"`` | (2,) | pelvis world x, z |
    | ``"desired_goal"`` | (2,) | goal world x, z |

    ## Rewards
    ``compute_reward(achieved_goal, desired_goal, info)``: ``reward_type="sparse"`` gives -1 per step
    until the pelvis is within ``arrive_radius`` of the goal, then 0; ``"dense"`` gives minus the
    distance in metres. ``info["reward_goal"]`` holds it. Goals of shape (..., 2) give rewards of
    shape (...,), float32 (a float for single (2,) goals).

    ## Starting State
    ``options["start"]`` (x, z, heading) or the origin facing +Z (``random_start=True``: random);
    ``options["goal"]`` (x, z) or a goal drawn from ``self.np_random`` 1.5-4 m away in any
    direction, clear of obstacles and inside the arena; ``options["text"]`` or a caption drawn from
    ``text_pool``.

    ## Episode End
    ### Termination
    When the pelvis is within ``arrive_radius`` of the goal (``terminate_on_arrival``).

    ### Truncation
    By the registration's ``TimeLimit``: 100 steps of four frames (20 s).

    ## Arguments
    Those of Waypoints-v0 (its table), plus:

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | ``reward_type`` | str | ``"sparse"`` | ``"sparse"`` or ``"dense"`` (Rewards) |

    ``gym.make("motion_env/GoalReach-v0", reward_type="dense", ...)``;
    ``gym.make_vec("motion_env/GoalReach-v0", num_envs=N)`` gives :class:`GoalReachVectorEnv`.

    ## ``info`` keys
    Those of Waypoints-v0 (its table; the route is the goal alone: ``route_length`` 1,
    ``route_target`` the goal), with one reward term instead of its four:

    | key | shape | meaning |
    |---|---|---|
    | ``reward_goal`` | float | the step's reward, as :meth:`compute_reward` gives it (``step`` only) |

    ## Version History
    * v0: Initial version.
    """

    reset_options: tuple[str, ...] = ("text", "goal", "start")

    def __init__(self, *args: Any, reward_type: str = "sparse", **kwargs: Any) -> None:
        self.reward_type = check_reward_type(reward_type)
        super().__init__(*args, **kwargs)
        self.observation_space = goal_observation_space()

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None
    ) -> np.ndarray | float:
        """Reward for goals (..., 2) achieved vs desired; works on batches (HER relabelling).

        Returns a float32 array of shape (...,) (a float for single (2,) goals).
        """
        return goal_reward(achieved_goal, desired_goal, self.reward_type, self.config.arrive_radius)

    def _route(self, options: dict[str, Any], start: np.ndarray) -> np.ndarray:
        goal = options.get("goal")
        if goal is not None:
            return check_goal(goal)
        return sample_goal(self.np_random, start, self.config, self.obstacles)

    def _reward_terms(self) -> dict[str, np.ndarray]:
        return goal_terms(self._batch, self.reward_type)

    def _observation(self) -> dict[str, np.ndarray]:
        return {name: value[0] for name, value in goal_observations(self._batch).items()}

    @property
    def goal(self) -> np.ndarray:
        """(2,) world x, z of the goal."""
        self._require_episode()
        return self._batch.routes[0][-1, :2].copy()


class GoalReachVectorEnv(WaypointsVectorEnv):
    """N GoalReach-v0 characters stepped together through one batched generator stream.

    ``gym.make_vec("motion_env/GoalReach-v0", num_envs=N)`` builds it. Each sub-environment behaves
    as :class:`GoalReachEnv` (observations, ``reward_type``, reset options ``text``, ``goal`` and
    ``start``); batching, autoreset and infos are those of
    :class:`~motion_env.envs.vector.WaypointsVectorEnv`. ``compute_reward`` works on batches of
    goals, as the single env's.
    """

    reset_options: tuple[str, ...] = ("text", "goal", "start")
    _route_option = "goal"
    _check_route = staticmethod(check_goal)
    _draw_route = staticmethod(sample_goal)

    def __init__(self, *args: Any, reward_type: str = "sparse", **kwargs: Any) -> None:
        self.reward_type = check_reward_type(reward_type)
        super().__init__(*args, **kwargs)

    def compute_reward(
        self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any = None
    ) -> np.ndarray | float:
        """As :meth:`GoalReachEnv.compute_reward`."""
        return goal_reward(achieved_goal, desired_goal, self.reward_type, self.config.arrive_radius)

    def _observation_space(self) -> spaces.Dict:
        return goal_observation_space()

    def _observations(self) -> dict[str, np.ndarray]:
        return goal_observations(self._batch)

    def _reward_terms(self) -> dict[str, np.ndarray]:
        return goal_terms(self._batch, self.reward_type)


# ----------------------------------------------------------------------------------------------
# What the single and the vector env share
# ----------------------------------------------------------------------------------------------


def goal_observation_space() -> spaces.Dict:
    """The GoalEnv observation space (finite bounds: those of Waypoints-v0's parts)."""
    parts = observation_space(1)
    low = np.concatenate([parts[name].low for name in _OBSERVATION_PARTS])
    high = np.concatenate([parts[name].high for name in _OBSERVATION_PARTS])
    goal = parts["root"].high[0]
    return spaces.Dict(
        {
            "observation": spaces.Box(low, high, dtype=np.float32),
            "achieved_goal": spaces.Box(-goal, goal, (2,), np.float32),
            "desired_goal": spaces.Box(-goal, goal, (2,), np.float32),
        }
    )


def goal_observations(batch: CharacterBatch) -> dict[str, np.ndarray]:
    """(B, ...) GoalEnv observations of every character."""
    obs = batch.observations()
    return {
        "observation": np.concatenate([obs[name] for name in _OBSERVATION_PARTS], axis=1),
        "achieved_goal": obs["root"][:, :2].copy(),
        "desired_goal": np.clip(batch.route_target, -MAX_COORDINATE, MAX_COORDINATE).astype(np.float32),
    }


def goal_reward(achieved_goal: Any, desired_goal: Any, reward_type: str, radius: float) -> np.ndarray | float:
    """Sparse (-1 until within `radius`, then 0) or dense (minus the distance) goal reward."""
    achieved = np.asarray(achieved_goal, dtype=np.float64)
    desired = np.asarray(desired_goal, dtype=np.float64)
    if achieved.shape[-1:] != (2,) or desired.shape[-1:] != (2,):
        raise ValueError(f"goals must have shape (..., 2), got {achieved.shape} and {desired.shape}")
    d = np.linalg.norm(achieved - desired, axis=-1)
    reward = -(d >= radius).astype(np.float32) if reward_type == "sparse" else -d.astype(np.float32)
    return float(reward) if reward.ndim == 0 else reward


def goal_terms(batch: CharacterBatch, reward_type: str) -> dict[str, np.ndarray]:
    reward = goal_reward(batch.pos, batch.route_target, reward_type, batch.config.arrive_radius)
    return {"reward_goal": np.atleast_1d(reward)}


def check_reward_type(reward_type: str) -> str:
    if reward_type not in REWARD_TYPES:
        raise ValueError(f"reward_type must be one of {REWARD_TYPES}, got {reward_type!r}")
    return reward_type
