"""The human side of retargeting: the clip in MuJoCo axes, the orientation of its body segments,
and its limb lengths.

Joint positions are all a :class:`~motion_env.motion.types.Motion` has, so every orientation is
built from joints that move rigidly together:

- ``pelvis``: the hips (left minus right) and spine1 above the pelvis: all three hang on the root;
- ``torso``: the collars (left minus right) and the neck above spine3: all hang on spine3;
- ``left_foot`` / ``right_foot``: ankle to toe, with the pelvis's left axis levelled (a position
  clip has no foot roll).

A frame is a rotation matrix whose columns are the segment's forward, left and up axes in
MuJoCo's world (x forward, y left, z up; :func:`motion_env.replay.humanoid.to_mujoco`). The
retargeter uses them relative to the same segment in the canonical rest pose
(:func:`rest_relative`), so a human standing in the rest pose maps onto the robot's own rest
orientation whatever the two rest poses look like.
"""

from __future__ import annotations

import functools

import numpy as np

from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.motion.validation import EPS
from motion_env.replay.humanoid import rest_positions, to_mujoco

__all__ = ["FRAMES", "LIMBS", "frames", "limb_length", "rest_relative"]

# What defines each segment frame: (joint giving +left, joint giving -left, lower, upper) for the
# trunk; (ankle, toe) for the feet.
_TRUNK = {
    "pelvis": ("left_hip", "right_hip", "pelvis", "spine1"),
    "torso": ("left_collar", "right_collar", "spine3", "neck"),
}
_FEET = {"left_foot": ("left_ankle", "left_foot"), "right_foot": ("right_ankle", "right_foot")}
FRAMES: tuple[str, ...] = (*_TRUNK, *_FEET)

# Limbs: the joint they hang from, then the joints along them. A limb's targets are placed from
# its root by the human's own limb vectors scaled to the robot's limb length.
LIMBS: dict[str, tuple[str, ...]] = {
    "left_leg": ("left_hip", "left_knee", "left_ankle", "left_foot"),
    "right_leg": ("right_hip", "right_knee", "right_ankle", "right_foot"),
    "left_arm": ("left_shoulder", "left_elbow", "left_wrist"),
    "right_arm": ("right_shoulder", "right_elbow", "right_wrist"),
}


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), EPS)


def _frame_from(left: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) with columns forward, left, up from a left and an up hint."""
    y = _unit(left)
    z = _unit(up - (up * y).sum(-1, keepdims=True) * y)
    return np.stack([np.cross(y, z), y, z], axis=-1)


def frames(joints: np.ndarray) -> dict[str, np.ndarray]:
    """Segment frames of a clip: name -> (T, 3, 3) rotations in MuJoCo's world.

    joints: (T, 22, 3) already in MuJoCo axes (:func:`to_mujoco`).
    """
    j = {name: joints[..., i, :] for name, i in JOINT_INDEX.items()}
    out = {name: _frame_from(j[lft] - j[rgt], j[hi] - j[lo]) for name, (lft, rgt, lo, hi) in _TRUNK.items()}
    # The foot's left axis is the pelvis's, levelled: a flat foot stays level, and a foot that
    # points straight down (heel raised at toe-off) keeps its yaw instead of flipping.
    level_left = out["pelvis"][..., :, 1] * np.array([1.0, 1.0, 0.0])
    for name, (ankle, toe) in _FEET.items():
        x = _unit(j[toe] - j[ankle])
        y = _unit(level_left - (level_left * x).sum(-1, keepdims=True) * x)
        out[name] = np.stack([x, y, np.cross(x, y)], axis=-1)
    return out


@functools.lru_cache(maxsize=1)
def _rest_frames() -> dict[str, np.ndarray]:
    return frames(to_mujoco(rest_positions())[None])


def rest_relative(segment_frames: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each frame times the inverse of the same frame in the canonical rest pose, (T, 3, 3): the
    rotation that carries the rest-pose segment onto the clip's."""
    rest = _rest_frames()
    return {name: r @ rest[name][0].T for name, r in segment_frames.items()}


def limb_length(joints: np.ndarray, names: tuple[str, ...]) -> float:
    """Median over frames of the summed distances between consecutive joints of `names` (metres).

    joints: (T, 22, 3).
    """
    idx = [JOINT_INDEX[n] for n in names]
    segments = np.linalg.norm(np.diff(joints[:, idx], axis=1), axis=-1).sum(axis=1)
    return float(np.median(segments))
