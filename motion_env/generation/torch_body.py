"""Torch twins of the motion math the refinement differentiates through (numpy originals in
:mod:`motion_env.motion`; ``tests/generation/test_refine.py`` checks that they agree).

- :func:`local_pose_torch`: decoded features -> the local pose of
  :func:`~motion_env.generation.recompose.local_pose_from_features`, with the per-frame yaw between
  the features' root frame and the hips-and-shoulders heading frame held fixed (:func:`frame_yaw`);
- :func:`with_bone_lengths_torch`: :func:`motion_env.motion.kinematics.with_bone_lengths`;
- :func:`fit_bone_lengths_torch`: :func:`motion_env.motion.kinematics.fit_bone_lengths`;
- :func:`hold_pelvis_shape_torch`: :func:`motion_env.motion.kinematics.hold_pelvis_shape`;
- :func:`place_on_path_torch`: :func:`~motion_env.generation.recompose.recompose` onto a fixed path.
"""

from __future__ import annotations

import numpy as np
import torch

from motion_env.motion.features import features_to_joints, recover_root
from motion_env.motion.kinematics import BONE_CHILDREN, BONE_PARENTS, BONE_SHARE, FIT_ITERATIONS
from motion_env.motion.skeleton import (
    BONE_LENGTHS,
    CHAINS,
    LEGS,
    NUM_JOINTS,
    PARENTS,
    RAW_OFFSETS,
    RIC,
    ROOT_Y,
)
from motion_env.motion.trajectory import root_path_from_joints

__all__ = [
    "fit_bone_lengths_torch",
    "frame_yaw",
    "hold_pelvis_shape_torch",
    "local_pose_torch",
    "place_on_path_torch",
    "rotate_y_torch",
    "with_bone_lengths_torch",
]


def rotate_y_torch(points: torch.Tensor, theta: torch.Tensor) -> torch.Tensor:
    """:func:`motion_env.motion.kinematics.rotate_y` in torch: (..., 3) points, theta broadcast to (...)."""
    c, s = torch.cos(theta), torch.sin(theta)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return torch.stack([x * c + z * s, y, -x * s + z * c], dim=-1)


def frame_yaw(features: np.ndarray) -> np.ndarray:
    """(n, 263) features -> (n,) yaw from the features' root frame to the local pose's heading frame.

    :func:`~motion_env.generation.recompose.local_pose_from_features` turns the features into world
    joints with the features' own (smoothed) root rotation and takes out the smoothed
    hips-and-shoulders heading; the local pose is the RIC channels turned by the difference.
    """
    heading, _ = recover_root(features)
    joints = features_to_joints(np.asarray(features, np.float32))
    return (heading - root_path_from_joints(joints)[:, 2]).astype(np.float32)


