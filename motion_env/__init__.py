"""motion_env: text- and path-controllable human motion as a Gymnasium environment.

Importing the package registers the Gymnasium environments (``motion_env/Waypoints-v0``, ...).
Torch-heavy parts (the generator) are imported lazily, on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from motion_env import motion, skeleton
from motion_env.clip import Motion, load_motion
from motion_env.registration import register_envs

if TYPE_CHECKING:
    from motion_env.bvh import load_bvh
    from motion_env.generator import MotionGenerator

__version__ = "0.1.0"
__all__ = ["Motion", "MotionGenerator", "load_bvh", "load_motion", "motion", "skeleton"]

_LAZY = {"load_bvh": "motion_env.bvh", "MotionGenerator": "motion_env.generator"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'motion_env' has no attribute {name!r}")


register_envs()
