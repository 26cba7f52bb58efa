"""A natively batched Waypoints-v0: N characters, one batched generator call per frame.

``gym.make_vec("motion_env/Waypoints-v0", num_envs=N, vectorization_mode="vector_entry_point")``
builds :class:`WaypointsVectorEnv`. Each sub-environment behaves as :class:`WaypointsEnv` (same
actions, observations, rewards, route semantics); the difference is that all N characters share
one generator stream, so a step costs one batched forward pass instead of N.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from motion_env.envs.config import EnvConfig, check_actions, validate_start
from motion_env.envs.core import build_characters
from motion_env.envs.episodes import sample_route, sample_start
from motion_env.envs.spaces import action_space, caption_size, observation_space
from motion_env.generation.request import check_text
from motion_env.joint_targets import JointTargets
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_waypoints

# The autoreset modes this env implements, by Gymnasium's enum, its value or a snake-case name.
AUTORESET_MODES: dict[Any, AutoresetMode] = {
    key: mode
    for mode, name in ((AutoresetMode.NEXT_STEP, "next_step"), (AutoresetMode.SAME_STEP, "same_step"))
    for key in (mode, mode.value, name)
}


class WaypointsVectorEnv(VectorEnv):
    """N Waypoints-v0 characters stepped together through one batched generator stream.

    Arguments are those of :class:`motion_env.envs.WaypointsEnv` (its behaviour settings passed
    through to :class:`~motion_env.envs.config.EnvConfig`) plus ``num_envs`` and
    ``max_episode_steps`` (truncation is done here, since no ``TimeLimit`` wraps a vector env;
    ``gym.make_vec`` passes the registration's 150). ``render_mode`` must be None.

    Autoreset (``autoreset_mode``, Gymnasium's two modes):

    - ``"next_step"`` (default, Gymnasium's default): the step after a sub-environment terminates
      or truncates resets it (a new caption, route and start from ``self.np_random``, or the reset
      options given to the last :meth:`reset`), ignores its action and returns its first
      observation with reward 0 and both flags False;
    - ``"same_step"`` (what stable-baselines3 expects; RLlib 2.60 uses next-step): the step that
      ends an episode also resets it and returns the new episode's first observation; the last
      observation and info of the old one are in ``infos["final_obs"]`` and ``infos["final_info"]``
      (object arrays, None for the others; masks ``_final_obs`` and ``_final_info``).

    A (re)started character's ``infos["step_joints"]`` row is its first frame F times, as after
    :meth:`reset` (every info entry keeps one shape).

    ``reset(seed, options)`` resets every sub-environment; options ``text``, ``waypoints`` and
    ``start`` apply to all of them (a value left out is drawn per sub-environment). ``infos`` hold
    the per-env entries of :class:`WaypointsEnv`'s ``info`` as arrays with a leading N axis (and
    Gymnasium's ``_name`` masks, all True); with ``robot=`` (as for :class:`WaypointsEnv`)
    ``infos["robot_qpos"]`` is (N, nq) float32, each character's last frame on the robot.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": [], "render_fps": FPS}
    reset_options: tuple[str, ...] = ("text", "waypoints", "start")
    # The reset option that gives the route, its check, and what draws a route when it is not given.
    _route_option: str = "waypoints"
    _check_route = staticmethod(validate_waypoints)
    _draw_route = staticmethod(sample_route)

    def __init__(
        self,
        num_envs: int = 1,
        max_episode_steps: int | None = None,
        generator: Any | None = None,
        model_path: str | None = None,
        text_pool: Sequence[str] | None = None,
        render_mode: str | None = None,
        obstacles: np.ndarray | Sequence | None = None,
        device: str = "cpu",
        robot: str | None = None,
        autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
        **config: Any,
    ) -> None:
        if int(num_envs) < 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if max_episode_steps is not None and int(max_episode_steps) < 1:
            raise ValueError(f"max_episode_steps must be >= 1 or None, got {max_episode_steps}")
        if render_mode is not None:
            raise ValueError(
                f"WaypointsVectorEnv does not render (render_mode must be None, got {render_mode!r})"
            )
        # The behaviour settings (action_mode, frames_per_step, arrive_radius, rewards, ...) are
        # WaypointsEnv's, checked once by EnvConfig.
        unknown = sorted(set(config) - {f.name for f in fields(EnvConfig)} - {"trail_length"})
        if unknown:
            raise TypeError(f"WaypointsVectorEnv got unknown arguments {unknown}")
        self.autoreset_mode = AUTORESET_MODES.get(autoreset_mode)
        if self.autoreset_mode is None:
            raise ValueError(
                f"autoreset_mode must be 'next_step' or 'same_step' (or Gymnasium's AutoresetMode), "
                f"got {autoreset_mode!r}"
            )
        self.config = EnvConfig(**config, trail_length=1)
        self.num_envs = int(num_envs)
        self.max_episode_steps = None if max_episode_steps is None else int(max_episode_steps)
        self.render_mode = None
        self.metadata = {
            **self.metadata,
            "render_fps": FPS / self.config.frames_per_step,
            "autoreset_mode": self.autoreset_mode,
        }
        self.text_pool, self.obstacles, self.generator, self._batch = build_characters(
            self.config, text_pool, obstacles, generator, model_path, device
        )
        self._batch.use_robot(robot, self.num_envs)
        self.single_action_space = action_space(self.config)
        self.single_observation_space = self._observation_space()
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._options: dict[str, Any] = {}
        self._autoreset = np.zeros(self.num_envs, bool)
        self._steps = np.zeros(self.num_envs, np.int64)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is not None and not isinstance(seed, (int, np.integer)):
            raise TypeError(f"seed must be an int or None (one seed for the whole batch), got {seed!r}")
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = sorted(set(options) - set(self.reset_options))
        if unknown:
            raise ValueError(f"unknown reset options {unknown}; known: {list(self.reset_options)}")
        if options.get("text") is not None:
            options["text"] = check_text(options["text"])
        if options.get("start") is not None:
            options["start"] = validate_start(options["start"])
        self._options = self._check_route_options(options)
        episodes = [self._episode() for _ in range(self.num_envs)]
        texts, routes, starts = (list(x) for x in zip(*episodes))
        seed_ = int(self.np_random.integers(2**31 - 1))
        self._batch.start(self.generator, texts, routes, np.stack(starts), seed=seed_)
        self._autoreset[:] = False
        self._steps[:] = 0
        zeros = np.zeros(self.num_envs)
        flags = np.zeros(self.num_envs, bool)
        terms = {name: zeros for name in self._reward_terms()}
        return self._observations(), self._infos(terms, flags, flags)

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        batch = self._batch
        if batch.stream is None:
            raise RuntimeError("call reset() before step()")
        cfg = self.config
        acts, valid, clipped = check_actions(
            actions, self.num_envs, cfg.action_bound, cfg.invalid_action, cfg.action_size
        )
        restart = np.nonzero(self._autoreset)[0]
        live = ~self._autoreset
        batch.begin_step()
        batch.command(acts, valid & live)
        for f in range(cfg.frames_per_step):
            if f == cfg.frames_per_step - 1:
                # Restart just before the last frame, so a restarted character's first frame is
                # the observation its new episode starts with (as WaypointsEnv.reset emits one).
                for i in restart:
                    batch.restart(int(i), *self._episode())
            batch.emit_frame()
        terms = {name: np.where(live, value, 0.0) for name, value in self._reward_terms().items()}
        reward = sum(terms.values()).astype(np.float64)
        terminated = live & cfg.terminate_on_arrival & batch.reached
        self._steps = np.where(live, self._steps + 1, 0)
        if self.max_episode_steps is None:
            truncated = np.zeros(self.num_envs, bool)
        else:
            truncated = live & ~terminated & (self._steps >= self.max_episode_steps)
        done = terminated | truncated
        infos = self._infos(terms, clipped & live, ~valid & live)
        obs = self._observations()
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._autoreset = done
            return obs, reward, terminated, truncated, infos
        return self._reset_ended(np.nonzero(done)[0], obs, reward, terminated, truncated, infos)

    def _reset_ended(
        self,
        ended: np.ndarray,
        obs: dict[str, np.ndarray],
        reward: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
        infos: dict[str, Any],
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Same-step autoreset: restart the characters whose episode ended, emit their first frame
        and return it, the final observations and infos under ``final_obs`` / ``final_info``."""
        if len(ended) == 0:
            return obs, reward, terminated, truncated, infos
        final_obs = np.full(self.num_envs, None, dtype=object)
        final_info = np.full(self.num_envs, None, dtype=object)
        for i in ended:
            final_obs[i] = {name: value[i].copy() for name, value in obs.items()}
            final_info[i] = {k: v[i] for k, v in infos.items() if not k.startswith("_")}
        batch = self._batch
        for i in ended:
            batch.restart(int(i), *self._episode())
        batch.emit_frame(ended)
        self._steps[ended] = 0
        flags = np.zeros(self.num_envs, bool)
        zeros = {name: np.zeros(self.num_envs) for name in infos if name.startswith("reward_")}
        new = self._infos(zeros, flags, flags)
        for name, value in infos.items():  # the others keep this step's info
            if not name.startswith("_"):
                value[ended] = new[name][ended]
        mask = np.zeros(self.num_envs, bool)
        mask[ended] = True
        infos.update(final_obs=final_obs, final_info=final_info, _final_obs=mask, _final_info=mask.copy())
        return self._observations(), reward, terminated, truncated, infos

    def set_text(self, text: str, index: int | None = None) -> None:
        """Change the caption of one character (or all, index=None) mid-episode."""
        self._check_index(index)
        self._batch.set_text(text, index=None if index is None else int(index))  # the stream checks it

    def set_joint_targets(
        self,
        targets: JointTargets | np.ndarray | None,
        index: int | None = None,
        first_frame: int | None = None,
    ) -> None:
        """Joint targets of one character (or all, index=None), as :meth:`WaypointsEnv.set_joint_targets`."""
        self._check_index(index)
        self._batch.stream.set_joint_targets(targets, index=index, first_frame=first_frame)

    def set_objectives(self, objectives: Sequence[Any] | None, index: int | None = None) -> None:
        """Height limits of one character (or all), as :meth:`WaypointsEnv.set_objectives`."""
        self._check_index(index)
        self._batch.stream.set_objectives(objectives, index=index)

    def _check_index(self, index: int | None) -> None:
        if self._batch.stream is None:
            raise RuntimeError("call reset() first")
        if index is not None and not 0 <= int(index) < self.num_envs:
            raise IndexError(f"index {index} out of range for {self.num_envs} envs")

    def close(self, **kwargs: Any) -> None:
        if hasattr(self, "_batch"):  # Gymnasium closes on __del__, also after a failed __init__
            self._batch.stream = None
        self.closed = True

    def _episode(self) -> tuple[str, np.ndarray, np.ndarray]:
        rng, opts = self.np_random, self._options
        text = opts.get("text") or self.text_pool[int(rng.integers(len(self.text_pool)))]
        start = opts.get("start")
        start = sample_start(rng, self.config, self.obstacles) if start is None else start
        return text, self._route(start), start

    def _check_route_options(self, options: dict[str, Any]) -> dict[str, Any]:
        if options.get(self._route_option) is not None:
            options[self._route_option] = self._check_route(options[self._route_option])
        return options

    def _route(self, start: np.ndarray) -> np.ndarray:
        route = self._options.get(self._route_option)
        if route is None:
            route = self._draw_route(self.np_random, start, self.config, self.obstacles)
        return route

    def _infos(
        self, terms: dict[str, np.ndarray], clipped: np.ndarray, invalid: np.ndarray
    ) -> dict[str, Any]:
        batch = self._batch
        target = batch.route_target
        info: dict[str, Any] = {
            "joints": batch.joints.copy(),
            "step_joints": batch.step_joints(),
            "text": np.array(batch.texts, dtype=object),
            "caption_warning": np.array(
                [self.generator.caption_warning(t) for t in batch.texts], dtype=object
            ),
            "frame": np.asarray(batch.stream.frame_index, dtype=np.int64).copy(),
            "route_length": batch.route_count.copy(),
            "route_index": batch.k.copy(),
            "route_target": target.astype(np.float32),
            "command": batch.command_xz.astype(np.float32),
            "following_route": batch.following.copy(),
            "distance": np.linalg.norm(batch.pos - target, axis=1),
            "is_success": batch.reached.copy(),
            "action_clipped": np.asarray(clipped, bool).copy(),
            "action_invalid": np.asarray(invalid, bool).copy(),
            **{name: np.asarray(value, np.float64).copy() for name, value in terms.items()},
        }
        if batch.retargeter is not None:
            info["robot_qpos"] = batch.robot_qpos.copy()
        for name in list(info):
            info[f"_{name}"] = np.ones(self.num_envs, bool)
        return info

    # -- what GoalReach's vector env changes ---------------------------------------------------

    def _observation_space(self) -> Any:
        return observation_space(caption_size(self.generator))

    def _observations(self) -> dict[str, np.ndarray]:
        return self._batch.observations()

    def _reward_terms(self) -> dict[str, np.ndarray]:
        return self._batch.rewards()
