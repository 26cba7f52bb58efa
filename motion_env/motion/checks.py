"""Shape and value checks shared by the motion math (raise ValueError naming the argument)."""

from __future__ import annotations

import numpy as np

from motion_env.motion.skeleton import NUM_JOINTS

EPS = 1e-8
"""Guards divisions by a norm."""


def check_last(x: np.ndarray, size: int, name: str) -> np.ndarray:
    x = np.asarray(x)
    if x.ndim < 1 or x.shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {x.shape}")
    return x


def check_joints(joints: np.ndarray, name: str = "joints", min_frames: int = 1) -> np.ndarray:
    """Validate a (T, 22, 3) array and return it as float64."""
    joints = np.asarray(joints)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3) or joints.shape[0] < min_frames:
        raise ValueError(
            f"{name} must have shape (T, {NUM_JOINTS}, 3) with T >= {min_frames}, got {joints.shape}"
        )
    if not np.isfinite(joints).all():
        bad = np.unique(np.nonzero(~np.isfinite(joints))[0])
        raise ValueError(f"{name} has NaN or infinite values at frames {bad[:10].tolist()}")
    return joints.astype(np.float64)
