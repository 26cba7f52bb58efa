"""Pure motion math on the canonical 22-joint skeleton (numpy; a torch decoder for training).

Conventions (see docs/PRODUCT.md): metres, Y up, floor at y = 0. Quaternions are ``(..., 4)``
arrays ``(w, x, y, z)``. A heading θ is a yaw about +Y; θ = 0 faces +Z and the facing direction
is ``(sin θ, cos θ)`` in (x, z). The heading frame of a character has x = lateral (+ is the
character's left, which is +X at θ = 0) and z = forward.

Rotation representations:

- rotation matrices ``(..., 3, 3)`` act on column vectors;
- the 6-D representation is HumanML3D's ``cont6d``: the first two *columns* of the matrix,
  concatenated, ``(..., 6)``.

Kinematics follow HumanML3D's ``Skeleton``: joint ``j`` carries the rotation of the bone that
ends at ``j`` relative to its *rotation parent*, which is the previous joint of its chain in
:data:`skeleton.CHAINS`, except that a chain's first bone is relative to the pelvis rotation
(so the collars hang off the pelvis frame, not spine3's). The rest pose has every bone along
:data:`skeleton.RAW_OFFSETS`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import gaussian_filter1d

from motion_env.skeleton import (
    BONE_LENGTHS,
    CHAINS,
    FACE_JOINTS,
    FEATURE_DIM,
    FOOT_JOINTS,
    LEFT_FOOT,
    MIRROR_INDEX,
    NUM_JOINTS,
    PARENTS,
    RAW_OFFSETS,
    RIGHT_FOOT,
)
from motion_env.skeleton import RIC as RIC_SLICE

if TYPE_CHECKING:
    import torch

_EPS = 1e-8


def _rotation_parents() -> tuple[int, ...]:
    parents = [-1] * NUM_JOINTS
    for chain in CHAINS:
        for i in range(1, len(chain)):
            parents[chain[i]] = 0 if i == 1 else chain[i - 1]
    return tuple(parents)


ROTATION_PARENTS: tuple[int, ...] = _rotation_parents()
"""Rotation parent of each joint in HumanML3D's chain-wise kinematics (see the module docstring)."""


# ----------------------------------------------------------------------------------------------
# Shape checks
# ----------------------------------------------------------------------------------------------


def _check_last(x: np.ndarray, size: int, name: str) -> np.ndarray:
    x = np.asarray(x)
    if x.ndim < 1 or x.shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {x.shape}")
    return x


def _check_joints(joints: np.ndarray, name: str = "joints", min_frames: int = 1) -> np.ndarray:
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


# ----------------------------------------------------------------------------------------------
# Quaternions (w, x, y, z)
# ----------------------------------------------------------------------------------------------


def qnormalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4)."""
    q = _check_last(q, 4, "q")
    return q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), _EPS)


def qinv(q: np.ndarray) -> np.ndarray:
    """Inverse (conjugate) of unit quaternions (..., 4)."""
    q = _check_last(q, 4, "q")
    return q * np.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype if q.dtype.kind == "f" else np.float64)


def qmul(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Hamilton product ``q * r`` (apply r, then q); shapes broadcast, (..., 4)."""
    q = _check_last(q, 4, "q")
    r = _check_last(r, 4, "r")
    w1, x1, y1, z1 = np.moveaxis(q, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(r, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4); shapes broadcast."""
    q = _check_last(q, 4, "q")
    v = _check_last(v, 3, "v")
    qvec = q[..., 1:]
    uv = np.cross(qvec, v)
    uuv = np.cross(qvec, uv)
    return v + 2.0 * (q[..., :1] * uv + uuv)


def qbetween(v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """The shortest-arc unit quaternion rotating direction v0 onto v1, (..., 3) -> (..., 4).

    Same formula as HumanML3D's ``qbetween``; for opposite directions (where that formula is
    0/0) it returns a half turn about an axis perpendicular to v0.
    """
    v0 = _check_last(v0, 3, "v0").astype(np.float64)
    v1 = _check_last(v1, 3, "v1").astype(np.float64)
    v0, v1 = np.broadcast_arrays(v0, v1)
    w = np.sqrt((v0**2).sum(-1, keepdims=True) * (v1**2).sum(-1, keepdims=True)) + (v0 * v1).sum(
        -1, keepdims=True
    )
    q = np.concatenate([w, np.cross(v0, v1)], axis=-1)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    scale = np.sqrt((v0**2).sum(-1, keepdims=True) * (v1**2).sum(-1, keepdims=True))
    opposite = (norm < 1e-6 * np.maximum(scale, _EPS))[..., 0]
    if opposite.any():
        # Any axis perpendicular to v0 works; cross with the coordinate axis least aligned to it.
        a = v0[opposite]
        helper = np.eye(3)[np.argmin(np.abs(a), axis=-1)]
        axis = np.cross(a, helper)
        axis /= np.maximum(np.linalg.norm(axis, axis=-1, keepdims=True), _EPS)
        q = q.copy()
        q[opposite] = np.concatenate([np.zeros(axis.shape[:-1] + (1,)), axis], axis=-1)
        norm = np.linalg.norm(q, axis=-1, keepdims=True)
    return q / np.maximum(norm, _EPS)


def qfix(q: np.ndarray) -> np.ndarray:
    """Flip signs along axis 0 (time) so consecutive quaternions have a non-negative dot product.

    q: (T, ..., 4). Returns the same rotations, continuous in time (as HumanML3D's ``qfix``).
    """
    q = _check_last(q, 4, "q")
    if q.ndim < 2:
        raise ValueError(f"qfix needs a time axis: q must have shape (T, ..., 4), got {q.shape}")
    dots = (q[1:] * q[:-1]).sum(-1)
    flip = np.cumsum(dots < 0, axis=0) % 2 == 1
    out = q.copy()
    out[1:][flip] *= -1
    return out


def quat_from_yaw(theta: np.ndarray) -> np.ndarray:
    """Rotations about +Y by angle θ (...,) -> (..., 4); θ = heading maps +Z onto the facing."""
    theta = np.asarray(theta, dtype=np.float64)
    zeros = np.zeros_like(theta)
    return np.stack([np.cos(theta / 2), zeros, np.sin(theta / 2), zeros], axis=-1)


def quat_from_axis_angle(axis_angle: np.ndarray) -> np.ndarray:
    """Axis-angle vectors (..., 3) (direction = axis, norm = angle in radians) -> (..., 4)."""
    aa = _check_last(axis_angle, 3, "axis_angle").astype(np.float64)
    angle = np.linalg.norm(aa, axis=-1, keepdims=True)
    # sin(a/2)/a written with np.sinc so that a -> 0 is exact (sinc(x) = sin(pi x)/(pi x)).
    return np.concatenate([np.cos(angle / 2), 0.5 * np.sinc(angle / (2 * np.pi)) * aa], axis=-1)


def quat_to_axis_angle(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) -> axis-angle vectors (..., 3), angles in [0, π]."""
    q = qnormalize(q).astype(np.float64)
    q = np.where(q[..., :1] < 0, -q, q)  # pick the representative with angle <= π
    sin_half = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sin_half, q[..., :1])
    scale = np.where(sin_half > 1e-12, angle / np.maximum(sin_half, 1e-12), 2.0)
    return q[..., 1:] * scale


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) (normalised here) -> rotation matrices (..., 3, 3)."""
    q = _check_last(q, 4, "q").astype(np.float64)
    w, x, y, z = np.moveaxis(q, -1, 0)
    two_s = 2.0 / np.maximum((q * q).sum(-1), _EPS)
    m = np.stack(
        [
            1 - two_s * (y * y + z * z), two_s * (x * y - z * w), two_s * (x * z + y * w),
            two_s * (x * y + z * w), 1 - two_s * (x * x + z * z), two_s * (y * z - x * w),
            two_s * (x * z - y * w), two_s * (y * z + x * w), 1 - two_s * (x * x + y * y),
        ],
        axis=-1,
    )  # fmt: skip
    return m.reshape(q.shape[:-1] + (3, 3))


def quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) with w >= 0."""
    m = np.asarray(m, dtype=np.float64)
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must have shape (..., 3, 3), got {m.shape}")
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # Four candidate solutions, each well conditioned when its |component| is largest.
    cands = np.stack(
        [
            np.stack([1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01], -1),
            np.stack([m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20], -1),
            np.stack([m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21], -1),
            np.stack([m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22], -1),
        ],
        axis=-2,
    )  # (..., 4 candidates, 4)
    diag = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = qnormalize(q)
    return np.where(q[..., :1] < 0, -q, q)


