"""Joint targets and objectives: the test-time refinement (generation/refine.py, targets.py,
torch_body.py, stream_control.py) on the tiny random model and on synthetic math; one short
check on the shipped model."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch

from motion_env.generation.closed_form import (
    FADE,
    HEAD_DROP,
    PLANT_WEIGHT,
    causal_field,
    residual_field,
    smooth_field,
    smoothstep,
    solve_limbs,
)
from motion_env.generation.feet import two_bone_ik
from motion_env.generation.recompose import local_pose_from_features, recompose
from motion_env.generation.torch_body import frame_yaw, local_pose_torch, place_on_path_torch
from motion_env.motion.features import joints_to_features
from motion_env.motion.kinematics import bone_lengths, fit_bone_lengths, hold_pelvis_shape, with_bone_lengths
from motion_env.motion.skeleton import BONE_LENGTHS, JOINT_INDEX
from motion_env.objectives import HeightLimit, KeepOut

HEAD, RIGHT_WRIST, LEFT_FOOT = JOINT_INDEX["head"], JOINT_INDEX["right_wrist"], JOINT_INDEX["left_foot"]


@pytest.fixture(scope="module")
def walk(random_generator) -> np.ndarray:
    """A real-looking clip: the random generator's output is noise, so use a clip it produced only
    for its shape, and a procedural walk for the math."""
    t = np.arange(60) / 20.0
    m = random_generator.generate("a person walks", num_frames=60, seed=1)
    joints = m.joints.astype(np.float64).copy()
    joints[..., 2] += 1.2 * t[:, None]
    return with_bone_lengths(joints)


def test_torch_twin_equals_the_numpy_recompose(walk) -> None:
    feats = joints_to_features(walk)  # (59, 263)
    local = local_pose_from_features(feats)
    yaw = torch.as_tensor(frame_yaw(feats))
    twin = local_pose_torch(torch.as_tensor(feats), yaw).numpy()
    np.testing.assert_allclose(twin, local, atol=1e-4)
    path = np.stack([np.linspace(0, 2, 59), np.linspace(1, 3, 59), np.linspace(0, 1, 59)], 1).astype(
        np.float32
    )
    world = fit_bone_lengths(recompose(local, path, face_travel=False))
    twin_world = place_on_path_torch(torch.as_tensor(local), torch.as_tensor(path)).numpy()
    np.testing.assert_allclose(twin_world, world, atol=1e-4)
    held = place_on_path_torch(torch.as_tensor(local), torch.as_tensor(path), 0.033).numpy()
    np.testing.assert_allclose(held, hold_pelvis_shape(world, 0.033), atol=1e-4)


def test_residual_field_interpolates_fades_and_holds() -> None:
    known = np.zeros(100, bool)
    known[[40, 50]] = True
    res = np.zeros((100, 1))
    res[40], res[50] = 1.0, 3.0
    field = residual_field(known, res)[:, 0]
    assert field[40] == 1.0 and field[50] == 3.0 and field[45] == pytest.approx(2.0)
    assert field[40 - FADE] == 0.0 and field[50 + FADE] == 0.0 and 0 < field[35] < 1
    assert np.abs(np.diff(field)).max() < 0.5  # no pop
    hold = np.zeros(100, bool)
    hold[60:75] = True
    known[:] = False
    known[70] = True
    res[70] = 2.0
    held = residual_field(known, res, hold=hold)[:, 0]
    assert np.all(held[60:75] == 2.0)  # a planted foot moves as one block


def test_causal_field_is_exact_at_targets_and_smooth() -> None:
    current = np.zeros((30, 3))
    target = np.full((30 + FADE, 3), np.nan)
    target[20] = [0.3, 0.0, 0.0]
    known = ~np.isnan(target[:, 0])
    out, carry = causal_field(current, target, known, None)
    assert np.allclose(out[20], [0.3, 0, 0]) and np.allclose(out[:9], 0)
    assert np.abs(np.diff(out[:, 0])).max() < 0.06
    assert carry[0] == 9 and np.allclose(carry[1], [0.3, 0, 0])
    # The same frames in two calls give the same result (the stream decodes 4 frames at a time).
    a, c = causal_field(current[:12], target[: 12 + FADE + 1], known[: 12 + FADE + 1], None)
    b, _ = causal_field(current[12:], target[12:], known[12:], c)
    np.testing.assert_allclose(np.concatenate([a, b]), out)


def test_two_bone_ik_keeps_bones() -> None:
    rng = np.random.default_rng(0)
    hip = rng.normal(size=(50, 3))
    knee = hip + rng.normal(size=(50, 3)) * 0.3
    ankle = knee + rng.normal(size=(50, 3)) * 0.3
    goal = hip + rng.normal(size=(50, 3)) * 0.2
    k2, a2 = two_bone_ik(hip, knee, ankle, goal)
    np.testing.assert_allclose(
        np.linalg.norm(k2 - hip, axis=1), np.linalg.norm(knee - hip, axis=1), atol=1e-9
    )
    np.testing.assert_allclose(
        np.linalg.norm(a2 - k2, axis=1), np.linalg.norm(ankle - knee, axis=1), atol=1e-9
    )


def test_finish_meets_reachable_targets_and_keeps_bones(walk) -> None:
    targets = np.full(walk.shape, np.nan, np.float32)
    targets[30, RIGHT_WRIST] = walk[30, RIGHT_WRIST] + [0.05, 0.08, 0.03]
    targets[30, HEAD] = walk[30, HEAD] + [0.04, -0.05, 0.0]
    targets[20, LEFT_FOOT] = walk[20, LEFT_FOOT] + [0.06, 0.0, 0.05]
    targets[40, 0] = walk[40, 0] + [0.0, -0.06, 0.0]
    ceiling = float(walk[:, HEAD, 1].min()) - 0.1
    out = solve_limbs(walk, targets, [HeightLimit("head", max_height=ceiling, frames=(45, 55))],
                 np.zeros((len(walk), 2), bool))  # fmt: skip
    known = ~np.isnan(targets[..., 0])
    assert np.linalg.norm(out[known] - targets[known], axis=-1).max() < 1e-3
    np.testing.assert_allclose(
        bone_lengths(out)[:, 1:], np.broadcast_to(BONE_LENGTHS[1:], (len(out), 21)), rtol=0.01
    )
    assert out[45:55, HEAD, 1].max() <= walk[:, HEAD, 1].min() - 0.1 + 1e-6
    assert np.abs(out[:, [7, 8]] - walk[:, [7, 8]]).max() < 0.15  # feet stay near where they were


def test_generate_with_targets_and_objectives(random_generator) -> None:
    gen = random_generator
    base = gen.generate("a person walks", num_frames=40, seed=0)
    targets = np.full((40, 22, 3), np.nan, np.float32)
    targets[20, RIGHT_WRIST] = base.joints[20, RIGHT_WRIST] + [0.05, 0.05, 0.0]
    targets[30, 0] = base.joints[30, 0] + [0.1, 0.0, 0.1]
    keep = KeepOut(center=(5.0, 5.0), radius=0.3)
    called = []

    def user(joints: torch.Tensor) -> torch.Tensor:
        called.append(joints.shape)
        return joints[:, 21, 1].sum() * 0.0 + (joints[:, 21, 1] - 5.0).clamp_min(0).sum()

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = gen.generate(
            "a person walks", num_frames=40, seed=0, joint_targets=targets, objectives=[keep, user]
        )
    assert m.joints.shape == (40, 22, 3) and "control" in m.meta and called
    assert np.linalg.norm(m.joints[30, 0, [0, 2]] - targets[30, 0, [0, 2]]) < 1e-3
    # Rows without targets in a batch are the plain clips.
    batch = gen.generate_batch(["a person walks", "a person runs"], num_frames=40, seed=0,
                               joint_targets=[targets, None])  # fmt: skip
    plain = gen.generate_batch(["a person walks", "a person runs"], num_frames=40, seed=0)
    np.testing.assert_array_equal(batch[1].joints, plain[1].joints)


def test_unreachable_targets_are_named_in_a_warning(random_generator) -> None:
    targets = np.full((40, 22, 3), np.nan, np.float32)
    targets[20, 0] = [0.0, 0.9, 0.0]
    targets[20, RIGHT_WRIST] = [0.0, 3.0, 0.0]  # 2 m above the pelvis: beyond any arm
    with pytest.warns(UserWarning, match=r"right_wrist at frame 20 by \d+"):
        random_generator.generate("a person walks", num_frames=40, seed=0, joint_targets=targets)


def test_stream_meets_targets_given_ahead(random_generator) -> None:
    stream = random_generator.stream(["a person walks"], seed=0)
    frames = [stream.step()[0] for _ in range(8)]
    targets = np.full((40, 22, 3), np.nan, np.float32)
    goal = frames[-1][RIGHT_WRIST] + [0.05, 0.05, 0.05]
    targets[30, RIGHT_WRIST] = goal
    stream.set_joint_targets(targets, first_frame=0)
    stream.set_objectives([HeightLimit("head", max_height=1.2, frames=(20, 30))])
    out = np.stack(frames + [stream.step()[0] for _ in range(32)])
    assert np.linalg.norm(out[30, RIGHT_WRIST] - goal) < 1e-3
    assert "1 targets" in stream.control_summary(0)
    with pytest.raises(ValueError, match="HeightLimit objectives only"):
        stream.set_objectives([KeepOut(center=(0, 0), radius=1)])
    late = targets[:5].copy()
    late[2, 0] = [0.0, 0.9, 0.0]
    with pytest.warns(UserWarning, match=r"frames \[2\] are already generated"):
        stream.set_joint_targets(late, first_frame=0)


def test_shipped_model_hits_a_keyframe_quickly(pretrained_generator) -> None:
    import time

    gen = pretrained_generator
    gen.generate("a person walks forward", num_frames=100, seed=0)  # warm-up (text encoder)
    base = gen.generate("a person walks forward", num_frames=100, seed=0)
    targets = np.full((100, 22, 3), np.nan, np.float32)
    targets[60, RIGHT_WRIST] = base.joints[60, RIGHT_WRIST] + [0.1, 0.2, 0.0]
    t0 = time.perf_counter()
    m = gen.generate("a person walks forward", num_frames=100, seed=0, joint_targets=targets)
    assert time.perf_counter() - t0 < 5.0
    assert np.linalg.norm(m.joints[60, RIGHT_WRIST] - targets[60, RIGHT_WRIST]) < 0.01


# ----------------------------------------------------------------------------------------------
# Smoothness of the closed-form finish (scripts/measure_refine_smoothness.py measures it whole)
# ----------------------------------------------------------------------------------------------


def _chain(opening: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 3) root, middle, end of a two-bone chain (bones 0.3 m) opened to `opening` of its length."""
    n = len(opening)
    root = np.zeros((n, 3))
    d = 0.6 * opening
    h = np.sqrt(np.maximum(0.09 - (d / 2) ** 2, 0.0))
    mid = np.stack([d / 2, -h, np.zeros(n)], 1)  # bent towards -y
    end = np.stack([d, np.zeros(n), np.zeros(n)], 1)
    return root, mid, end


