"""The foot contacts the feet, balance and physics stages read: the decoder's, with the toes a
run stands on that it leaves unflagged.

The decoder flags a run's planted feet late and lets go early: at touch-down and toe-off the toe
is on the floor, slow, and not flagged, so the foot pin lets it slide (generated runs skated 1.26x
the real runs' on the 46 test run takes; walks, whose contacts it flags, 0.9x). A toe of a running
body (pelvis at :data:`RUN_SPEED` or more) below :data:`TOE_HEIGHT` and moving slower than half
the pelvis (and :data:`TOE_MAX_SPEED`) is counted as planted. Speeds are backward differences,
so the rule is causal and the stream applies it to each token with the last emitted frame as the
one before (the model card's Naturalness, session 19: run skating 1.26 -> 1.08x).
"""

from __future__ import annotations

import numpy as np

from motion_env.motion.skeleton import FOOT_JOINTS, FPS

__all__ = ["RUN_SPEED", "TOE_HEIGHT", "TOE_MAX_SPEED", "with_run_toes"]

RUN_SPEED = 1.8
"""(m/s) Pelvis speed from which the body runs (the data's walks 1.2-1.5 m/s, runs 2.7)."""
TOE_HEIGHT = 0.045
"""(m) A toe joint lower than this is on the floor (standing flat, 2-3 cm)."""
TOE_MAX_SPEED = 2.0
"""(m/s) A toe faster than this is swinging, whatever the pelvis's speed."""
_TOE_CHANNELS = (1, 3)  # the contact channels of the left and right toe (FOOT_JOINTS' order)


def _speeds(points: np.ndarray, before: np.ndarray | None) -> np.ndarray:
    """Horizontal speed (m/s) of (..., T, 3) points by backward differences; the first frame's from
    `before` (..., 3) (the frame before), or, without it, the same as the second frame's."""
    xz = points[..., [0, 2]]
    prev = xz[..., :1, :] if before is None else np.asarray(before)[..., None, [0, 2]]
    step = np.diff(np.concatenate([prev, xz], axis=-2), axis=-2)
    if before is None and points.shape[-2] > 1:
        step[..., 0, :] = step[..., 1, :]
    return np.linalg.norm(step, axis=-1) * FPS


def with_run_toes(joints: np.ndarray, contacts: np.ndarray, before: np.ndarray | None = None) -> np.ndarray:
    """The decoder's contact channels with a run's planted toes added.

    Args:
        joints: (..., T, 22, 3) the composed body.
        contacts: (..., T, 4) the decoded contact channels (> 0.5 = in contact).
        before: (..., 22, 3) the frame before the first (the stream's last emitted one), or None.

    Returns:
        (..., T, 4) float32: `contacts` with 1 where a toe is planted by the rule above.
    """
    pelvis = _speeds(joints[..., 0, :], None if before is None else before[..., 0, :])
    out = np.array(contacts, dtype=np.float32)
    for channel in _TOE_CHANNELS:
        toe = FOOT_JOINTS[channel]
        speed = _speeds(joints[..., toe, :], None if before is None else before[..., toe, :])
        planted = (
            (pelvis >= RUN_SPEED)
            & (joints[..., toe, 1] < TOE_HEIGHT)
            & (speed < np.minimum(0.5 * pelvis, TOE_MAX_SPEED))
        )
        out[..., channel] = np.where(planted, 1.0, out[..., channel])
    return out