def matrix_to_rot6d(m: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> HumanML3D 6-D (first two columns), (..., 6)."""
    m = np.asarray(m)
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must have shape (..., 3, 3), got {m.shape}")
    return np.concatenate([m[..., :, 0], m[..., :, 1]], axis=-1)


def rot6d_to_matrix(d6: np.ndarray) -> np.ndarray:
    """HumanML3D 6-D (..., 6) -> rotation matrices (..., 3, 3) by Gram-Schmidt (``cont6d_to_matrix``)."""
    d6 = _check_last(d6, 6, "rot6d").astype(np.float64)
    x = d6[..., :3] / np.maximum(np.linalg.norm(d6[..., :3], axis=-1, keepdims=True), _EPS)
    z = np.cross(x, d6[..., 3:])
    z /= np.maximum(np.linalg.norm(z, axis=-1, keepdims=True), _EPS)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-1)


def quat_to_rot6d(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) -> 6-D (..., 6)."""
    return matrix_to_rot6d(quat_to_matrix(q))


def rot6d_to_quat(d6: np.ndarray) -> np.ndarray:
    """6-D (..., 6) -> unit quaternions (..., 4), w >= 0."""
    return quat_from_matrix(rot6d_to_matrix(d6))


# ----------------------------------------------------------------------------------------------
# Heading and the heading frame
# ----------------------------------------------------------------------------------------------


def _across(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 3): right-minus-left of hips plus shoulders (points to the right)."""
    r_hip, l_hip, r_sdr, l_sdr = FACE_JOINTS
    return (joints[..., r_hip, :] - joints[..., l_hip, :]) + (joints[..., r_sdr, :] - joints[..., l_sdr, :])


def heading_from_joints(joints: np.ndarray) -> np.ndarray:
    """Yaw θ of each pose from the hips + shoulders across vector, as HumanML3D faces a body.

    joints: (..., 22, 3), usually (T, 22, 3). Returns (...,) angles in (-π, π]; the facing
    direction is ``(sin θ, cos θ)`` in (x, z) and θ = 0 faces +Z.
    """
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim < 2 or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must have shape (..., {NUM_JOINTS}, 3), got {joints.shape}")
    across = _across(joints)
    # forward = up x across = (across_z, 0, -across_x)
    return np.arctan2(across[..., 2], -across[..., 0])


def to_heading_frame(vec_xz: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """World (dx, dz) vectors (..., 2) into the frame of a character with heading θ (...).

    Returns (..., 2) = (lateral, forward); lateral > 0 is the character's left.
    """
    vec_xz = _check_last(vec_xz, 2, "vec_xz").astype(np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    dx, dz = vec_xz[..., 0], vec_xz[..., 1]
    return np.stack([dx * c - dz * s, dx * s + dz * c], axis=-1)


def from_heading_frame(vec_local: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_heading_frame`: (lateral, forward) (..., 2) -> world (dx, dz)."""
    vec_local = _check_last(vec_local, 2, "vec_local").astype(np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    lx, lz = vec_local[..., 0], vec_local[..., 1]
    return np.stack([lx * c + lz * s, -lx * s + lz * c], axis=-1)


def rotate_y(points: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    """Rotate points (..., 3) about +Y by θ (broadcast against ``points[..., 0]``).

    A character with heading h gets heading h + θ; +Z goes to (sin θ, 0, cos θ).
    """
    points = _check_last(points, 3, "points").astype(np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    return np.stack([x * c + z * s, np.broadcast_to(y, np.broadcast(x, c).shape), -x * s + z * c], axis=-1)


# ----------------------------------------------------------------------------------------------
# Skeleton geometry, kinematics
# ----------------------------------------------------------------------------------------------


def bone_lengths(joints: np.ndarray) -> np.ndarray:
    """Length of the bone ending at each joint, (..., 22, 3) -> (..., 22) (0 for the pelvis)."""
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim < 2 or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must have shape (..., {NUM_JOINTS}, 3), got {joints.shape}")
    parents = np.array([max(p, 0) for p in PARENTS])
    return np.linalg.norm(joints - joints[..., parents, :], axis=-1)


def bone_offsets(lengths: np.ndarray = BONE_LENGTHS) -> np.ndarray:
    """Rest-pose offsets (..., 22, 3) = RAW_OFFSETS scaled by bone lengths (..., 22)."""
    lengths = _check_last(lengths, NUM_JOINTS, "lengths").astype(np.float64)
    return lengths[..., None] * RAW_OFFSETS.astype(np.float64)


def _bone_directions(joints: np.ndarray) -> np.ndarray:
    """Unit direction of each bone (T, 22, 3); a zero-length bone keeps its rest direction."""
    parents = np.array([max(p, 0) for p in PARENTS])
    vec = joints - joints[:, parents]
    norm = np.linalg.norm(vec, axis=-1, keepdims=True)
    rest = np.broadcast_to(RAW_OFFSETS.astype(np.float64), vec.shape)
    dirs = np.where(norm > 1e-9, vec / np.maximum(norm, 1e-9), rest)
    dirs[:, 0] = 0.0
    return dirs


def _chain_local_rotations(joints: np.ndarray, root_quat: np.ndarray) -> np.ndarray:
    """HumanML3D's ``inverse_kinematics_np`` given the root rotation: (T,22,3), (T,4) -> (T,22,4).

    Each bone's world rotation is the shortest arc from its rest direction to the observed one;
    its local rotation is relative to the rotation parent's world rotation (the root's for the
    first bone of each chain).
    """
    dirs = _bone_directions(joints)
    world = np.zeros(joints.shape[:-1] + (4,))  # world rotation of each bone
    world[:, 0] = root_quat
    rest = np.broadcast_to(RAW_OFFSETS.astype(np.float64), dirs.shape)
    world[:, 1:] = qbetween(rest[:, 1:], dirs[:, 1:])
    local = qmul(qinv(world[:, list(ROTATION_PARENTS[1:])]), world[:, 1:])
    return np.concatenate([world[:, :1], local], axis=1)


def forward_kinematics(
    root_pos: np.ndarray, local_rots: np.ndarray, offsets: np.ndarray | None = None
) -> np.ndarray:
    """Joint positions from root positions and local rotations (HumanML3D chain convention).

    root_pos: (T, 3) pelvis positions. local_rots: (T, 22, 4) quaternions, joint 0 = the root's
    world rotation. offsets: (22, 3) or (T, 22, 3) rest-pose bone vectors (default
    ``bone_offsets(BONE_LENGTHS)``). Returns (T, 22, 3).
    """
    root_pos = np.asarray(root_pos, dtype=np.float64)
    local_rots = np.asarray(local_rots, dtype=np.float64)
    if root_pos.ndim != 2 or root_pos.shape[1] != 3:
        raise ValueError(f"root_pos must have shape (T, 3), got {root_pos.shape}")
    n = root_pos.shape[0]
    if local_rots.shape != (n, NUM_JOINTS, 4):
        raise ValueError(
            f"local_rots must have shape ({n}, {NUM_JOINTS}, 4) to match root_pos, got {local_rots.shape}"
        )
    offsets = bone_offsets() if offsets is None else np.asarray(offsets, dtype=np.float64)
    if offsets.shape not in ((NUM_JOINTS, 3), (n, NUM_JOINTS, 3)):
        raise ValueError(
            f"offsets must have shape ({NUM_JOINTS}, 3) or ({n}, {NUM_JOINTS}, 3), got {offsets.shape}"
        )
    offsets = np.broadcast_to(offsets, (n, NUM_JOINTS, 3))
    local_rots = qnormalize(local_rots)
    world = np.zeros((n, NUM_JOINTS, 4))
    world[:, 0] = local_rots[:, 0]
    joints = np.zeros((n, NUM_JOINTS, 3))
    joints[:, 0] = root_pos
    for j in range(1, NUM_JOINTS):  # parents precede children in both trees
        world[:, j] = qmul(world[:, ROTATION_PARENTS[j]], local_rots[:, j])
        joints[:, j] = joints[:, PARENTS[j]] + qrot(world[:, j], offsets[:, j])
    return joints


def inverse_kinematics(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root positions and local rotations that reproduce joint positions (bone directions).

    joints: (T, 22, 3). Returns ``(root_pos (T, 3), local_rots (T, 22, 4))``: the root rotation is
    the yaw :func:`quat_from_yaw` of :func:`heading_from_joints` (pelvis tilt lives in the child
    bones); each other joint holds the shortest-arc rotation of its bone from the rest direction,
    relative to its rotation parent. Quaternions are made continuous in time (:func:`qfix`).
    ``forward_kinematics(*inverse_kinematics(j), bone_offsets(bone_lengths(j)))`` gives back ``j``.
    """
    joints = _check_joints(joints)
    root_quat = quat_from_yaw(heading_from_joints(joints))
    return joints[:, 0].copy(), qfix(_chain_local_rotations(joints, root_quat))


# ----------------------------------------------------------------------------------------------
# Whole-clip operations
# ----------------------------------------------------------------------------------------------


def retarget(joints: np.ndarray, lengths: np.ndarray = BONE_LENGTHS) -> np.ndarray:
    """Rebuild poses from the pelvis down with new bone lengths, keeping every bone's direction.

    joints: (T, 22, 3); lengths: (22,). As HumanML3D's ``uniform_skeleton``, the pelvis
    trajectory is scaled by the ratio of leg lengths (knee->ankle + hip->knee of the right leg,
    median over frames) so that steps keep their size relative to the legs. Returns (T, 22, 3).
    """
    joints = _check_joints(joints)
    lengths = _check_lengths(lengths)
    src = np.median(bone_lengths(joints), axis=0)
    r_knee, r_ankle = 5, 8
    src_leg = src[r_knee] + src[r_ankle]
    scale = (lengths[r_knee] + lengths[r_ankle]) / src_leg if src_leg > 1e-9 else 1.0
    return _rebuild(joints, joints[:, 0] * scale, lengths)


def _check_lengths(lengths: np.ndarray) -> np.ndarray:
    lengths = np.asarray(lengths, dtype=np.float64)
    if lengths.shape != (NUM_JOINTS,):
        raise ValueError(f"lengths must have shape ({NUM_JOINTS},), got {lengths.shape}")
    return lengths


def _rebuild(joints: np.ndarray, pelvis: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The poses of `joints` rebuilt from `pelvis` (T, 3) outward with bone `lengths`."""
    dirs = _bone_directions(joints)
    out = np.zeros_like(joints)
    out[:, 0] = pelvis
    for j in range(1, NUM_JOINTS):
        out[:, j] = out[:, PARENTS[j]] + dirs[:, j] * lengths[j]
    return out


def with_bone_lengths(joints: np.ndarray, lengths: np.ndarray = BONE_LENGTHS) -> np.ndarray:
    """Rebuild every frame from the pelvis outward with `lengths`, keeping each bone's direction.

    Unlike :func:`retarget` the pelvis trajectory is not scaled: each frame is only shifted up or
    down so that its lowest foot joint stays at the height it had. A decoder's bones stretch and
    shrink a little from frame to frame (a leg 9 cm short puts a rigid body's foot 9 cm into the
    floor); on fixed lengths every frame is a pose of one body. Per frame, so streaming-safe.

    joints: (T, 22, 3); lengths: (22,). Returns (T, 22, 3) float32.
    """
    joints = _check_joints(joints)
    out = _rebuild(joints, joints[:, 0], _check_lengths(lengths))
    feet = list(FOOT_JOINTS)
    out[..., 1] += (joints[:, feet, 1].min(axis=1) - out[:, feet, 1].min(axis=1))[:, None]
    return out.astype(np.float32)


def floor_height(joints: np.ndarray, percentile: float = 3.0) -> float:
    """Robust floor level of a clip: a low percentile over frames of the lowest foot joint.

    joints: (T, 22, 3). The per-frame minimum height of the ankles and toes is taken, then its
    ``percentile`` over frames, so a few bad frames do not lift the whole clip.
    """
    joints = _check_joints(joints)
    if not 0.0 <= percentile <= 100.0:
        raise ValueError(f"percentile must be in [0, 100], got {percentile}")
    lowest = joints[:, list(FOOT_JOINTS), 1].min(axis=1)
    return float(np.percentile(lowest, percentile))


def canonicalize(joints: np.ndarray, floor_percentile: float = 3.0) -> np.ndarray:
    """Put a clip on the canonical skeleton, on the floor, at the origin, facing +Z.

    joints: (T, 22, 3) world positions (Y up, metres) of any proportions. Steps: :func:`retarget`
    to ``BONE_LENGTHS``; shift so the lowest foot joint is at y = 0 (:func:`floor_height`); move
    the frame-0 pelvis to x = z = 0; rotate about Y so frame 0 faces +Z
    (:func:`heading_from_joints`). Returns (T, 22, 3) float32.
    """
    out = retarget(joints)
    out[..., 1] -= floor_height(out, floor_percentile)
    out[..., [0, 2]] -= out[0, 0, [0, 2]]
    out = rotate_y(out, -heading_from_joints(out[0]))
    return out.astype(np.float32)


def mirror(joints: np.ndarray) -> np.ndarray:
    """Mirror poses across the YZ plane: x -> -x and left/right joints swapped.

    joints: (..., 22, 3). A clip facing +Z stays facing +Z; a left turn becomes a right turn.
    """
    joints = np.asarray(joints)
    if joints.ndim < 2 or joints.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"joints must have shape (..., {NUM_JOINTS}, 3), got {joints.shape}")
    out = joints[..., list(MIRROR_INDEX), :].copy()
    out[..., 0] *= -1
    return out


def resample(joints: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """Change the frame rate by linear interpolation in time.

    joints: (T, ...) frames at ``src_fps``. Returns (T', ...) at ``dst_fps``, frame k at time
    k / dst_fps, covering the source duration: T' = floor((T - 1) * dst_fps / src_fps) + 1.
    """
    joints = np.asarray(joints)
    if joints.ndim < 1 or joints.shape[0] < 1:
        raise ValueError(f"joints must have shape (T, ...) with T >= 1, got {joints.shape}")
    for name, fps in (("src_fps", src_fps), ("dst_fps", dst_fps)):
        if not (np.isfinite(fps) and fps > 0):
            raise ValueError(f"{name} must be a positive number, got {fps!r}")
    n_src = joints.shape[0]
    n_dst = int(np.floor((n_src - 1) * dst_fps / src_fps + 1e-6)) + 1
    t = np.arange(n_dst) * (src_fps / dst_fps)  # fractional source frame of each output frame
    i0 = np.clip(np.floor(t).astype(int), 0, n_src - 1)
    i1 = np.minimum(i0 + 1, n_src - 1)
    w = (t - i0).reshape((-1,) + (1,) * (joints.ndim - 1))
    out = joints[i0] * (1.0 - w) + joints[i1] * w
    return out.astype(joints.dtype if joints.dtype.kind == "f" else np.float64)


# ----------------------------------------------------------------------------------------------
# The HumanML3D 263-d representation (port of HumanML3D's process_file / recover_from_ric)
# ----------------------------------------------------------------------------------------------

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
    across = across / np.maximum(np.linalg.norm(across, axis=-1, keepdims=True), _EPS)
    forward = np.cross(np.array([[0.0, 1.0, 0.0]]), across)
    forward = gaussian_filter1d(forward, FACING_SMOOTH_SIGMA, axis=0, mode="nearest")
    forward = forward / np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), _EPS)
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

    Steps, as the original: :func:`retarget` to ``BONE_LENGTHS``; put on the floor (the lowest
    joint of the whole clip at y = 0; skipped with ``floor=False``, e.g. for clips already
    floored by :func:`canonicalize`); frame-0 pelvis to x = z = 0; rotate so frame 0 faces +Z;
    then per frame t < T-1 (layout in :mod:`motion_env.skeleton`):

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
    positions = retarget(_check_joints(joints, min_frames=2))
    if floor:
        positions[..., 1] -= positions[..., 1].min()
    positions[..., [0, 2]] -= positions[0, 0, [0, 2]]
    positions = rotate_y(positions, -heading_from_joints(positions[0]))
    n = positions.shape[0]

    contacts = _foot_contacts(positions, feet_threshold)
    r_rot = _feature_root_quat(positions)  # (T, 4) world -> body
    local_rots = _chain_local_rotations(positions, r_rot)
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
    features = np.asarray(features, dtype=np.float64)
    _check_features(features)
    half = np.zeros(features.shape[:-1])
    half[..., 1:] = np.cumsum(features[..., :-1, 0], axis=-1)
    heading = -2.0 * half  # the body-frame quaternion is a yaw of 2 * half; its inverse is θ
    step = np.zeros(features.shape[:-1] + (3,))
    step[..., 1:, 0] = features[..., :-1, 1]
    step[..., 1:, 2] = features[..., :-1, 2]
    root = np.cumsum(rotate_y(step, heading), axis=-2)
    root[..., 1] = features[..., 3]
    return heading, root


def features_to_joints(features: np.ndarray | torch.Tensor) -> np.ndarray | torch.Tensor:
    """HumanML3D's ``recover_from_ric``: features (..., T, 263) -> joint positions (..., T, 22, 3).

    Uses the root channels and the RIC positions (not the rotations). A torch tensor is handed to
    :func:`features_to_joints_torch` and a tensor comes back; otherwise returns float32 numpy.
    """
    if type(features).__module__.startswith("torch"):
        return features_to_joints_torch(features)
    features = np.asarray(features, dtype=np.float64)
    _check_features(features)
    heading, root = recover_root(features)
    ric = features[..., RIC_SLICE].reshape(features.shape[:-1] + (NUM_JOINTS - 1, 3))
    joints = rotate_y(ric, heading[..., None])
    joints[..., [0, 2]] += root[..., None, [0, 2]]
    return np.concatenate([root[..., None, :], joints], axis=-2).astype(np.float32)


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
