"""What the replay's public functions accept, checked once where a caller hands it over.

:func:`~motion_env.replay.evaluate`, :func:`~motion_env.replay.evaluate_detailed`,
:func:`~motion_env.replay.measure`, :func:`~motion_env.replay.tracking.track` and the fit
(:func:`~motion_env.replay.fit.fit_qpos`, which takes raw arrays) call these first, so that a bad
input fails with a ValueError naming the argument instead of deep inside MuJoCo or the fit.

A :class:`motion_env.Motion` checks its joints and rate when it is made, but its arrays can be
changed afterwards (``motion.joints[5] = np.nan``, ``motion.fps = 0``), and :func:`measure`
takes any object with ``joints`` and ``fps``: so the motion is checked again here.
:func:`~motion_env.replay.robot.evaluate_robot` checks a robot's ``qpos`` with :func:`check_qpos`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motion_env.motion.validation import check_joints, check_positive


def check_mass(mass: Any) -> float:
    """The humanoid's mass in kg as a float, or ValueError."""
    return check_positive(mass, "mass", " of kg")


def check_motion(motion: Any, name: str = "motion") -> tuple[np.ndarray, float]:
    """``(joints (T, 22, 3) float64, fps)`` of a motion, or ValueError naming what is wrong
    (a wrong shape, the frames with NaN or infinite values, a rate that is not > 0)."""
    if not (hasattr(motion, "joints") and hasattr(motion, "fps")):
        raise TypeError(f"{name} must be a motion_env.Motion, got {type(motion).__name__}")
    joints = check_joints(motion.joints, f"{name}.joints")
    fps = check_positive(motion.fps, f"{name}.fps", " of frames per second")
    return joints, fps


def check_qpos(qpos: Any, nq: int, name: str = "qpos") -> np.ndarray:
    """A robot trajectory ``(T, nq)`` as float64 with unit root quaternions (columns 3:7, w x y z,
    normalised), or ValueError naming what is wrong: not a 2-D array of `nq` columns, no frame,
    NaN or infinite values (naming the frames), a root quaternion far from unit length."""
    try:
        array = np.array(qpos, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers (T, {nq}), got {type(qpos).__name__}") from None
    if array.ndim != 2 or array.shape[1] != nq or not len(array):
        raise ValueError(f"{name} must have shape (T, {nq}) with T >= 1 (the model's nq), got {array.shape}")
    bad = np.flatnonzero(~np.isfinite(array).all(axis=1))
    if len(bad):
        raise ValueError(f"{name} has NaN or infinite values at frames {bad[:10].tolist()}")
    norm = np.linalg.norm(array[:, 3:7], axis=1)
    off = np.flatnonzero(np.abs(norm - 1.0) > 0.01)
    if len(off):
        raise ValueError(
            f"{name}: the root quaternion (columns 3:7, w x y z) is not of unit length at frames "
            f"{off[:10].tolist()} (norm {norm[off[0]]:.3f})"
        )
    array[:, 3:7] /= norm[:, None]
    return array
