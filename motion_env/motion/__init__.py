"""Motion math and the `Motion` type (numpy only): the bottom layer every other package builds on.

- :mod:`.skeleton`: the 22-joint HumanML3D skeleton, bone lengths, the 263-d feature layout.
- :mod:`.types`: :class:`Motion`, one clip of joint positions with `.npz` save/load.
- :mod:`.rotations`: quaternions (w, x, y, z), rotation matrices, axis-angle, 6-D.
- :mod:`.kinematics`: heading, bones, FK/IK, canonicalisation, mirroring, resampling.
- :mod:`.features`: HumanML3D's 263-d features (``joints_to_features`` / ``features_to_joints``).
- :mod:`.trajectory`: root paths (x, z, heading per frame) and waypoints.

The math is re-exported here, so ``motion_env.motion.joints_to_features`` works as before.
"""

from motion_env.motion.features import (
    FACING_SMOOTH_SIGMA,
    FOOT_CONTACT_THRESHOLD,
    features_to_joints,
    features_to_joints_torch,
    joints_to_features,
    recover_root,
)
from motion_env.motion.kinematics import (
    ROTATION_PARENTS,
    bone_lengths,
    bone_offsets,
    canonicalize,
    chain_local_rotations,
    floor_height,
    forward_kinematics,
    from_heading_frame,
    heading_from_joints,
    inverse_kinematics,
    mirror,
    resample,
    retarget,
    rotate_y,
    to_heading_frame,
    with_bone_lengths,
)
from motion_env.motion.rotations import (
    matrix_to_rot6d,
    qbetween,
    qfix,
    qinv,
    qmul,
    qnormalize,
    qrot,
    quat_from_axis_angle,
    quat_from_matrix,
    quat_from_yaw,
    quat_to_axis_angle,
    quat_to_matrix,
    quat_to_rot6d,
    rot6d_to_matrix,
    rot6d_to_quat,
)
from motion_env.motion.types import Motion

__all__ = [
    "FACING_SMOOTH_SIGMA", "FOOT_CONTACT_THRESHOLD", "ROTATION_PARENTS", "Motion", "bone_lengths",
    "bone_offsets", "canonicalize", "chain_local_rotations", "features_to_joints",
    "features_to_joints_torch", "floor_height", "forward_kinematics", "from_heading_frame",
    "heading_from_joints", "inverse_kinematics", "joints_to_features", "matrix_to_rot6d", "mirror",
    "qbetween", "qfix", "qinv", "qmul", "qnormalize", "qrot", "quat_from_axis_angle",
    "quat_from_matrix", "quat_from_yaw", "quat_to_axis_angle", "quat_to_matrix", "quat_to_rot6d",
    "recover_root", "resample", "retarget", "rot6d_to_matrix", "rot6d_to_quat", "rotate_y",
    "to_heading_frame", "with_bone_lengths",
]  # fmt: skip
