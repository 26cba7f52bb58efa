"""The canonical 22-joint HumanML3D ("t2m") skeleton: names, tree, chains and bone lengths.

Every motion in the project lives on this skeleton. Constants only; the math that uses them
lives in :mod:`motion_env.motion`.
"""

from __future__ import annotations

import numpy as np

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck", "left_collar",
    "right_collar", "head", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist",
)  # fmt: skip
NUM_JOINTS = len(JOINT_NAMES)
JOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(JOINT_NAMES)}

# Parent of each joint (-1 for the pelvis); parents always precede children.
PARENTS: tuple[int, ...] = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)

# HumanML3D's kinematic chains (right leg, left leg, spine, right arm, left arm).
CHAINS: tuple[tuple[int, ...], ...] = (
    (0, 2, 5, 8, 11),
    (0, 1, 4, 7, 10),
    (0, 3, 6, 9, 12, 15),
    (9, 14, 17, 19, 21),
    (9, 13, 16, 18, 20),
)
# The legs as (hip, knee, ankle, toe), left then right (the leg chains without the pelvis).
LEGS: tuple[tuple[int, int, int, int], ...] = ((1, 4, 7, 10), (2, 5, 8, 11))

# Left/right pairs; MIRROR_INDEX maps each joint to its mirror image.
LEFT_RIGHT_PAIRS: tuple[tuple[int, int], ...] = (
    (1, 2), (4, 5), (7, 8), (10, 11), (13, 14), (16, 17), (18, 19), (20, 21),
)  # fmt: skip
MIRROR_INDEX: tuple[int, ...] = tuple(
    next((b for a, b in LEFT_RIGHT_PAIRS if a == j), None)
    or next((a for a, b in LEFT_RIGHT_PAIRS if b == j), j)
    for j in range(NUM_JOINTS)
)

# Rest-pose bone directions of HumanML3D's t2m skeleton (paramUtil.t2m_raw_offsets): Y up,
# the character faces +Z, so its left is +X.
RAW_OFFSETS = np.array(
    [
        [0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, -1, 0], [0, 1, 0],
        [0, -1, 0], [0, -1, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1], [0, 1, 0], [1, 0, 0],
        [-1, 0, 0], [0, 0, 1], [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0],
        [0, -1, 0],
    ],
    dtype=np.float32,
)  # fmt: skip

# Canonical bone lengths in metres (length of the bone from PARENTS[j] to j; 0 for the
# pelvis), measured on HumanML3D's own sample clips, which is already on HumanML3D's target
# skeleton (the lengths vary by < 1e-6 m over its frames).
BONE_LENGTHS = np.array(
    [
        0.0, 0.10307, 0.10988, 0.13157, 0.39362, 0.39019, 0.14319, 0.43243, 0.42564, 0.05736,
        0.14338, 0.14942, 0.21936, 0.13749, 0.14338, 0.10304, 0.13161, 0.12298, 0.25684,
        0.26309, 0.26601, 0.26988,
    ],
    dtype=np.float32,
)  # fmt: skip

# Joints HumanML3D uses for facing direction and foot contacts.
FACE_JOINTS: tuple[int, int, int, int] = (2, 1, 17, 16)  # right hip, left hip, right/left shoulder
LEFT_FOOT: tuple[int, int] = (7, 10)  # left ankle, left toe ("foot")
RIGHT_FOOT: tuple[int, int] = (8, 11)
FOOT_JOINTS: tuple[int, ...] = LEFT_FOOT + RIGHT_FOOT

FPS = 20  # the canonical frame rate

# The 263-d HumanML3D feature layout: slices into one frame's vector.
FEATURE_DIM = 263
ROOT_ROT_VEL = slice(0, 1)
ROOT_LIN_VEL = slice(1, 3)
ROOT_Y = slice(3, 4)
RIC = slice(4, 4 + (NUM_JOINTS - 1) * 3)  # 21 joint positions relative to the root
ROT6D = slice(RIC.stop, RIC.stop + (NUM_JOINTS - 1) * 6)
LOCAL_VEL = slice(ROT6D.stop, ROT6D.stop + NUM_JOINTS * 3)
FOOT_CONTACT = slice(LOCAL_VEL.stop, LOCAL_VEL.stop + 4)
assert FOOT_CONTACT.stop == FEATURE_DIM
