"""The HumanML3D 263-d feature vector: joints <-> features (port of ``process_file`` / ``recover_from_ric``).

numpy throughout; :func:`features_to_joints_torch` is the differentiable torch version used in
training (torch is imported inside it, so the numpy functions do not pull it in).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.ndimage import gaussian_filter1d

from motion_env.motion.kinematics import (
    bone_offsets,
    chain_local_rotations,
    forward_kinematics,
    heading_from_joints,
    rescale_bones,
    rotate_y,
)
from motion_env.motion.rotations import qbetween, qinv, qmul, qrot, quat_to_rot6d
from motion_env.motion.skeleton import (
    FACE_JOINTS,
    FEATURE_DIM,
    LEFT_FOOT,
    NUM_JOINTS,
    RIGHT_FOOT,
)
from motion_env.motion.skeleton import RIC as RIC_SLICE
from motion_env.motion.validation import EPS, check_finite, check_joints

if TYPE_CHECKING:
    import torch

__all__ = [
    "FACING_SMOOTH_SIGMA",
    "FOOT_CONTACT_THRESHOLD",
    "features_to_joints",
    "features_to_joints_torch",
    "joints_to_features",
    "recover_root",
    "rest_pose_features",
]

FOOT_CONTACT_THRESHOLD = 0.002
"""HumanML3D's ``feet_thre``: a foot joint is in contact when its squared displacement to the
next frame is below this (m², i.e. slower than about 4.5 cm per frame at 20 fps; no height test)."""

FACING_SMOOTH_SIGMA = 20.0
"""Gaussian sigma (frames) HumanML3D uses to smooth the facing direction of the root rotation."""


def _feature_root_quat(positions: np.ndarray) -> np.ndarray:
    """The root rotation of HumanML3D's features, (T, 22, 3) -> (T, 4), world -> body frame.

    A faithful copy of ``Skeleton.inverse_kinematics_np(..., smooth_forward=True)`` as it produced
    the released data, quirks included (both are needed to reproduce ``new_joint_vecs``):
    - it unpacks the face joints as (l_hip, r_hip, ...) while they are given as (r_hip, l_hip,
      ...), so its across vector is (left hip - right hip) + (right shoulder - left shoulder);
    - the forward direction is Gaussian-smoothed over time (sigma 20 frames, 'nearest' edges);
    - the first frame's root rotation is the identity (the data was made with that line active).
    This heading differs from :func:`heading_from_joints`, which uses the intended across vector.
    """
    r_hip, l_hip, r_sdr, l_sdr = FACE_JOINTS
    across = (positions[:, l_hip] - positions[:, r_hip]) + (positions[:, r_sdr] - positions[:, l_sdr])
    across = across / np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), EPS)
    forward = np.cross(np.array([[0.0, 1.0, 0.0]]), across)
    forward = gaussian_filter1d(forward, FACING_SMOOTH_SIGMA, axis=0, mode="nearest")
    forward = forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), EPS)
    root_quat = qbetween(forward, np.array([[0.0, 0.0, 1.0]]))
    root_quat[0] = [1.0, 0.0, 0.0, 0.0]
    return root_quat


def _foot_contacts(positions: np.ndarray, threshold: float) -> np.ndarray:
    """(T, 22, 3) -> (T-1, 4) contacts of (left ankle, left toe, right ankle, right toe)."""
    feet = list(LEFT_FOOT + RIGHT_FOOT)
    disp2 = ((positions[1:, feet] - positions[:-1, feet]) ** 2).sum(-1)
    return (disp2 < threshold).astype(np.float64)


def joints_to_features(
    joints: np.ndarray, feet_threshold: float = FOOT_CONTACT_THRESHOLD, floor: bool = True
) -> np.ndarray:
    """HumanML3D's ``process_file``: joint positions (T, 22, 3) -> 263-d features (T-1, 263).

    Steps, as the original: :func:`~motion_env.motion.kinematics.rescale_bones` to
    ``BONE_LENGTHS``; put on the floor (the lowest joint of the whole clip at y = 0; skipped with
    ``floor=False``, e.g. for clips already floored by :func:`canonicalize`); frame-0 pelvis to
    x = z = 0; rotate so frame 0 faces +Z;
    then per frame t < T-1 (layout in :mod:`motion_env.motion.skeleton`):

    - ROOT_ROT_VEL: half the yaw change of the smoothed root rotation from t to t+1 (radians);
    - ROOT_LIN_VEL: pelvis XZ displacement t -> t+1 in the body frame of t+1;
    - ROOT_Y: pelvis height; RIC: joints 1..21 relative to the pelvis XZ, in the body frame;
    - ROT6D: joints 1..21 local rotations (HumanML3D's IK) as 6-D;
    - LOCAL_VEL: all joints' displacement t -> t+1 in the body frame of t;
    - FOOT_CONTACT: squared foot-joint displacement below ``feet_threshold``.

    One deliberate deviation: the yaw change is taken between same-hemisphere quaternions, so a
    body turning through -Z gets the right sign (the original flips it there; the reference clip
    never faces -Z, so it reproduces unchanged). Returns float32.
    """
    positions = rescale_bones(check_joints(joints, min_frames=2))
    if floor:
        positions[..., 1] -= positions[..., 1].min()
    positions[..., [0, 2]] -= positions[0, 0, [0, 2]]
    positions = rotate_y(positions, -heading_from_joints(positions[0]))
    n = positions.shape[0]

    contacts = _foot_contacts(positions, feet_threshold)
    r_rot = _feature_root_quat(positions)  # (T, 4) world -> body
    local_rots = chain_local_rotations(positions, r_rot)
    rot6d = quat_to_rot6d(local_rots[:, 1:]).reshape(n, -1)

    root_vel = qrot(r_rot[1:], positions[1:, 0] - positions[:-1, 0])[:, [0, 2]]
    r_vel = qmul(r_rot[1:], qinv(r_rot[:-1]))
    r_vel = np.where(r_vel[:, :1] < 0, -r_vel, r_vel)
    root_rot_vel = np.arcsin(np.clip(r_vel[:, 2:3], -1.0, 1.0))

    ric = positions.copy()
    ric[..., [0, 2]] -= positions[:, :1, [0, 2]]
    ric = qrot(r_rot[:, None], ric)
    local_vel = qrot(r_rot[:-1, None], positions[1:] - positions[:-1])

    features = np.concatenate(
        [
            root_rot_vel,
            root_vel,
            positions[:-1, 0, 1:2],
            ric[:-1, 1:].reshape(n - 1, -1),
            rot6d[:-1],
            local_vel.reshape(n - 1, -1),
            contacts,
        ],
        axis=-1,
    )
    assert features.shape[-1] == FEATURE_DIM
    return features.astype(np.float32)


def rest_pose_features() -> np.ndarray:
    """(263,) features of the canonical skeleton standing in its rest pose (the random model's mean)."""
    rots = np.zeros((2, NUM_JOINTS, 4))
    rots[..., 0] = 1.0  # identity quaternions (w, x, y, z)
    height = -float(bone_offsets()[[2, 5, 8], 1].sum())  # hip + knee + ankle drop of the right leg
    joints = forward_kinematics(np.array([[0.0, height, 0.0]] * 2), rots)
    return joints_to_features(joints)[0].astype(np.float32)


def _check_features(features: np.ndarray) -> None:
    if features.ndim < 2 or features.shape[-1] != FEATURE_DIM or features.shape[-2] < 1:
        raise ValueError(
            f"features must have shape (..., T, {FEATURE_DIM}) with T >= 1, got {tuple(features.shape)}"
        )


def recover_root(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root heading and position from 263-d features (HumanML3D's ``recover_root_rot_pos``).

    features: (..., T, 263). Returns ``(heading (..., T), root_pos (..., T, 3))``: the heading
    is the features' smoothed root yaw (θ convention of this module, 0 at frame 0) and the root
    starts at x = z = 0.
    """
    features = np.asarray(features)
    _check_features(features)
    return _root_of(np.asarray(features[..., :4], dtype=np.float64))


def _root_of(channels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`recover_root` from the features' first four channels (..., T, 4), float64."""
    half = np.zeros(channels.shape[:-1])
    half[..., 1:] = np.cumsum(channels[..., :-1, 0], axis=-1)
    heading = -2.0 * half  # the body-frame quaternion is a yaw of 2 * half; its inverse is θ
    step = np.zeros(channels.shape[:-1] + (3,))
    step[..., 1:, 0] = channels[..., :-1, 1]
    step[..., 1:, 2] = channels[..., :-1, 2]
    root = np.cumsum(rotate_y(step, heading), axis=-2)
    root[..., 1] = channels[..., 3]
    return heading, root


def features_to_joints(
    features: np.ndarray | torch.Tensor, first: int = 0, only: Sequence[int] | None = None
) -> np.ndarray | torch.Tensor:
    """HumanML3D's ``recover_from_ric``: features (..., T, 263) -> joint positions (..., T, 22, 3).

    Uses the root channels and the RIC positions (not the rotations). A torch tensor is handed to
    :func:`features_to_joints_torch` and a tensor comes back; otherwise returns float32 numpy.

    `first` and `only` ask for part of it, the same numbers as that part of the whole (the root is
    integrated from frame 0 either way): frames first.. only, and only the joints `only` (indices,
    in that order), (..., T - first, len(only), 3).
    """
    if type(features).__module__.startswith("torch"):
        _check_part(first, only, int(features.shape[-2]) if features.ndim >= 2 else 0)
        whole = features_to_joints_torch(features)[..., first:, :, :]
        return whole if only is None else whole[..., list(only), :]
    features = np.asarray(features)
    _check_features(features)
    _check_part(first, only, features.shape[-2])
    check_finite(features.reshape(-1, FEATURE_DIM), "features", "frames")
    # float64 for the channels read (the root's and the RIC positions), not all 263
    heading, root = _root_of(np.asarray(features[..., :4], dtype=np.float64))
    heading, root = heading[..., first:], root[..., first:, :]
    ric = np.asarray(features[..., first:, RIC_SLICE], dtype=np.float64)
    ric = ric.reshape(features.shape[:-2] + (-1, NUM_JOINTS - 1, 3))
    order = np.arange(NUM_JOINTS) if only is None else np.asarray(only, np.int64)
    body = np.nonzero(order > 0)[0]  # joint 0 is the root itself, the others its RIC positions
    joints = rotate_y(ric[..., order[body] - 1, :], heading[..., None])  # per joint: a part is the same
    joints[..., [0, 2]] += root[..., None, [0, 2]]
    out = np.empty(root.shape[:-1] + (len(order), 3), np.float32)
    out[..., body, :] = joints
    out[..., order == 0, :] = root[..., None, :]
    return out


def _is_index(value: Any, stop: int) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and 0 <= value < stop


def _check_part(first: int, only: Sequence[int] | None, frames: int) -> None:
    """ValueError unless `first` is a frame of `frames` and `only` lists joint indices."""
    if not _is_index(first, max(frames, 1)):
        raise ValueError(f"first must be a frame index in [0, {frames}), got {first!r}")
    if only is not None and not (list(only) and all(_is_index(j, NUM_JOINTS) for j in only)):
        raise ValueError(f"only must list joint indices in [0, {NUM_JOINTS}), got {list(only)!r}")


def features_to_joints_torch(features: torch.Tensor) -> torch.Tensor:
    """Differentiable torch version of :func:`features_to_joints`.

    features: torch tensor (..., T, 263) on any device/dtype. Returns (..., T, 22, 3), same
    device and dtype. torch is imported here so that the numpy functions do not pull it in.
    """
    import torch

    if not isinstance(features, torch.Tensor):
        raise TypeError(f"features_to_joints_torch expects a torch.Tensor, got {type(features).__name__}")
    _check_features(features)
    half = torch.cumsum(features[..., :-1, 0], dim=-1)
    half = torch.cat([torch.zeros_like(half[..., :1]), half], dim=-1)
    cos, sin = torch.cos(2.0 * half), torch.sin(2.0 * half)  # rotation by θ = -2 * half

    def to_world(x: torch.Tensor, z: torch.Tensor, c: torch.Tensor, s: torch.Tensor) -> tuple:
        return x * c - z * s, x * s + z * c

    vel = torch.nn.functional.pad(features[..., :-1, 1:3], (0, 0, 1, 0))  # (..., T, 2), 0 at t=0
    vx, vz = to_world(vel[..., 0], vel[..., 1], cos, sin)
    root_x, root_z = torch.cumsum(vx, dim=-1), torch.cumsum(vz, dim=-1)
    ric = features[..., RIC_SLICE].reshape(features.shape[:-1] + (NUM_JOINTS - 1, 3))
    jx, jz = to_world(ric[..., 0], ric[..., 2], cos[..., None], sin[..., None])
    joints = torch.stack([jx + root_x[..., None], ric[..., 1], jz + root_z[..., None]], dim=-1)
    root = torch.stack([root_x, features[..., 3], root_z], dim=-1)
    return torch.cat([root[..., None, :], joints], dim=-2)
