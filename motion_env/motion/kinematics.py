"""Kinematics on the canonical 22-joint skeleton: heading, bones, FK/IK, whole-clip operations.

Conventions (``docs/conventions.md``): metres, Y up, floor at y = 0. Quaternions are
``(..., 4)`` arrays ``(w, x, y, z)`` (:mod:`motion_env.motion.rotations`). A heading θ is a yaw
about +Y; θ = 0 faces +Z and the facing direction is ``(sin θ, cos θ)`` in (x, z). The heading
frame of a character has x = lateral (+ is the character's left, which is +X at θ = 0) and
z = forward.

Kinematics follow HumanML3D's ``Skeleton``: joint ``j`` carries the rotation of the bone that
ends at ``j`` relative to its *rotation parent*, which is the previous joint of its chain in
:data:`skeleton.CHAINS`, except that a chain's first bone is relative to the pelvis rotation
(so the collars hang off the pelvis frame, not spine3's). The rest pose has every bone along
:data:`skeleton.RAW_OFFSETS`.
"""

from __future__ import annotations

import numpy as np

from motion_env.motion.rotations import (
    qbetween,
    qfix,
    qinv,
    qmul,
    qnormalize,
    qrot,
    quat_from_yaw,
    vector_norm,
)
from motion_env.motion.skeleton import (
    BONE_LENGTHS,
    CHAINS,
    FACE_JOINTS,
    FOOT_JOINTS,
    LEGS,
    MIRROR_INDEX,
    NUM_JOINTS,
    PARENTS,
    RAW_OFFSETS,
)
from motion_env.motion.validation import check_joints, check_last

__all__ = [
    "ROTATION_PARENTS",
    "bone_lengths",
    "bone_offsets",
    "canonicalize",
    "chain_local_rotations",
    "fit_bone_lengths",
    "floor_height",
    "forward_kinematics",
    "from_heading_frame",
    "heading_from_joints",
    "hold_pelvis_shape",
    "inverse_kinematics",
    "mirror",
    "pelvis_shape",
    "resample",
    "rescale_bones",
    "rotate_y",
    "to_heading_frame",
    "with_bone_lengths",
]


def _rotation_parents() -> tuple[int, ...]:
    parents = [-1] * NUM_JOINTS
    for chain in CHAINS:
        for i in range(1, len(chain)):
            parents[chain[i]] = 0 if i == 1 else chain[i - 1]
    return tuple(parents)


