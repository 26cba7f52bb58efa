"""Joint ranges and joint speeds of a robot's qpos: clip into the ranges, cap the speed, count
violations. Limited hinge and slide joints have a range; a limited ball joint a largest angle.

The retargeter keeps every joint inside a *soft* range, a share of the model's range about its
centre (:data:`SOFT_LIMIT`, 90 %, as mjlab's robots set ``soft_joint_pos_limit_factor``): a tracking
controller that follows the clip then never has to push a joint onto its end stop, where mjlab
penalises it. :func:`soft_limited` is the model with those ranges, for the IK and the clipping.
"""

from __future__ import annotations

import copy

import mujoco
import numpy as np

__all__ = ["SOFT_LIMIT", "check_soft_limit", "clip_to_limits", "limit_speed", "range_violations",
           "scalar_joints", "soft_limited"]  # fmt: skip

SOFT_LIMIT = 0.9

# Plain ints: a pybind enum on the left of == is not equal to a numpy int (``x in _SCALAR`` with
# x from model.jnt_type would always be False).
_SCALAR = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_BALL = int(mujoco.mjtJoint.mjJNT_BALL)


def scalar_joints(model: mujoco.MjModel) -> np.ndarray:
    """Joint ids of the hinge and slide joints (one qpos entry each)."""
    return np.flatnonzero(np.isin(model.jnt_type, _SCALAR))


def check_soft_limit(value: object) -> float:
    """A share of the joint range in (0, 1], or ValueError naming ``soft_limit``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= 1:
        raise ValueError(f"soft_limit must be a share of the joint range in (0, 1], got {value!r}")
    return float(value)


def soft_limited(model: mujoco.MjModel, soft_limit: float) -> mujoco.MjModel:
    """A copy of `model` whose limited joints keep `soft_limit` of their range about its centre (a
    ball joint: of its largest angle). With 1.0, `model` itself."""
    soft_limit = check_soft_limit(soft_limit)
    if soft_limit == 1.0:
        return model
    out = copy.deepcopy(model)
    for j in np.flatnonzero(model.jnt_limited):
        low, high = model.jnt_range[j]
        if int(model.jnt_type[j]) in _SCALAR:
            mid, half = 0.5 * (low + high), 0.5 * soft_limit * (high - low)
            out.jnt_range[j] = (mid - half, mid + half)
        elif int(model.jnt_type[j]) == _BALL:
            out.jnt_range[j, 1] = soft_limit * high
    return out


def _ball_angle(q: np.ndarray) -> np.ndarray:
    """Rotation angle (rad) of unit quaternions (..., 4)."""
    return 2.0 * np.arctan2(np.linalg.norm(q[..., 1:], axis=-1), np.abs(q[..., 0]))


def clip_to_limits(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Clip every limited joint of `qpos` (..., nq) into its range, in place, and return it: hinge
    and slide joints to [low, high], a ball joint's rotation angle down to its largest angle."""
    for j in np.flatnonzero(model.jnt_limited):
        a, (low, high) = model.jnt_qposadr[j], model.jnt_range[j]
        if int(model.jnt_type[j]) in _SCALAR:
            qpos[..., a] = np.clip(qpos[..., a], low, high)
        elif int(model.jnt_type[j]) == _BALL:
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
        if int(model.jnt_type[j]) in _SCALAR:
            value = qpos[:, a]
            count += int(((value < low - tolerance) | (value > high + tolerance)).sum())
        elif int(model.jnt_type[j]) == _BALL:
            count += int((_ball_angle(qpos[:, a : a + 4]) > high + tolerance).sum())
    return count