def test_two_bone_leaves_an_unmoved_chain_and_keeps_bones() -> None:
    from motion_env.generation.closed_form import _two_bone

    root, mid, end = _chain(np.linspace(0.05, 0.999, 40))
    new_mid, new_end = _two_bone(root, mid, end, end, soft=0.03)
    np.testing.assert_allclose(new_mid, mid, atol=1e-6)
    np.testing.assert_allclose(new_end, end, atol=1e-6)
    rng = np.random.default_rng(1)
    goal = end + rng.normal(size=end.shape) * 0.1
    new_mid, new_end = _two_bone(root, mid, end, goal, np.array([0.0, 0.0, 1.0]), soft=0.03)
    np.testing.assert_allclose(np.linalg.norm(new_mid - root, axis=1), 0.3, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(new_end - new_mid, axis=1), 0.3, atol=1e-9)


def test_two_bone_moves_its_middle_joint_no_more_than_the_analytic_solve_and_reaches_softly() -> None:
    """Small moves of the end, in every direction, at every opening: the middle joint moves no
    more than the plain analytic solve's (feet.two_bone_ik); out past full extension the chain
    straightens softly instead of snapping."""
    from motion_env.generation.closed_form import _two_bone

    rng = np.random.default_rng(0)
    for opening in (0.04, 0.1, 0.3, 0.9):
        root, mid, end = _chain(np.full(200, opening))
        move = rng.normal(size=(200, 3))
        move *= 0.01 / np.linalg.norm(move, axis=1, keepdims=True)
        new_mid, _ = _two_bone(root, mid, end, end + move)
        old_mid, _ = two_bone_ik(root, mid, end, end + move)
        gain = np.linalg.norm(new_mid - mid, axis=1)
        assert gain.max() <= np.linalg.norm(old_mid - mid, axis=1).max() + 1e-6
    n = 60
    root, mid, end = _chain(np.full(n, 0.9))
    goal = end + np.linspace(0.0, 0.15, n)[:, None] * [1.0, 0.0, 0.0]
    new_mid, new_end = _two_bone(root, mid, end, goal, soft=0.03)
    old_mid, _ = two_bone_ik(root, mid, end, goal)
    jerk = np.linalg.norm(np.diff(new_mid, 2, axis=0), axis=1).max()
    assert jerk < 0.5 * np.linalg.norm(np.diff(old_mid, 2, axis=0), axis=1).max()
    assert 0.6 - 0.03 < np.linalg.norm(new_end[-1]) < 0.6


