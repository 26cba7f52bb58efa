"""Motion math and the `Motion` type (numpy only): the bottom layer every other package builds on.

- :mod:`.skeleton`: the 22-joint HumanML3D skeleton, bone lengths, the 263-d feature layout.
- :mod:`.types`: :class:`Motion`, one clip of joint positions with `.npz` save/load.
- :mod:`.rotations`: quaternions (w, x, y, z), rotation matrices, axis-angle, 6-D.
- :mod:`.kinematics`: heading, bones, FK/IK, canonicalisation, mirroring, resampling.
- :mod:`.features`: HumanML3D's 263-d features (``joints_to_features`` / ``features_to_joints``).
- :mod:`.trajectory`: root paths (x, z, heading per frame) and waypoints.
- :mod:`.validation`: the shape and value checks they share.

The math (rotations, kinematics, features) is re-exported here: ``motion_env.motion.joints_to_features``.
"""

from motion_env.motion import features, kinematics, rotations
from motion_env.motion.features import *  # noqa: F403
from motion_env.motion.kinematics import *  # noqa: F403
from motion_env.motion.rotations import *  # noqa: F403
from motion_env.motion.types import Motion

__all__ = ["Motion", *rotations.__all__, *kinematics.__all__, *features.__all__]
