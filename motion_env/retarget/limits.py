"""Joint ranges and joint speeds of a robot's qpos: clip into the ranges, cap the speed, count
violations. Limited hinge and slide joints have a range; a limited ball joint a largest angle."""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["clip_to_limits", "limit_speed", "range_violations", "scalar_joints"]

_SCALAR = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)


def scalar_joints(model: mujoco.MjModel) -> np.ndarray:
    """Joint ids of the hinge and slide joints (one qpos entry each)."""
    return np.flatnonzero(np.isin(model.jnt_type, _SCALAR))


def _ball_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) of unit quaternions (..., 4)."""
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def clip_to_limits(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Clip every limited joint of `qpos` (..., nq) into its range, in place, and return it: hinge
    and slide joints to [low, high], a ball joint's rotation angle down to its largest angle."""
    for j in np.flatnonzero(model.jnt_limited):
        a, (low, high) = model.jnt_qposadr[j], model.jnt_range[j]
        if model.jnt_type[j] in _SCALAR:
            qpos[..., a] = np.clip(qpos[..., a], low, high)
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            q = qpos[..., a : a + 4]
            q *= np.where(q[..., :1] < 0, -1.0, 1.0)  # the representative with angle <= pi
            angle = _ball_angle(q)
            norm = np.maximum(np.linalg.norm(q[..., 1:], axis=-1, keepdims=True), 1e-12)
            half = 0.5 * np.minimum(angle, high)[..., None]
            q[..., :] = np.concatenate([np.cos(half), q[..., 1:] / norm * np.sin(half)], axis=-1)
    return qpos


def limit_speed(model: mujoco.MjModel, qpos: np.ndarray, max_step: float) -> np.ndarray:
    """Cap how far each hinge and slide joint moves between consecutive frames, in place.

    qpos: (T, nq). A joint that would move more than `max_step` (rad or m) in a frame moves
    `max_step` and catches up over the next frames.
    """
    cols = model.jnt_qposadr[scalar_joints(model)]
    for t in range(1, qpos.shape[0]):
        step = np.clip(qpos[t, cols] - qpos[t - 1, cols], -max_step, max_step)
        qpos[t, cols] = qpos[t - 1, cols] + step
    return qpos


def range_violations(model: mujoco.MjModel, qpos: np.ndarray, tolerance: float = 1e-9) -> int:
    """How many (frame, joint) entries of `qpos` (T, nq) lie outside their joint's range."""
    count = 0
    for j in np.flatnonzero(model.jnt_limited):
        a, (low, high) = model.jnt_qposadr[j], model.jnt_range[j]
        if model.jnt_type[j] in _SCALAR:
            value = qpos[:, a]
            count += int(((value < low - tolerance) | (value > high + tolerance)).sum())
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            count += int((_ball_angle(qpos[:, a : a + 4]) > high + tolerance).sum())
    return count