def test_two_bone_spreads_a_flip_of_a_chain_swung_far_over_frames() -> None:
    """A leg hanging down, knee bent forward, its foot raised frame by frame past hip height in
    front (a climb): the side the knee bent to, measured against the new axis, vanishes as the leg
    passes the horizontal and flips, and the knee swings to the other side in a frame. Given the
    rows' frames, the flip is spread over the frames around it; the foot still meets its goal."""
    from motion_env.generation.closed_form import _two_bone

    n = 40
    angle = np.linspace(0.0, 0.75 * np.pi, n)  # the leg's swing, from straight down to forward and up
    root = np.zeros((n, 3))
    mid = np.tile([0.0, -0.4, 0.05], (n, 1))  # knee a little forward (+z)
    end = np.tile([0.0, -0.8, 0.0], (n, 1))
    goal = 0.7 * np.stack([np.zeros(n), -np.cos(angle), np.sin(angle)], 1)
    accel = {}
    for frames in (None, np.arange(n)):
        new_mid, new_end = _two_bone(root, mid, end, goal, soft=0.01, frames=frames)
        np.testing.assert_allclose(new_end, goal, atol=1e-9)
        np.testing.assert_allclose(np.linalg.norm(new_mid - root, axis=1), 0.4031, atol=1e-3)
        accel[frames is None] = np.linalg.norm(np.diff(new_mid, 2, axis=0), axis=1).max()
    assert accel[True] > 0.3  # the flip: the knee jumps 40 cm
    assert accel[False] < 0.25 * accel[True]


