"""Robot-ready reference motion: human clips retargeted onto humanoid robots as MuJoCo qpos.

>>> import motion_env
>>> r = motion_env.retarget(motion, robot="unitree_g1", fps=50)   # or "booster_t1", or an MJCF path
>>> r.qpos.shape                  # (T', nq): root x, y, z, quaternion w, x, y, z, then the joints
>>> r.save("clip.npz", format="mjlab")   # mjlab's tracking npz; "gmr" (.pkl), "lafan_csv", "csv", "npz"
>>> load_robot_motion("clip.npz")         # any of them back
>>> r.residual_summary()          # how far each tracked frame ended from its target

This package is also callable: ``motion_env.retarget(...)`` is :func:`retarget`.

What is where (the stages in the order :func:`retarget` runs them):

- :mod:`.robot`: the shipped robots (``robots/<name>/``: Menagerie model, LICENSE, README, the
  mapping table ``retarget.json``), :func:`load_robot`, :func:`known_robots`;
- :mod:`.table`: the mapping table format (:func:`.table.describe_table` prints one);
  :mod:`.guess`: a table guessed from body names for an MJCF without one (it says what it mapped);
- :mod:`.human`: the human's segment frames and limb lengths; :mod:`.ik_goals`: the clip scaled
  onto the robot as IK targets;
- :mod:`.ik`: the warm-started differential IK (mink), inside the joints' soft ranges
  (:mod:`.limits`: 90 % of each range, and the joint speeds) and with the arms kept off the body
  (:mod:`.collisions`); :mod:`.smoothing`: the low-pass; :mod:`.floor`: the lowest point of the
  geoms;
- :mod:`.api`: :func:`retarget`; :mod:`.stream`: :class:`StreamRetargeter`, the same frame by
  frame while a motion streams (causal: no low-pass); :mod:`.result`: :class:`RobotMotion` and
  :func:`load_robot_motion`; :mod:`.files`: its files (the project's CSV and npz, mjlab's tracking
  npz, GMR's pickle, a LAFAN-style CSV), read and written as plain arrays; :mod:`.tracking`: the
  bodies and velocities of mjlab's npz;
- :mod:`.quality`: the numbers ``scripts/evaluate_retarget.py`` reports; :mod:`.video`: a video
  of a robot clip.

Needs the optional ``mink`` package: ``pip install -c constraints.txt -e ".[robots]"``.
"""

import sys
import types

from motion_env.retarget.api import retarget
from motion_env.retarget.ik import IKSettings
from motion_env.retarget.result import RobotMotion, load_robot_motion
from motion_env.retarget.robot import known_robots, load_robot
from motion_env.retarget.stream import StreamRetargeter

__all__ = [
    "IKSettings",
    "RobotMotion",
    "StreamRetargeter",
    "known_robots",
    "load_robot",
    "load_robot_motion",
    "retarget",
]


class _CallableModule(types.ModuleType):
    """The package as the function the public API names: ``motion_env.retarget(motion, ...)``.

    Importing the package binds the name ``motion_env.retarget`` to it, so the package itself has
    to be callable for that call to work whatever was imported first.
    """

    def __call__(self, *args, **kwargs) -> RobotMotion:
        return retarget(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