def local_pose_torch(features: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
    """(n, 263) features and (n,) :func:`frame_yaw` -> (n, 22, 3) local pose (pelvis at x = z = 0)."""
    n = features.shape[0]
    ric = features[:, RIC].reshape(n, NUM_JOINTS - 1, 3)
    body = rotate_y_torch(ric, yaw[:, None])
    pelvis = torch.stack([torch.zeros_like(yaw), features[:, ROOT_Y.start], torch.zeros_like(yaw)], dim=-1)
    return torch.cat([pelvis[:, None], body], dim=1)


def with_bone_lengths_torch(joints: torch.Tensor) -> torch.Tensor:
    """:func:`motion_env.motion.kinematics.with_bone_lengths` with the canonical lengths: (T, 22, 3)."""
    return _rebuild_torch(joints, joints[:, 0])


def fit_bone_lengths_torch(joints: torch.Tensor, iterations: int = FIT_ITERATIONS) -> torch.Tensor:
    """:func:`motion_env.motion.kinematics.fit_bone_lengths` with the canonical lengths: (T, 22, 3)."""
    target = joints.new_tensor(BONE_LENGTHS[BONE_CHILDREN])[:, None]
    share = joints.new_tensor(BONE_SHARE)
    x = joints
    for _ in range(int(iterations)):
        bone = x[:, BONE_CHILDREN] - x[:, BONE_PARENTS]
        excess = (1.0 - target / bone.norm(dim=-1, keepdim=True).clamp_min(1e-9)) * bone
        x = x - torch.einsum("jb,tbk->tjk", share, excess)
    return _rebuild_torch(x, joints[:, 0])


def _rebuild_torch(joints: torch.Tensor, pelvis: torch.Tensor) -> torch.Tensor:
    """The poses of `joints` (T, 22, 3) rebuilt from `pelvis` (T, 3) outward along their bones'
    directions, on the canonical lengths (a zero-length bone takes its rest direction)."""
    lengths = joints.new_tensor(BONE_LENGTHS)
    rest = joints.new_tensor(RAW_OFFSETS)
    out = [pelvis]
    for j in range(1, NUM_JOINTS):
        vec = joints[:, j] - joints[:, PARENTS[j]]
        norm = vec.norm(dim=-1, keepdim=True)
        direction = torch.where(norm > 1e-9, vec / norm.clamp_min(1e-9), rest[j])
        out.append(out[PARENTS[j]] + direction * lengths[j])
    return torch.stack(out, dim=1)


def place_on_path_torch(local: torch.Tensor, path: torch.Tensor, pelvis: float | None = None) -> torch.Tensor:
    """:func:`~motion_env.generation.recompose.recompose` (``face_travel=False``) on bone lengths
    (:func:`fit_bone_lengths_torch`), with the pelvis shape `pelvis` held where given
    (:func:`hold_pelvis_shape_torch`, as :meth:`~motion_env.generation.pipeline.Pipeline.compose` does):
    (T, 22, 3) local pose, (T, 3) path (x, z, heading; already turned to the travel) -> world joints."""
    local = (
        local - torch.stack([local[:, 0, 0], torch.zeros_like(local[:, 0, 0]), local[:, 0, 2]], -1)[:, None]
    )
    world = rotate_y_torch(local, path[:, None, 2])
    shift = torch.stack([path[:, 0], torch.zeros_like(path[:, 0]), path[:, 1]], dim=-1)
    joints = fit_bone_lengths_torch(world + shift[:, None])
    return joints if pelvis is None else hold_pelvis_shape_torch(joints, pelvis)


_HIPS, _LEG_JOINTS = [leg[0] for leg in LEGS], np.array(LEGS)


def hold_pelvis_shape_torch(joints: torch.Tensor, shape: float) -> torch.Tensor:
    """:func:`motion_env.motion.kinematics.hold_pelvis_shape` with one shape (m): (T, 22, 3)."""
    left, right = joints[:, _HIPS[0]], joints[:, _HIPS[1]]
    across = left - right
    across = across / across.norm(dim=-1, keepdim=True).clamp_min(1e-9)
    up = joints[:, CHAINS[2][1]] - 0.5 * (left + right)
    up = up - (up * across).sum(-1, keepdim=True) * across
    up = (up / up.norm(dim=-1, keepdim=True).clamp_min(1e-9))[:, None]  # (T, 1, 3): both legs at once
    bone = joints[:, _HIPS] - joints[:, :1]  # (T, 2, 3)
    length = bone.norm(dim=-1)
    side = bone - (bone * up).sum(-1, keepdim=True) * up
    along = torch.minimum(torch.maximum(torch.full_like(length, -shape), -0.9 * length), 0.9 * length)
    scale = (length**2 - along**2).sqrt() / side.norm(dim=-1).clamp_min(1e-9)
    moved = side * scale[..., None] + along[..., None] * up - bone  # (T, 2, 3)
    moves = torch.zeros_like(joints)
    moves[:, _LEG_JOINTS] = moved[:, :, None].expand(-1, -1, _LEG_JOINTS.shape[1], -1)  # legs with their hips
    return joints + moves