ROTATION_PARENTS: tuple[int, ...] = _rotation_parents()
"""Rotation parent of each joint in HumanML3D's chain-wise kinematics (see the module docstring)."""


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
    vec_xz = check_last(vec_xz, 2, "vec_xz").astype(np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    dx, dz = vec_xz[..., 0], vec_xz[..., 1]
    return np.stack([dx * c - dz * s, dx * s + dz * c], axis=-1)


def from_heading_frame(vec_local: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_heading_frame`: (lateral, forward) (..., 2) -> world (dx, dz)."""
    vec_local = check_last(vec_local, 2, "vec_local").astype(np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    lx, lz = vec_local[..., 0], vec_local[..., 1]
    return np.stack([lx * c + lz * s, -lx * s + lz * c], axis=-1)


def rotate_y(points: np.ndarray, theta: np.ndarray | float) -> np.ndarray:
    """Rotate points (..., 3) about +Y by θ (broadcast against ``points[..., 0]``).

    A character with heading h gets heading h + θ; +Z goes to (sin θ, 0, cos θ).
    """
    points = check_last(points, 3, "points").astype(np.float64)
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
    lengths = check_last(lengths, NUM_JOINTS, "lengths").astype(np.float64)
    return lengths[..., None] * RAW_OFFSETS.astype(np.float64)


def _bone_directions(joints: np.ndarray) -> np.ndarray:
    """Unit direction of each bone (T, 22, 3); a zero-length bone keeps its rest direction."""
    parents = np.array([max(p, 0) for p in PARENTS])
    vec = joints - joints[..., parents, :]
    norm = np.linalg.norm(vec, axis=-1, keepdims=True)
    rest = np.broadcast_to(RAW_OFFSETS.astype(np.float64), vec.shape)
    dirs = np.where(norm > 1e-9, vec / np.maximum(norm, 1e-9), rest)
    dirs[..., 0, :] = 0.0
    return dirs


def chain_local_rotations(joints: np.ndarray, root_quat: np.ndarray) -> np.ndarray:
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
    joints = check_joints(joints)
    root_quat = quat_from_yaw(heading_from_joints(joints))
    return joints[:, 0].copy(), qfix(chain_local_rotations(joints, root_quat))


# ----------------------------------------------------------------------------------------------
# Whole-clip operations
# ----------------------------------------------------------------------------------------------


def rescale_bones(joints: np.ndarray, lengths: np.ndarray = BONE_LENGTHS) -> np.ndarray:
    """Rebuild poses from the pelvis down with new bone lengths, keeping every bone's direction.

    joints: (T, 22, 3); lengths: (22,). As HumanML3D's ``uniform_skeleton``, the pelvis
    trajectory is scaled by the ratio of leg lengths (knee->ankle + hip->knee of the right leg,
    median over frames) so that steps keep their size relative to the legs. Returns (T, 22, 3).
    """
    joints = check_joints(joints)
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
    """The poses of `joints` (..., 22, 3) rebuilt from `pelvis` (..., 3) outward with bone `lengths`."""
    dirs = _bone_directions(joints)
    out = np.zeros_like(joints)
    out[..., 0, :] = pelvis
    for j in range(1, NUM_JOINTS):
        out[..., j, :] = out[..., PARENTS[j], :] + dirs[..., j, :] * lengths[j]
    return out


def with_bone_lengths(joints: np.ndarray, lengths: np.ndarray = BONE_LENGTHS) -> np.ndarray:
    """Rebuild every frame from the pelvis outward with `lengths`, keeping each bone's direction.

    Unlike :func:`rescale_bones` the pelvis trajectory is kept as it is, height included. A
    decoder's bones stretch and shrink a little from frame to frame; on fixed lengths every frame
    is a pose of one body. The feet go where the legs put them (a leg 9 cm short lifts its foot
    9 cm): the generator's feet and physics stages put them on the floor, where the knees take up
    the difference. Keeping the lowest foot's height instead moved the whole frame with every
    jitter of the decoded legs, and a standing body bobbed at 2-3 m/s^2 (a real one: 0.4). Per
    frame, so streaming-safe.

    joints: (T, 22, 3) (or (B, T, 22, 3): B clips); lengths: (22,). Returns float32 of the same shape.
    """
    joints = check_joints(joints, batched=True)
    return _rebuild(joints, joints[..., 0, :], _check_lengths(lengths)).astype(np.float32)


# Each bone as (child, parent), and BONE_SHARE (22, 21): how much of a bone's excess length each
# joint takes up in a round of :func:`fit_bone_lengths` (and its torch twin): half of it at either
# end, with the opposite sign at the parent, divided by the number of bones meeting at the joint.
BONE_CHILDREN = np.arange(1, NUM_JOINTS)
BONE_PARENTS = np.array(PARENTS[1:])
_INCIDENCE = np.zeros((NUM_JOINTS, NUM_JOINTS - 1))
_INCIDENCE[BONE_CHILDREN, np.arange(NUM_JOINTS - 1)] = 1.0
_INCIDENCE[BONE_PARENTS, np.arange(NUM_JOINTS - 1)] = -1.0
BONE_SHARE = (0.5 * _INCIDENCE / np.abs(_INCIDENCE).sum(axis=1, keepdims=True)).astype(np.float32)
FIT_ITERATIONS = 6
"""Rounds of :func:`fit_bone_lengths`: bones within about 7 mm of their lengths before its exact
rebuild, which then moves joints by 3-4 mm on average (1 cm of noise on every joint)."""


def fit_bone_lengths(
    joints: np.ndarray, lengths: np.ndarray = BONE_LENGTHS, iterations: int = FIT_ITERATIONS
) -> np.ndarray:
    """Every frame on `lengths`, each joint moved about as little as the lengths need.

    :func:`with_bone_lengths` rebuilds a pose from the pelvis outward along the bones' directions,
    so a wrist or a toe sums the errors of the six or seven bones before it: a decoder's bones,
    which stretch and shrink a little from frame to frame, become joints that jitter more the
    further they are from the pelvis (the wrists', knees' and toes' accelerations of generated
    clips rose by 10-25 %). Here each round shortens or stretches every bone towards its length
    by moving its two ends towards or away from each other, half each, shared out over the bones
    that meet at a joint (a Jacobi position projection); after `iterations` rounds the pose is
    rebuilt with :func:`with_bone_lengths`, whose lengths are exact and whose moves are now small,
    from the pelvis's place in `joints` (a pelvis on a root path stays on it, at its height, as
    there). Per frame, so streaming-safe.

    joints: (T, 22, 3) (or (B, T, 22, 3)); lengths: (22,). Returns float32 of the same shape.
    """
    joints = check_joints(joints, batched=True)
    lengths = _check_lengths(lengths)
    if int(iterations) < 0:
        raise ValueError(f"iterations must be >= 0, got {iterations}")
    # Joint-major (22, frames * 3), float32: a round is a few whole-array operations and one
    # matrix product (a stream step fits 64 characters' new frames in about 1 ms).
    x = np.ascontiguousarray(np.moveaxis(joints.astype(np.float32), -2, 0)).reshape(NUM_JOINTS, -1)
    frames = x.shape[1] // 3
    target = lengths[BONE_CHILDREN, None].astype(np.float32)
    for _ in range(int(iterations)):
        bone = (x[BONE_CHILDREN] - x[BONE_PARENTS]).reshape(NUM_JOINTS - 1, frames, 3)
        norm = np.sqrt(np.einsum("ijk,ijk->ij", bone, bone))
        excess = bone * (1.0 - target / np.maximum(norm, 1e-9))[..., None]  # what each bone is too long by
        x = x - BONE_SHARE @ excess.reshape(NUM_JOINTS - 1, -1)
    x = np.moveaxis(x.reshape(NUM_JOINTS, *joints.shape[:-2], 3), 0, -2).astype(np.float64)
    # The pelvis where it was: on the root path, at its height.
    return _rebuild(x, joints[..., 0, :], lengths).astype(np.float32)


_HIPS, _LEG_JOINTS = [leg[0] for leg in LEGS], np.array(LEGS)


def _torso_up(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(hips' centre (..., 3), unit torso axis (..., 3)): from the hips' centre to spine1, made
    square to the line through the hips."""
    left, right = joints[..., _HIPS[0], :], joints[..., _HIPS[1], :]
    centre = 0.5 * (left + right)
    across = left - right
    across = across / np.maximum(vector_norm(across, keepdims=True), 1e-9)
    up = joints[..., CHAINS[2][1], :] - centre
    up = up - (up * across).sum(-1, keepdims=True) * across
    return centre, up / np.maximum(vector_norm(up, keepdims=True), 1e-9)


def pelvis_shape(joints: np.ndarray) -> np.ndarray:
    """How far (m) the pelvis joint sits above the hips' centre along the torso: (..., 22, 3) -> (...).

    The training takes place it either about 3 cm below the hips' centre (CMU) or about 3 cm above
    it (Bandai Namco), and a decoder may move from one to the other within a clip: the hips slide
    along the spine, which no rigid body does (:func:`hold_pelvis_shape`).
    """
    joints = check_joints(joints, batched=True).astype(np.float64)
    centre, up = _torso_up(joints)
    return ((joints[..., 0, :] - centre) * up).sum(-1)


def hold_pelvis_shape(joints: np.ndarray, shape: float | np.ndarray) -> np.ndarray:
    """Every frame's pelvis joint `shape` m above the hips' centre along the torso (see
    :func:`pelvis_shape`): each hip turns about the pelvis joint, its bone's length kept, and its
    leg moves with it; the pelvis joint, the torso and the arms stay where they were (the feet
    move with the hips, as :func:`with_bone_lengths` explains). One shape for a clip makes its
    pelvis a rigid body, as the replay's humanoid has it. Per frame, so streaming-safe.

    joints: (T, 22, 3) (or (B, T, 22, 3)); shape: a number, or one per frame or per clip that
    broadcasts against (T,) (or (B, T)): pass (B, 1) for one per clip. Returns float32.
    """
    joints = check_joints(joints, batched=True)
    out = joints.astype(np.float64)
    held = np.broadcast_to(np.asarray(shape, dtype=np.float64), out.shape[:-2])
    if not np.isfinite(held).all():
        raise ValueError("shape must be finite (metres above the hips' centre)")
    _, up = _torso_up(out)
    up = up[..., None, :]  # (..., 1, 3): both legs at once
    bone = out[..., _HIPS, :] - out[..., :1, :]  # (..., 2, 3)
    length = vector_norm(bone)
    side = bone - (bone * up).sum(-1, keepdims=True) * up  # the bones square to the torso
    along = np.minimum(np.maximum(-held[..., None], -0.9 * length), 0.9 * length)  # hips below: -shape
    scale = np.sqrt(length**2 - along**2) / np.maximum(vector_norm(side), 1e-9)
    moved = side * scale[..., None] + along[..., None] * up - bone  # (..., 2, 3)
    out[..., _LEG_JOINTS, :] += moved[..., None, :]  # each leg rigidly with its hip
    return out.astype(np.float32)


def floor_height(joints: np.ndarray, percentile: float = 3.0) -> float:
    """Robust floor level of a clip: a low percentile over frames of the lowest foot joint.

    joints: (T, 22, 3). The per-frame minimum height of the ankles and toes is taken, then its
    ``percentile`` over frames, so a few bad frames do not lift the whole clip.
    """
    joints = check_joints(joints)
    if not 0.0 <= percentile <= 100.0:
        raise ValueError(f"percentile must be in [0, 100], got {percentile}")
    lowest = joints[:, list(FOOT_JOINTS), 1].min(axis=1)
    return float(np.percentile(lowest, percentile))


def canonicalize(joints: np.ndarray, floor_percentile: float = 3.0) -> np.ndarray:
    """Put a clip on the canonical skeleton, on the floor, at the origin, facing +Z.

    joints: (T, 22, 3) world positions (Y up, metres) of any proportions. Steps: :func:`rescale_bones`
    to ``BONE_LENGTHS``; shift so the lowest foot joint is at y = 0 (:func:`floor_height`); move
    the frame-0 pelvis to x = z = 0; rotate about Y so frame 0 faces +Z
    (:func:`heading_from_joints`). Returns (T, 22, 3) float32.
    """
    out = rescale_bones(joints)
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