def test_head_target_near_the_pelvis_does_not_swing_the_upper_body(walk) -> None:
    """Head targets far below the reach of a lowered pelvis (where the pelvis goes, a few cm off
    it and circling it): the spine leans towards them without the upper body swinging round the
    pelvis (aimed at the targets' directions, the head went round at 100 m/s^2)."""
    targets = np.full(walk.shape, np.nan, np.float32)
    frames = np.arange(10, 50, 2)
    drift = 0.04 * np.stack([np.sin(frames / 4.0), np.zeros(len(frames)), np.cos(frames / 4.0)], 1)
    targets[frames, HEAD] = walk[frames, 0] + drift + [0.0, -HEAD_DROP, 0.0]  # at the lowered pelvis
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = solve_limbs(walk, targets, [], np.zeros((len(walk), 2), bool))
    head_acc = np.linalg.norm(np.diff(out[:, HEAD], 2, axis=0), axis=1).max() * 400.0  # m/s^2 at 20 fps
    assert head_acc < 20.0
    assert (out[frames, HEAD, 1] < walk[frames, HEAD, 1] - 0.2).all()  # it does go down


def test_head_target_lowers_the_pelvis_and_leans_instead_of_bending_the_spine(walk) -> None:
    targets = np.full(walk.shape, np.nan, np.float32)
    frames = np.arange(10, 50, 3)
    rng = np.random.default_rng(0)
    # Dense head targets a few cm lower and forward, noisy as a real take's head against ours.
    targets[frames, HEAD] = (
        walk[frames, HEAD] + [0.03, -0.05, 0.04] + rng.normal(size=(len(frames), 3)) * 0.01
    )
    out = solve_limbs(walk, targets, [], np.zeros((len(walk), 2), bool))
    assert np.linalg.norm(out[frames, HEAD] - targets[frames, HEAD], axis=-1).max() < 2e-3
    # The spine keeps its shape (spine3 on its way from the pelvis to the head), so the upper body
    # does not swing with the noise: no joint accelerates more than the clip plus the targets ask.
    spine = np.linalg.norm(out[:, 9] - out[:, 0], axis=-1) + np.linalg.norm(out[:, 15] - out[:, 9], axis=-1)
    straight = np.linalg.norm(out[:, 15] - out[:, 0], axis=-1)
    before = np.linalg.norm(walk[:, 15] - walk[:, 0], axis=-1)
    np.testing.assert_allclose(straight / spine, before / spine, atol=1e-3)
    assert out[frames, 0, 1].mean() < walk[frames, 0, 1].mean() - 0.03


