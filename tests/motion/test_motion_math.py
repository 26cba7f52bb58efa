"""Tests for motion_env.motion: rotations, kinematics, clip operations and the 263-d features."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env import motion as M
from motion_env import skeleton as S
from motion_env.motion import kinematics


def _synthetic_clip(seed: int = 0, frames: int = 60, lengths: np.ndarray = S.BONE_LENGTHS) -> np.ndarray:
    """A smooth random clip (T, 22, 3): FK of slowly varying joint rotations along a curved path."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, frames)[:, None, None]
    # Per joint two random axis-angles blended over time: smooth but non-trivial poses.
    a, b = rng.normal(scale=0.4, size=(2, 1, S.NUM_JOINTS, 3))
    local = M.quat_from_axis_angle(a * (1 - t) + b * t)
    local[:, 0] = M.quat_from_yaw(np.linspace(0.3, 2.0, frames))
    root = np.stack(
        [np.sin(np.linspace(0, 2, frames)), np.full(frames, 0.9), np.linspace(0, 1.5, frames)], -1
    )
    return M.forward_kinematics(root, local, M.bone_offsets(lengths)).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Rotations
# ---------------------------------------------------------------------------------------------


def test_quaternion_algebra_matches_matrices() -> None:
    rng = np.random.default_rng(0)
    q, r = M.qnormalize(rng.normal(size=(2, 200, 4)))
    v = rng.normal(size=(200, 3))
    mq, mr = M.quat_to_matrix(q), M.quat_to_matrix(r)
    np.testing.assert_allclose(M.qrot(q, v), (mq @ v[..., None])[..., 0], atol=1e-12)
    np.testing.assert_allclose(M.quat_to_matrix(M.qmul(q, r)), mq @ mr, atol=1e-12)
    np.testing.assert_allclose(M.qmul(q, M.qinv(q)), np.tile([1.0, 0, 0, 0], (200, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(mq), 1.0, atol=1e-12)


def test_rotation_round_trips() -> None:
    rng = np.random.default_rng(1)
    q = M.qnormalize(rng.normal(size=(500, 4)))
    q = np.where(q[:, :1] < 0, -q, q)  # the w >= 0 representative
    np.testing.assert_allclose(M.quat_from_matrix(M.quat_to_matrix(q)), q, atol=1e-10)
    np.testing.assert_allclose(M.rot6d_to_quat(M.quat_to_rot6d(q)), q, atol=1e-10)
    np.testing.assert_allclose(M.quat_from_axis_angle(M.quat_to_axis_angle(q)), q, atol=1e-10)
    # 6-D is HumanML3D's: the first two columns; Gram-Schmidt repairs a perturbed pair.
    m = M.quat_to_matrix(q)
    np.testing.assert_allclose(M.quat_to_rot6d(q), np.concatenate([m[:, :, 0], m[:, :, 1]], -1))
    noisy = M.quat_to_rot6d(q) * 1.7 + np.concatenate([np.zeros((500, 3)), 0.3 * m[:, :, 0]], -1)
    np.testing.assert_allclose(M.rot6d_to_matrix(noisy), m, atol=1e-10)
    # Axis-angle of a known rotation, and the zero rotation.
    np.testing.assert_allclose(M.quat_to_axis_angle(M.quat_from_yaw(np.array(0.5))), [0, 0.5, 0], atol=1e-12)
    np.testing.assert_allclose(M.quat_from_axis_angle(np.zeros(3)), [1, 0, 0, 0])


def test_qbetween_including_opposite_directions() -> None:
    rng = np.random.default_rng(2)
    v0, v1 = rng.normal(size=(2, 100, 3))
    v0[:3] = [[0, -1, 0], [1, 0, 0], [0.3, 0.2, -0.5]]
    v1[:3] = -v0[:3] * [[2.0], [0.5], [1.0]]  # exactly opposite: the formula's 0/0 case
    q = M.qbetween(v0, v1)
    assert np.isfinite(q).all()
    unit = lambda v: v / np.linalg.norm(v, axis=-1, keepdims=True)  # noqa: E731
    np.testing.assert_allclose(M.qrot(q, unit(v0)), unit(v1), atol=1e-10)


def test_qfix_makes_sequences_continuous() -> None:
    rng = np.random.default_rng(3)
    q = M.qnormalize(np.cumsum(rng.normal(scale=0.05, size=(50, 3, 4)), axis=0) + [1, 0, 0, 0])
    flipped = q * rng.choice([-1.0, 1.0], size=(50, 3, 1))
    fixed = M.qfix(flipped)
    assert ((fixed[1:] * fixed[:-1]).sum(-1) >= 0).all()
    np.testing.assert_allclose(np.abs((fixed * q).sum(-1)), 1.0, atol=1e-12)  # same rotations


# ---------------------------------------------------------------------------------------------
# Heading conventions
# ---------------------------------------------------------------------------------------------


def test_heading_conventions() -> None:
    theta = np.array([0.0, 0.7, -2.0, np.pi / 2])
    # θ rotates +Z onto the facing direction (sin θ, cos θ).
    np.testing.assert_allclose(
        M.qrot(M.quat_from_yaw(theta), np.array([0.0, 0, 1])),
        np.stack([np.sin(theta), 0 * theta, np.cos(theta)], -1),
        atol=1e-12,
    )
    # The rest skeleton (left = +X) faces +Z; rotated by θ it faces θ.
    rest = M.forward_kinematics(np.zeros((1, 3)), np.tile([1.0, 0, 0, 0], (1, S.NUM_JOINTS, 1)))
    assert abs(M.heading_from_joints(rest)[0]) < 1e-12
    np.testing.assert_allclose(
        M.heading_from_joints(M.rotate_y(rest, theta[:, None, None])[:, 0]), theta, atol=1e-12
    )
    # Heading frame: facing +X (θ = π/2), a world +X step is forward and +Z is to the right.
    np.testing.assert_allclose(
        M.to_heading_frame(np.array([[1.0, 0], [0, 1]]), np.pi / 2), [[0, 1], [-1, 0]], atol=1e-12
    )
    np.testing.assert_allclose(M.to_heading_frame(np.array([1.0, 0]), 0.0), [1, 0])  # +X is left at θ = 0
    rng = np.random.default_rng(4)
    vec, th = rng.normal(size=(30, 2)), rng.uniform(-4, 4, size=30)
    np.testing.assert_allclose(M.from_heading_frame(M.to_heading_frame(vec, th), th), vec, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Kinematics and clip operations
# ---------------------------------------------------------------------------------------------


def test_fk_ik_round_trip_synthetic() -> None:
    lengths = S.BONE_LENGTHS * np.linspace(0.8, 1.3, S.NUM_JOINTS)
    joints = _synthetic_clip(lengths=lengths).astype(np.float64)
    root, local = M.inverse_kinematics(joints)
    assert root.shape == (60, 3) and local.shape == (60, S.NUM_JOINTS, 4)
    np.testing.assert_allclose(np.linalg.norm(local, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(M.forward_kinematics(root, local, M.bone_offsets(lengths)), joints, atol=1e-6)
    # The root rotation is the facing yaw.
    np.testing.assert_allclose(M.qrot(local[:, 0], np.array([0.0, 0, 1]))[:, 1], 0.0, atol=1e-12)


def test_fk_ik_round_trip_on_reference_clip(humanml3d_sample) -> None:
    joints, _ = humanml3d_sample
    root, local = M.inverse_kinematics(joints)
    rebuilt = M.forward_kinematics(root, local, M.bone_offsets(M.bone_lengths(joints)))
    np.testing.assert_allclose(rebuilt, joints, atol=1e-6)
    # The reference clip is on the canonical skeleton.
    np.testing.assert_allclose(
        M.bone_lengths(joints), np.broadcast_to(S.BONE_LENGTHS, (len(joints), 22)), atol=1e-4
    )


def test_canonicalize_properties() -> None:
    src = _synthetic_clip(seed=5, lengths=S.BONE_LENGTHS * 1.3)  # a taller body, turned, away from origin
    src = M.rotate_y(src, 1.0) + [3.0, 0.4, -2.0]
    src[17, :, 1] -= 0.5  # one broken frame far below the floor must not lift the clip
    out = M.canonicalize(src)
    assert out.shape == src.shape and out.dtype == np.float32
    np.testing.assert_allclose(M.bone_lengths(out), np.broadcast_to(S.BONE_LENGTHS, (60, 22)), atol=1e-5)
    lowest_foot = out[:, list(S.FOOT_JOINTS), 1].min(axis=1)
    assert np.percentile(lowest_foot, 3) == pytest.approx(0.0, abs=1e-5)
    assert lowest_foot[17] < -0.3 and abs(M.floor_height(np.delete(out, 17, axis=0))) < 0.01
    np.testing.assert_allclose(out[0, 0, [0, 2]], 0.0, atol=1e-6)
    assert abs(M.heading_from_joints(out[0])) < 1e-6
    # Bone directions are kept: canonicalizing the canonical clip changes nothing.
    np.testing.assert_allclose(M.canonicalize(out), out, atol=1e-5)


def test_canonicalize_keeps_reference_clip(humanml3d_sample) -> None:
    joints, _ = humanml3d_sample
    out = M.canonicalize(joints)
    # Already canonical up to the floor rule (HumanML3D floors the lowest joint of the whole clip).
    np.testing.assert_allclose(out[..., [0, 2]], joints[..., [0, 2]], atol=1e-4)
    assert np.ptp(out[..., 1] - joints[..., 1]) < 1e-4
    assert abs(M.floor_height(out)) < 1e-6 and M.floor_height(joints) < 0.03


def test_mirror() -> None:
    joints = _synthetic_clip(seed=6)
    mirrored = M.mirror(joints)
    np.testing.assert_array_equal(M.mirror(mirrored), joints)
    np.testing.assert_array_equal(
        mirrored[:, S.JOINT_INDEX["left_wrist"], 0], -joints[:, S.JOINT_INDEX["right_wrist"], 0]
    )
    np.testing.assert_array_equal(
        mirrored[:, S.JOINT_INDEX["left_hip"], 1:], joints[:, S.JOINT_INDEX["right_hip"], 1:]
    )
    # A mirrored body turns the other way: heading θ becomes -θ.
    np.testing.assert_allclose(M.heading_from_joints(mirrored), -M.heading_from_joints(joints), atol=1e-6)
    np.testing.assert_allclose(
        M.bone_lengths(mirrored), M.bone_lengths(joints)[:, list(S.MIRROR_INDEX)], atol=1e-6
    )


def test_resample() -> None:
    joints = _synthetic_clip(seed=7, frames=61)
    up = M.resample(joints, 20, 40)
    assert up.shape == (121, 22, 3) and up.dtype == np.float32
    np.testing.assert_allclose(up[::2], joints, atol=1e-6)
    np.testing.assert_allclose(up[1], (joints[0] + joints[1]) / 2, atol=1e-6)
    assert M.resample(joints, 30, 20).shape == (41, 22, 3)  # 2 s at 30 fps -> 2 s at 20 fps
    assert M.resample(joints[:1], 120, 20).shape == (1, 22, 3)
    np.testing.assert_allclose(M.resample(M.resample(joints, 20, 120), 120, 20), joints, atol=1e-5)


def test_wrong_shapes_raise_clear_errors() -> None:
    bad = np.zeros((10, 21, 3))
    fns = (M.canonicalize, M.inverse_kinematics, M.joints_to_features, M.rescale_bones, M.with_bone_lengths)
    for fn in fns:
        with pytest.raises(ValueError, match=r"\(T, 22, 3\).*\(10, 21, 3\)"):
            fn(bad)
    with pytest.raises(ValueError, match="T >= 2"):
        M.joints_to_features(np.zeros((1, 22, 3)))
    with pytest.raises(ValueError, match="NaN"):
        M.canonicalize(np.full((3, 22, 3), np.nan))
    with pytest.raises(ValueError, match=r"\(\.\.\., T, 263\).*\(5, 262\)"):
        M.features_to_joints(np.zeros((5, 262)))
    with pytest.raises(ValueError, match=r"\(\.\.\., 4\)"):
        M.qmul(np.zeros(3), np.zeros(4))
    with pytest.raises(ValueError, match="local_rots"):
        M.forward_kinematics(np.zeros((4, 3)), np.zeros((5, 22, 4)))
    with pytest.raises(ValueError, match="src_fps"):
        M.resample(np.zeros((4, 22, 3)), 0, 20)
    with pytest.raises(ValueError, match=r"\(\.\.\., 22, 3\)"):
        M.heading_from_joints(np.zeros((22, 2)))


# ---------------------------------------------------------------------------------------------
# The HumanML3D 263-d features
# ---------------------------------------------------------------------------------------------


def test_features_match_humanml3d_reference(humanml3d_sample) -> None:
    joints, vecs = humanml3d_sample
    # recover_from_ric: the reference new_joints are exactly what HumanML3D decodes from new_joint_vecs.
    np.testing.assert_allclose(M.features_to_joints(vecs), joints, atol=1e-4)
    # process_file: the clip is one frame shorter than the one HumanML3D encoded, so the
    # facing smoothing (sigma 20 frames) differs near the end: compare all but the last 30 frames.
    feats = M.joints_to_features(joints)
    assert feats.shape == (len(joints) - 1, S.FEATURE_DIM) and feats.dtype == np.float32
    n = len(feats) - 30
    err = np.abs(feats[:n] - vecs[:n])
    assert np.delete(err, np.r_[S.ROT6D], axis=1).max() < 2e-3
    assert err[:, S.ROT6D].max() < 1e-2
    np.testing.assert_array_equal(feats[:, S.FOOT_CONTACT], vecs[:-1, S.FOOT_CONTACT])


def test_features_round_trip_through_a_full_turn() -> None:
    # Spin a clip through 2π about the origin: the root heading passes -Z, where HumanML3D's
    # yaw-velocity sign flips; the decoder must still get the motion back.
    joints = M.canonicalize(_synthetic_clip(seed=8, frames=120)).astype(np.float64)
    joints[..., 1] -= joints[..., 1].min()  # joints_to_features floors the lowest joint
    spun = M.rotate_y(joints, np.linspace(0.0, 2 * np.pi, len(joints))[:, None])
    feats = M.joints_to_features(spun)
    rebuilt = M.features_to_joints(feats)
    np.testing.assert_allclose(rebuilt, spun[:-1], atol=1e-4)
    heading, root = M.recover_root(feats)
    np.testing.assert_allclose(root[:, [0, 2]], spun[:-1, 0, [0, 2]], atol=1e-4)
    assert np.ptp(heading) > 1.5 * np.pi  # turned most of a revolution, continuously


def test_foot_contacts_follow_foot_speed() -> None:
    joints = M.canonicalize(_synthetic_clip(seed=9, frames=40)).astype(np.float64)
    joints[20:, S.LEFT_FOOT[0]] = joints[20, S.LEFT_FOOT[0]]  # planted left ankle from frame 20
    feats = M.joints_to_features(joints, floor=False)
    contact = feats[:, S.FOOT_CONTACT]
    assert set(np.unique(contact)) <= {0.0, 1.0}
    assert (contact[20:, 0] == 1).all()
    step = ((joints[1:, S.RIGHT_FOOT[1]] - joints[:-1, S.RIGHT_FOOT[1]]) ** 2).sum(-1)
    np.testing.assert_array_equal(contact[:, 3], (step < M.FOOT_CONTACT_THRESHOLD).astype(np.float32))


def test_torch_decoder_matches_numpy() -> None:
    torch = pytest.importorskip("torch")
    feats = np.stack([M.joints_to_features(_synthetic_clip(seed=s)) for s in (10, 11)])  # (2, 59, 263)
    expected = M.features_to_joints(feats)  # numpy accepts a batch too
    assert expected.shape == (2, 59, 22, 3)
    np.testing.assert_allclose(expected[1], M.features_to_joints(feats[1]), atol=1e-6)
    tensor = torch.from_numpy(feats).requires_grad_(True)
    out = M.features_to_joints_torch(tensor)
    assert out.shape == (2, 59, 22, 3) and out.dtype == torch.float32
    np.testing.assert_allclose(out.detach().numpy(), expected, atol=1e-4)
    out.sum().backward()
    assert tensor.grad is not None and torch.isfinite(tensor.grad).all()
    assert isinstance(M.features_to_joints(tensor.detach()), torch.Tensor)


def _stretched_clip() -> tuple[np.ndarray, np.ndarray]:
    """A synthetic clip on the canonical lengths and the same clip with every bone 0.85-1.15x
    its length, drawn anew each frame (a decoder's bones stretch and shrink)."""
    canonical = _synthetic_clip(seed=3)
    rng = np.random.default_rng(0)
    stretch = S.BONE_LENGTHS * rng.uniform(0.85, 1.15, size=(canonical.shape[0], S.NUM_JOINTS))
    stretched = np.stack([_synthetic_clip(seed=3, lengths=stretch[t])[t] for t in range(len(stretch))])
    return canonical, stretched


@pytest.mark.parametrize("rebuild", [M.with_bone_lengths, M.fit_bone_lengths])
def test_bone_length_rebuilds_fix_stretched_bones_and_keep_the_pelvis(rebuild) -> None:
    canonical, stretched = _stretched_clip()
    fixed = rebuild(stretched)
    np.testing.assert_allclose(
        M.bone_lengths(fixed)[:, 1:], np.broadcast_to(S.BONE_LENGTHS[1:], (60, 21)), atol=1e-5
    )
    # The same pelvis, height included, frame by frame: the legs' stretch moves the feet, not
    # the body (a frame moved to keep its lowest foot's height bobbed with the legs' jitter).
    np.testing.assert_allclose(fixed[:, 0], stretched[:, 0], atol=1e-6)
    feet = list(S.FOOT_JOINTS)
    assert np.abs(fixed[:, feet, 1].min(1) - stretched[:, feet, 1].min(1)).max() > 0.01
    # A body already on the lengths is left as it is.
    np.testing.assert_allclose(rebuild(canonical), canonical, atol=1e-5)
    if rebuild is M.with_bone_lengths:  # it keeps every bone's direction
        np.testing.assert_allclose(
            kinematics._bone_directions(fixed)[:, 1:],
            kinematics._bone_directions(stretched)[:, 1:],
            atol=1e-5,
        )


def test_fitted_bones_do_not_jitter_far_from_the_pelvis() -> None:
    # Joints a decoder puts 1 cm off, independently: rebuilt from the pelvis outward, the wrists
    # and toes (chain ends) sum the errors of the bones before them, so they land further from the
    # true pose and jitter more than when each bone is fitted where it lies.
    canonical, _ = _stretched_clip()
    noisy = canonical + np.random.default_rng(1).normal(0.0, 0.01, canonical.shape)
    ends = [10, 11, 15, 20, 21]
    errors, jitters = [], []
    for rebuilt in (M.with_bone_lengths(noisy), M.fit_bone_lengths(noisy)):
        errors.append(np.linalg.norm(rebuilt[:, ends] - canonical[:, ends], axis=-1).mean())
        jitters.append(np.linalg.norm(np.diff(rebuilt[:, ends], n=2, axis=0), axis=-1).mean())
    assert errors[1] < 0.8 * errors[0] and jitters[1] < 0.8 * jitters[0]  # about 0.7 each
    with pytest.raises(ValueError, match="iterations"):
        M.fit_bone_lengths(canonical, iterations=-1)


def test_held_pelvis_shape_is_one_rigid_pelvis_with_the_legs_kept() -> None:
    # A clip whose hips slide along the spine from 3 cm below the pelvis joint to 3 cm above it
    # (the two mocap sources' shapes, mixed by a decoder) gets one shape for every frame.
    clip = _synthetic_clip(seed=4)
    slide = np.linspace(-0.03, 0.03, len(clip))
    _, up = kinematics._torso_up(clip.astype(np.float64))
    sliding = clip.copy()
    for leg in S.LEGS:
        sliding[:, list(leg)] += (slide[:, None] * up)[:, None].astype(np.float32)
    shape = M.pelvis_shape(sliding)
    assert shape.max() - shape.min() > 0.02
    held = M.hold_pelvis_shape(sliding, 0.033)
    np.testing.assert_allclose(M.pelvis_shape(held), 0.033, atol=2e-4)
    lengths = M.bone_lengths(sliding)
    np.testing.assert_allclose(M.bone_lengths(held), lengths, atol=1e-5)  # the hips turn, not stretch
    # The legs move rigidly with their hips; the pelvis joint, the torso and the arms stay.
    knee_from_hip = held[:, 4] - held[:, 1]
    np.testing.assert_allclose(knee_from_hip, sliding[:, 4] - sliding[:, 1], atol=1e-5)
    upper = [j for j in range(S.NUM_JOINTS) if j not in np.array(S.LEGS).ravel()]
    np.testing.assert_allclose(held[:, upper], sliding[:, upper], atol=1e-6)
    # One shape per clip in a batch; a clip at its shape stays (to a fraction of a millimetre: the
    # torso's axis, taken from the hips, turns a little as they move).
    both = M.hold_pelvis_shape(np.stack([sliding, held]), np.array([[0.033], [0.033]]))
    np.testing.assert_allclose(both[0], held, atol=1e-6)
    np.testing.assert_allclose(both[1], held, atol=5e-4)
    with pytest.raises(ValueError, match="shape must be finite"):
        M.hold_pelvis_shape(sliding, np.nan)


def test_vector_norm_and_cross_give_numpys_numbers() -> None:
    from motion_env.motion.rotations import cross, vector_norm

    rng = np.random.default_rng(0)
    for dtype in (np.float32, np.float64):
        a = rng.normal(size=(5, 4, 3)).astype(dtype)
        b = rng.normal(size=(4, 3)).astype(dtype)  # broadcast, as qrot's quaternions do
        np.testing.assert_array_equal(vector_norm(a), np.linalg.norm(a, axis=-1))
        kept = np.linalg.norm(a, axis=-1, keepdims=True)
        np.testing.assert_array_equal(vector_norm(a, keepdims=True), kept)
        np.testing.assert_array_equal(cross(a, b), np.cross(a, b))
        assert cross(a, b).dtype == np.cross(a, b).dtype and vector_norm(a).dtype == dtype
