"""A light zero-phase low-pass filter over a robot clip's qpos.

The IK is warm-started frame to frame and damped, so its output is already continuous; the filter
takes off the frame-to-frame jitter that stepping a few QP iterations per frame leaves. Positions
and hinge angles are filtered as numbers; the quaternions of free and ball joints component-wise
after putting consecutive ones in the same hemisphere, then normalised.
"""

from __future__ import annotations

import mujoco
import numpy as np
from scipy.ndimage import gaussian_filter1d

__all__ = ["quaternion_columns", "smooth_qpos"]


def quaternion_columns(model: mujoco.MjModel) -> list[int]:
    """qpos index of the first (w) entry of every quaternion (free and ball joints)."""
    out = []
    for j in range(model.njnt):
        a = int(model.jnt_qposadr[j])
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            out.append(a + 3)
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            out.append(a)
    return out


def smooth_qpos(model: mujoco.MjModel, qpos: np.ndarray, sigma_frames: float) -> np.ndarray:
    """`qpos` (T, nq) low-passed along time with a Gaussian of `sigma_frames` (a new array).

    sigma_frames <= 0 returns a copy.
    """
    out = np.array(qpos, dtype=np.float64)
    if sigma_frames <= 0 or out.shape[0] < 2:
        return out
    quats = quaternion_columns(model)
    for a in quats:
        q = out[:, a : a + 4]
        # q and -q are one rotation: flip each to the hemisphere of the previous frame.
        flips = np.cumprod(np.where((q[1:] * q[:-1]).sum(-1) < 0, -1.0, 1.0))
        q[1:] *= flips[:, None]
    # Extend the clip past each end by its point reflection (2 x_end - x mirrored): a joint or the
    # root moving at a steady speed keeps it to the last frame. Repeating the end frame ("nearest")
    # would brake every motion over the last few frames, a force no floor supplies to a runner.
    pad = min(int(np.ceil(4 * sigma_frames)), out.shape[0] - 1)
    head = 2 * out[:1] - out[pad:0:-1]
    tail = 2 * out[-1:] - out[-2 : -pad - 2 : -1]
    padded = np.concatenate([head, out, tail])
    out = gaussian_filter1d(padded, sigma_frames, axis=0, mode="nearest")[pad : pad + out.shape[0]]
    for a in quats:
        q = out[:, a : a + 4]
        q /= np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
        q *= np.where(q[:, :1] < 0, -1.0, 1.0)  # w >= 0, as MuJoCo writes them
    return out