def test_paths_are_steered_only_to_targets_out_of_reach() -> None:
    from motion_env.generation.root_bending import implied_route, within_reach

    path = np.zeros((100, 3), np.float32)
    path[:, 1] = np.linspace(0.0, 4.0, 100)  # walks 4 m along z
    targets = np.full((100, 22, 3), np.nan, np.float32)
    targets[50, RIGHT_WRIST] = [0.4, 1.2, 2.1]  # an arm's length from where the body is then
    assert within_reach(targets, path) and implied_route(targets, path=path) is None
    assert implied_route(targets) is not None  # without the path: steered, as before
    targets[80, 0] = [1.5, 0.9, 3.2]  # the pelvis 1.5 m aside: the body has to walk there
    assert not within_reach(targets, path)
    route = implied_route(targets, path=path)
    assert route is not None and route[-1, 2] == 80


def test_bent_root_does_not_jump_at_the_start_or_spin_for_a_side_step() -> None:
    from motion_env.generation.root_bending import bend_root

    t = 100
    path = np.zeros((t, 3), np.float32)
    path[:, 1] = np.linspace(0.0, 3.0, t)
    joints = np.zeros((t, 22, 3), np.float32)
    joints[:, :, [0, 2]] = path[:, None, :2]
    targets = np.full((t, 22, 3), np.nan, np.float32)
    targets[1, HEAD] = [0.15, 1.6, path[1, 1]]  # the head 15 cm aside at frame 1
    bent = bend_root(path, joints, targets, None)
    assert np.linalg.norm(bent[1, :2] - bent[0, :2]) < 0.05  # the limbs reach, the path eases in
    targets = np.full((t, 22, 3), np.nan, np.float32)
    targets[60, 0] = [0.0, 0.9, path[60, 1]]
    targets[63, 0] = [0.12, 0.9, path[63, 1]]  # a 12 cm side step in 3 frames
    bent = bend_root(path, joints, targets, None)
    np.testing.assert_allclose(bent[[60, 63]][:, :2], targets[[60, 63], 0][:, [0, 2]], atol=1e-5)
    assert np.abs(np.diff(bent[:, 2])).max() < 0.15  # radians per frame: no spin


