"""Quality metrics, as ``docs/metrics.md`` defines them (numpy; one implementation each).

- root error: :func:`motion_env.motion.trajectory.waypoint_errors` (pure path math, used by the
  trainers too) averaged over waypoints;
- foot skating: :func:`foot_skating_ratio`;
- foot contacts of a clip without contact labels: :func:`detect_foot_contacts`.
"""

from __future__ import annotations

import numpy as np

from motion_env.motion.checks import check_joints
from motion_env.motion.skeleton import FOOT_JOINTS, FPS

__all__ = ["SKATE_HEIGHT", "SKATE_STEP", "detect_foot_contacts", "foot_skating_ratio"]

# Foot skating: a foot joint below this height (m) ...
SKATE_HEIGHT = 0.05
# ... that moves more than this (m) horizontally from the previous frame (at 20 fps).
SKATE_STEP = 0.025


def foot_skating_ratio(joints: np.ndarray, height: float = SKATE_HEIGHT, step: float = SKATE_STEP) -> float:
    """Share of frames in which a foot joint (ankle or toe) below `height` m moves more than `step` m.

    The definition of ``docs/metrics.md``: frame t (t >= 1) skates when any of the four foot joints is below
    `height` at t and its XZ moved more than `step` from t-1 (20 fps). Returns 0 for a single frame.
    """
    joints = check_joints(joints)
    if joints.shape[0] < 2:
        return 0.0
    feet = joints[:, list(FOOT_JOINTS)]  # (T, 4, 3)
    low = feet[1:, :, 1] < height
    moved = np.linalg.norm(feet[1:, :, [0, 2]] - feet[:-1, :, [0, 2]], axis=-1) > step
    return float((low & moved).any(axis=1).mean())


def detect_foot_contacts(joints: np.ndarray, margin: float = 0.03, max_speed: float = 1.0) -> np.ndarray:
    """Foot contacts from height and speed: (T, 22, 3) -> (T, 4) bool for FOOT_JOINTS.

    A foot joint is in contact when it is within `margin` m of its own resting height (the 5th
    percentile of its height over the clip, so a clip that floats or sinks still works) and moves
    slower than `max_speed` m/s; isolated single frames are dropped.
    """
    joints = check_joints(joints)
    feet = joints[:, list(FOOT_JOINTS)]
    rest = np.percentile(feet[..., 1], 5, axis=0)
    step = np.zeros(feet.shape[:2])
    if len(feet) > 1:
        d = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1)
        step[1:] = d
        step[0] = d[0]
    contact = (feet[..., 1] < rest + margin) & (step * FPS < max_speed)
    lone = contact.copy()
    lone[1:-1] &= ~contact[:-2] & ~contact[2:]
    if len(contact) > 2:
        contact[1:-1] &= ~lone[1:-1]
    return contact
