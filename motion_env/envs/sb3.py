"""stable-baselines3 on the natively batched vector env: :func:`make_sb3_env`.

SB3 cannot take a Gymnasium ``VectorEnv``: it has its own ``VecEnv`` interface, with the reset in
the same step as the episode's end and the last observation in ``info["terminal_observation"]``.
:class:`MotionVecEnv` adapts the motion_env vector env (made with ``autoreset_mode="same_step"``)
to it, so N characters still cost one batched generator call per frame.

    import motion_env
    from stable_baselines3 import PPO

    env = motion_env.make_sb3_env("motion_env/Waypoints-v0", num_envs=16)
    PPO("MultiInputPolicy", env).learn(60_000)

Needs the optional extra ``pip install "motion-env[rl]"``.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Sequence
from typing import Any

import numpy as np

# The VecEnv base class comes from SB3, which is optional: the class is built on first use.
_CLASS: type | None = None


def _vec_env_base() -> type:
    try:
        return importlib.import_module("stable_baselines3.common.vec_env").VecEnv
    except ImportError as exc:
        raise ImportError(
            "make_sb3_env needs stable-baselines3, which is not installed: "
            'pip install "motion-env[rl]" (or pip install stable-baselines3)'
        ) from exc


def make_sb3_env(env_id: str = "motion_env/Waypoints-v0", num_envs: int = 8, **env_kwargs: Any) -> Any:
    """An SB3 ``VecEnv`` of `num_envs` characters of `env_id`, backed by the native vector env.

    Args:
        env_id: a motion_env id (``motion_env/Waypoints-v0`` or ``motion_env/GoalReach-v0``).
        num_envs: characters stepped together (>= 1).
        **env_kwargs: the env's arguments (``generator``, ``text_pool``, ``frames_per_step``,
            ``max_episode_steps``, ...), as for ``gym.make``.

    Returns:
        A :class:`MotionVecEnv` (observations are the env's ``Dict``: use SB3's
        ``"MultiInputPolicy"``).
    """
    import gymnasium as gym  # the ids are registered: this module is inside motion_env

    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
    if not isinstance(env_id, str) or not env_id.startswith("motion_env/"):
        raise ValueError(f"env_id must be a motion_env id such as 'motion_env/Waypoints-v0', got {env_id!r}")
    if "autoreset_mode" in env_kwargs:
        raise ValueError(
            "make_sb3_env sets autoreset_mode itself (SB3 resets in the step that ends an episode)"
        )
    global _CLASS
    if _CLASS is None:
        _CLASS = type("MotionVecEnv", (_MotionVecEnv, _vec_env_base()), {"__doc__": _MotionVecEnv.__doc__})
    venv = gym.make_vec(
        env_id,
        num_envs=int(num_envs),
        vectorization_mode="vector_entry_point",
        autoreset_mode="same_step",
        **env_kwargs,
    )
    return _CLASS(venv)


class _MotionVecEnv:
    """An SB3 ``VecEnv`` over a motion_env vector env in same-step autoreset mode.

    ``reset()`` uses the seed given to ``seed()`` (the first env's: the native env takes one seed
    for the whole batch) and the options given to ``set_options`` (the same for every env).
    ``step_wait`` returns per-env info dicts with the env's entries, ``terminal_observation`` and
    ``TimeLimit.truncated`` when an episode ended. ``env_method`` calls the vector env's method
    with ``index=i`` for each index where it takes one (``env_method("set_text", "a person jogs",
    indices=[0])``), else once per index as it is (``compute_reward``, which HER calls).
    """

    def __init__(self, venv: Any) -> None:
        self.venv = venv
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    # -- the VecEnv interface ------------------------------------------------------------------

    def reset(self) -> dict[str, np.ndarray]:
        options = self._options[0] if self._options else {}
        if any(o != options for o in self._options):
            raise ValueError("the native vector env takes the same reset options for every env")
        obs, infos = self.venv.reset(seed=self._seeds[0], options=options or None)
        self.reset_infos = self._split(infos)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, list[dict[str, Any]]]:
        if self._actions is None:
            raise RuntimeError("step_wait() called without step_async(actions)")
        obs, reward, terminated, truncated, infos = self.venv.step(self._actions)
        self._actions = None
        dones = terminated | truncated
        out = self._split(infos)
        for i in np.nonzero(dones)[0]:
            out[i] = dict(infos["final_info"][i])
            out[i]["terminal_observation"] = infos["final_obs"][i]
            out[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, reward.astype(np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        value = getattr(self.venv, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        if indices is not None and len(self._indices(indices)) != self.num_envs:
            raise ValueError("the native vector env shares its attributes: set them for every env")
        setattr(self.venv, attr_name, value)

    def env_method(
        self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any
    ) -> list:
        method = getattr(self.venv, method_name)
        if "index" in inspect.signature(method).parameters:  # per character: set_text(text, index=i)
            return [method(*method_args, index=i, **method_kwargs) for i in self._indices(indices)]
        # Shared by every env (compute_reward, as HER calls it): the same call for each index.
        return [method(*method_args, **method_kwargs) for _ in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False for _ in self._indices(indices)]  # no Gymnasium wrappers inside

    # -- internals -----------------------------------------------------------------------------

    def _indices(self, indices: Any) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        return [int(indices)] if isinstance(indices, (int, np.integer)) else [int(i) for i in indices]

    def _split(self, infos: dict[str, Any]) -> list[dict[str, Any]]:
        """Gymnasium's batched info dict -> one dict per env (the masks and final entries left out)."""
        keys = [k for k in infos if not k.startswith("_") and k not in ("final_obs", "final_info")]
        return [{k: infos[k][i] for k in keys} for i in range(self.num_envs)]