def test_smooth_field_keeps_exact_frames_and_rounds_off_a_held_step() -> None:
    # A foot planted over frames 20-34 holds its correction (0), a target at frame 37 asks 0.4 m:
    # residual_field jumps there in 2 frames; smoothed, the step spreads over several frames.
    known = np.zeros(60, bool)
    known[37] = True
    res = np.zeros((60, 3))
    res[37] = [0.4, 0.0, -0.2]
    hold = np.zeros(60, bool)
    hold[20:35] = True
    known_hold = known.copy()
    known_hold[25] = True  # the planted stretch keeps its (zero) correction
    raw = residual_field(known_hold, res, hold=hold)
    smooth = smooth_field(raw, known_hold, np.where(hold, PLANT_WEIGHT, 1.0), 4.0)
    np.testing.assert_allclose(smooth[known_hold], raw[known_hold], atol=1e-6)
    acc = lambda f: np.abs(np.diff(f, 2, axis=0)).max()  # noqa: E731
    assert acc(smooth) < acc(raw) / 3
    assert np.abs(smooth[20:30]).max() < 0.04  # the planted foot gives way by a tenth at most
    # Nothing to smooth: a zero field, or one given at every frame, comes back as it was.
    assert not smooth_field(np.zeros((60, 3)), known, np.ones(60), 4.0).any()
    every = np.random.default_rng(0).normal(size=(60, 3))
    np.testing.assert_array_equal(smooth_field(every, np.ones(60, bool), np.ones(60), 4.0), every)


def test_leg_correction_next_to_a_plant_does_not_pop(walk, monkeypatch) -> None:
    """A correction held over a plant and joined linearly to a target a few frames later jumped."""
    import motion_env.generation.closed_form as closed_form

    targets = np.full(walk.shape, np.nan, np.float32)
    ankle = JOINT_INDEX["left_ankle"]
    # The foot is planted on its target (frames 20-34), and 4 frames later asked 27 cm away.
    targets[25, ankle] = walk[25, ankle]
    targets[38, ankle] = walk[38, ankle] + [0.25, 0.05, 0.1]
    planted = np.zeros((len(walk), 2), bool)
    planted[20:35, 0] = True
    out = solve_limbs(walk, targets, [], planted)
    monkeypatch.setattr(closed_form, "SMOOTH_FRAMES", 0.0)
    unsmoothed = solve_limbs(walk, targets, [], planted)
    for f in (25, 38):
        assert np.linalg.norm(out[f, ankle] - targets[f, ankle]) < 1e-3
    acc = lambda j: np.abs(np.diff(j[:, ankle] - walk[:, ankle], 2, axis=0)).max()  # noqa: E731
    assert acc(out) < acc(unsmoothed) / 2
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(walk), atol=1e-4)


