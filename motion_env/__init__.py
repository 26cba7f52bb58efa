"""motion_env: text- and path-controllable human motion as a Gymnasium environment.

Importing the package registers the Gymnasium environments (``motion_env/Waypoints-v0``, ...).
Torch-heavy parts (the generator) are imported lazily, on first use. The package map is in
``docs/architecture.md``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from motion_env import motion
from motion_env.envs.registration import register_envs
from motion_env.io import load_bvh, load_motion
from motion_env.joint_targets import JointTargets
from motion_env.motion import skeleton
from motion_env.motion.types import Motion

if TYPE_CHECKING:
    from motion_env import objectives
    from motion_env.envs.sb3 import make_sb3_env
    from motion_env.generation.generator import MotionGenerator
    from motion_env.retarget.api import retarget

__version__ = "0.1.0"
__all__ = [
    "JointTargets",
    "Motion",
    "MotionGenerator",
    "load_bvh",
    "load_motion",
    "make_sb3_env",
    "motion",
    "objectives",
    "retarget",
    "skeleton",
]

# Loaded on first use. `retarget` is a package that can be called as its function.
_LAZY = {
    "MotionGenerator": "motion_env.generation.generator",
    "retarget": "motion_env.retarget",
    "make_sb3_env": "motion_env.envs.sb3",
    "objectives": "motion_env.objectives",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        module = importlib.import_module(_LAZY[name])
        return module if module.__name__ == f"{__name__}.{name}" else getattr(module, name)
    raise AttributeError(f"module 'motion_env' has no attribute {name!r}")


register_envs()