class _ArmsFlip:
    """A composition and placement standing in for the real ones: (n, 263) features -> (n, 22, 3)
    joints that move smoothly with channel 0 as composed, and whose elbow flips 20 cm to the other
    side once placed (feet pinned, physics) wherever channel 0 passes 0.5: a shortened decoded arm,
    or a foot the pin takes anew, that the composition alone does not show."""

    def compose(self, features: np.ndarray, path: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        joints = np.zeros((n, 22, 3), np.float32)
        joints[:, :, 0] = features[:n, :1]  # the body moves with channel 0
        return joints, path

    def place_clip(self, features: np.ndarray, path: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        joints, _ = self.compose(features, path, n)
        placed = joints.copy()
        placed[:, 19, 2] = np.where(features[:n, 0] > 0.5, 0.2, 0.0)
        return joints, placed


def test_an_optimised_clip_that_composes_to_a_pop_keeps_less_of_its_change() -> None:
    from motion_env.generation.refine import _without_new_pops

    n, pipe, path = 40, _ArmsFlip(), np.zeros((40, 3), np.float32)
    sampled = np.zeros((n, 263), np.float32)
    sampled[:, 0] = 0.2 * np.sin(np.arange(n) / 4.0)  # a smooth motion, below 0.5
    optimised = sampled.copy()
    optimised[:, 0] += 0.45 * smoothstep((np.arange(n) - 5) / 30.0)  # a smooth change: past 0.5 late
    guarded, _ = _without_new_pops(pipe, sampled, optimised, path, n, guard=1.2)
    np.testing.assert_allclose(guarded, sampled + 0.5 * (optimised - sampled), atol=1e-6)  # no flip
    assert guarded[:, 0].max() < 0.5 < optimised[:, 0].max()
    unguarded, _ = _without_new_pops(pipe, sampled, optimised, path, n, guard=0.0)
    np.testing.assert_array_equal(unguarded, optimised)
    small = sampled.copy()
    small[:, 0] += 0.1 * smoothstep((np.arange(n) - 5) / 30.0)  # composes smoothly: kept whole
    np.testing.assert_array_equal(_without_new_pops(pipe, sampled, small, path, n, guard=1.2)[0], small)


def test_a_big_wrist_correction_fades_over_enough_frames_to_stay_gentle(walk) -> None:
    from motion_env.generation.closed_form import ARM_ACCEL

    still = np.repeat(walk[:1], 80, axis=0)  # a body standing still: all acceleration is the finish's
    shoulder, wrist = still[40, 17], still[40, RIGHT_WRIST]
    rel = wrist - shoulder
    turned = np.array([rel[0], -rel[2], rel[1]])  # the arm swung a quarter turn about the shoulder
    targets = np.full(still.shape, np.nan, np.float32)
    targets[40, RIGHT_WRIST] = shoulder + turned
    sweep = float(np.linalg.norm(turned - rel))
    assert 6 * sweep / FADE**2 > 1.5 * ARM_ACCEL  # faded over FADE frames alone it would be harsher
    out = solve_limbs(still, targets, [], np.zeros((len(still), 2), bool))
    assert np.linalg.norm(out[40, RIGHT_WRIST] - targets[40, RIGHT_WRIST]) < 1e-3
    accel = np.linalg.norm(np.diff(out[:, RIGHT_WRIST], 2, axis=0), axis=-1)
    assert accel.max() <= 1.5 * ARM_ACCEL


def test_dense_irregular_head_targets_are_met_without_kinks(walk) -> None:
    """Head targets every 1-4 frames, taken from a smooth sway the body does not make: the
    finish meets each one and rounds the correction off between them (joined linearly, its kinks
    at the targets made a wrist pop: a controlled wave 3.65x its clip without targets)."""
    still = np.repeat(walk[:1], 60, axis=0)
    frames = np.array([10, 12, 13, 17, 19, 20, 24, 26, 27, 31, 33, 34, 38, 40])
    t = np.arange(60) / 20.0
    sway = np.stack([0.08 * np.sin(2.0 * t), -0.06 * (1 - np.cos(1.5 * t)), 0.05 * np.sin(3.0 * t)], 1)
    targets = np.full(still.shape, np.nan, np.float32)
    targets[frames, HEAD] = still[frames, HEAD] + sway[frames]
    out = solve_limbs(still, targets, [], np.ones((60, 2), bool))
    assert np.linalg.norm(out[frames, HEAD] - targets[frames, HEAD], axis=1).max() < 2e-3

    def largest(x: np.ndarray) -> float:  # m/s^2 at 20 fps
        return float(np.linalg.norm(np.diff(x, 2, axis=0), axis=-1).max() * 400.0)

    own = largest(still[:, HEAD] + sway)  # the sway's own, about 0.6 m/s^2
    assert largest(out[:, HEAD]) < 3.0 * own
    assert largest(out[:, RIGHT_WRIST]) < 4.0 * own
