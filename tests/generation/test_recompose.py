"""Recompose (body on the path), waypoint snapping, foot-contact cleanup and the skating metric."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from motion_env.evaluation.metrics import foot_skating_ratio
from motion_env.generation import recompose as rc
from motion_env.generation.feet import FootPinner, two_bone_ik
from motion_env.motion.features import features_to_joints
from motion_env.motion.kinematics import heading_from_joints
from motion_env.motion.skeleton import LEGS
from motion_env.motion.trajectory import root_path_from_joints, waypoint_errors, wrap_angle


def _curve(num: int) -> np.ndarray:
    """An S-shaped walk at ~1.2 m/s whose heading wobbles up to 15 degrees off the travel direction."""
    t = np.arange(num) / 20.0
    x = 1.5 * np.sin(0.6 * t)
    z = 1.2 * t
    travel = np.arctan2(0.9 * np.cos(0.6 * t), 1.2)
    return np.stack([x, z, travel + np.radians(15) * np.sin(3 * t)], 1).astype(np.float32)


def test_recompose_round_trips_real_motion(humanml3d_sample) -> None:
    joints, features = humanml3d_sample
    path = root_path_from_joints(joints)
    local = rc.local_pose_from_joints(joints, path)
    np.testing.assert_allclose(local[:, 0, [0, 2]], 0, atol=1e-6)
    np.testing.assert_allclose(rc.recompose(local, path, face_travel=False), joints, atol=1e-5)
    np.testing.assert_allclose(
        rc.local_pose_from_features(features),
        rc.local_pose_from_joints(features_to_joints(features)),
        atol=1e-6,
    )


def test_part_of_the_local_pose_is_the_same_numbers_as_the_whole(humanml3d_sample) -> None:
    """The stream's window: the local pose of its last frames only (the heading still smoothed
    over the window) and joints of some frames and joints only are bit for bit the whole's."""
    _, features = humanml3d_sample
    feats = np.stack([features[:40], features[30:70]])
    whole = rc.local_pose_from_features(feats)
    for first in (1, 20, 36, 39):
        np.testing.assert_array_equal(rc.local_pose_from_features(feats, first=first), whole[:, first:])
        np.testing.assert_array_equal(rc.local_pose_from_features(feats[1], first=first), whole[1, first:])
    joints = features_to_joints(feats)
    np.testing.assert_array_equal(features_to_joints(feats, first=36), joints[:, 36:])
    np.testing.assert_array_equal(features_to_joints(feats, only=(17, 0, 2)), joints[:, :, [17, 0, 2]])
    np.testing.assert_array_equal(features_to_joints(feats, first=5, only=(0,)), joints[:, 5:, :1])
    bad_parts = [{"first": 40}, {"first": -1}, {"first": 1.5}, {"only": (22,)}, {"only": ()}]
    for bad in [*bad_parts, {"only": (0.5,)}]:
        with pytest.raises(ValueError, match="first must be|only must"):
            features_to_joints(feats, **bad)


def test_compose_of_a_batch_equals_composing_each_clip(humanml3d_sample, random_generator) -> None:
    _, features = humanml3d_sample
    feats = np.stack([features[:40], features[10:50], features[20:60]])  # three clips of 40 frames
    paths = np.stack([_curve(60), _curve(60)[::-1].copy(), _curve(60) + 0.5])  # 20 frames of look-ahead
    joints, path = random_generator.pipeline.compose(feats, paths, 40)
    assert joints.shape == (3, 40, 22, 3) and path.shape == (3, 40, 3)
    for b in range(3):
        one_joints, one_path = random_generator.pipeline.compose(feats[b], paths[b], 40)
        np.testing.assert_allclose(joints[b], one_joints, atol=1e-6)
        np.testing.assert_allclose(path[b], one_path, atol=1e-6)


def test_recompose_puts_the_pelvis_on_the_path_facing_travel(humanml3d_sample) -> None:
    joints, _ = humanml3d_sample
    # A local pose whose own facing is exactly +Z in every frame (factor out the raw heading).
    local = rc.local_pose_from_joints(joints, root_path_from_joints(joints, smooth_sigma=0))
    path = _curve(len(local))
    out = rc.recompose(local, path)
    assert out.shape == joints.shape and out.dtype == np.float32
    np.testing.assert_allclose(out[:, 0, [0, 2]], path[:, :2], atol=1e-5)
    np.testing.assert_allclose(out[:, :, 1], local[:, :, 1], atol=1e-5)  # heights from the pose
    vel = np.gradient(path[:, :2], axis=0)
    travel = np.arctan2(vel[:, 0], vel[:, 1])
    facing = heading_from_joints(out)
    assert np.degrees(np.abs(wrap_angle(facing - travel)))[3:-3].max() < 3.0
    # Without face_travel the body keeps the path's own heading.
    kept = heading_from_joints(rc.recompose(local, path, face_travel=False))
    np.testing.assert_allclose(wrap_angle(kept - path[:, 2]), 0, atol=1e-4)


def test_align_heading_keeps_side_steps_and_still_frames() -> None:
    n = 60
    side = np.stack([np.arange(n) * 0.05, np.zeros(n), np.zeros(n)], 1)  # moving +X while facing +Z
    np.testing.assert_allclose(rc.align_heading_to_travel(side)[:, 2], 0, atol=1e-6)
    still = np.stack([np.zeros(n), np.zeros(n), np.full(n, 1.0)], 1)
    np.testing.assert_allclose(rc.align_heading_to_travel(still)[:, 2], 1.0, atol=1e-6)


def test_recompose_errors() -> None:
    with pytest.raises(ValueError, match="root_path has 10 frames"):
        rc.recompose(np.zeros((12, 22, 3)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match="local_pose"):
        rc.recompose(np.zeros((10, 21, 3)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match="NaN or infinite"):
        rc.recompose(np.zeros((2, 22, 3)), np.array([[0, 0, 0], [np.nan, 0, 0]]))


def test_snap_hits_timed_and_untimed_waypoints_exactly() -> None:
    path = _curve(120)
    wp = np.array(
        [[0.5, 1.0, 20], [2.0, 3.5, 55], [0.0, 5.0, np.nan], [1.0, 7.0, 110], [9, 9, 400]], np.float32
    )
    snapped = rc.snap_to_waypoints(path, wp)
    frames = rc.waypoint_frames(snapped, wp)
    assert frames[-1] == -1  # past the end: ignored
    err = waypoint_errors(snapped, wp[:4])
    np.testing.assert_allclose(err, 0, atol=1e-5)
    np.testing.assert_allclose(snapped[0], path[0], atol=1e-6)  # the start stays
    # Smooth: no step in the path larger than the original steps plus the spread-out residual.
    assert np.abs(np.diff(snapped[:, :2], axis=0)).max() < 0.2
    # Deterministic.
    np.testing.assert_array_equal(rc.snap_to_waypoints(path, wp), snapped)


def test_a_turned_back_waypoint_is_found_on_the_path_before_smoothing() -> None:
    # Out 3 m along z and straight back: smoothing cuts the turn's corner, so the smoothed path
    # stops short of the waypoint at the turn (by more than SNAP_RADIUS at this speed); the
    # controller's own path, which steered through it, still finds it.
    t = np.arange(60, dtype=np.float64)
    z = np.where(t < 30, t * 0.1, 6.0 - t * 0.1)
    steered = np.stack([np.zeros_like(t), z, np.zeros_like(t)], 1).astype(np.float32)
    smoothed = rc.smooth_path(steered, 12.0)
    route = np.array([[0.0, 3.0, np.nan]], np.float32)
    assert np.linalg.norm(smoothed[:, :2] - route[0, :2], axis=1).min() > rc.SNAP_RADIUS
    assert len(rc.route_anchors(smoothed, route)) == 0
    anchors = rc.route_anchors(smoothed, route, steered=steered)
    np.testing.assert_allclose(anchors, [[0.0, 3.0, 30.0]])
    snapped = rc.snap_route(smoothed, route, steered)
    np.testing.assert_allclose(snapped[30, :2], [0.0, 3.0], atol=1e-5)


def _walk_then_stand(stop_z: float, frames: int = 80) -> np.ndarray:
    """Along +z at 1.5 m/s, slowing to a stand at `stop_z` by frame 50, then standing still."""
    t = np.arange(frames, dtype=np.float64)
    s = np.clip(t / 50, 0, 1)
    z = stop_z * (1 - (1 - s) ** 2)  # decelerates to zero speed at frame 50
    return np.stack([np.zeros_like(t), z, np.zeros_like(t)], 1).astype(np.float32)


def test_a_clip_stands_on_its_last_untimed_waypoint_not_past_it() -> None:
    # The path passes the waypoint at z = 3.0 and stands 0.36 m beyond it (a jog that brakes
    # late): the stance, not the passing point, is put on the waypoint.
    path = _walk_then_stand(3.36)
    route = np.array([[0.0, 3.0, np.nan]], np.float32)
    anchors = rc.route_anchors(path, route)
    assert len(anchors) == 1 and 40 < anchors[0, 2] < 60  # where the path comes to rest
    snapped = rc.snap_route(path, route)
    k = int(anchors[0, 2])
    np.testing.assert_allclose(snapped[k:, :2].mean(axis=0), [0.0, 3.0], atol=1e-4)
    np.testing.assert_allclose(snapped[-1, :2], [0.0, 3.0], atol=0.005)
    np.testing.assert_allclose(snapped[0], path[0], atol=1e-6)
    # Standing short of it (0.7 m: never within SNAP_RADIUS) brings it there too.
    short = rc.snap_route(_walk_then_stand(2.3), route)
    np.testing.assert_allclose(short[-1, :2], [0.0, 3.0], atol=0.02)
    # Farther than STOP_RADIUS: the controller went elsewhere; the path is left alone.
    far = _walk_then_stand(3.0 - rc.STOP_RADIUS - 0.3)
    np.testing.assert_array_equal(rc.snap_route(far, route), far)
    # The stream's open end, a timed last waypoint, a path still moving at its end: as before.
    passing = int(np.argmin(np.abs(path[:, 1] - 3.0)))
    np.testing.assert_allclose(rc.route_anchors(path, route, open_end=True), [[0.0, 3.0, passing]])
    timed = np.array([[0.0, 3.0, 30.0]], np.float32)
    np.testing.assert_allclose(rc.route_anchors(path, timed), [[0.0, 3.0, 30.0]])
    moving = path.copy()
    moving[:, 1] += 0.02 * np.arange(len(path))  # never comes to rest
    assert rc.route_anchors(moving, route)[0, 2] == np.argmin(np.abs(moving[:, 1] - 3.0))


def test_snap_turns_the_heading_with_the_new_direction() -> None:
    n = 80
    straight = np.stack([np.zeros(n), np.arange(n) * 0.06, np.zeros(n)], 1)  # forward along +Z
    snapped = rc.snap_to_waypoints(straight, [[4.8, 4.8, n - 1]])  # pulled to walk diagonally
    vel = np.gradient(snapped[:, :2], axis=0)
    travel = np.arctan2(vel[:, 0], vel[:, 1])
    mid = slice(n // 4, 3 * n // 4)
    np.testing.assert_allclose(wrap_angle(snapped[mid, 2] - travel[mid]), 0, atol=0.05)
    dense = np.stack([np.sin(np.arange(n) / 10), np.arange(n) * 0.05, np.arange(n)], 1)
    np.testing.assert_allclose(rc.snap_to_waypoints(straight, dense)[:, :2], dense[:, :2], atol=1e-5)


def test_foot_pinner_reduces_skating_and_keeps_the_legs(humanml3d_sample) -> None:
    joints, features = humanml3d_sample
    # Skating clip: the body glides forward 4 cm per frame on top of its own motion, so every planted
    # foot slides (what a root path faster than the legs produces). The pinner holds a foot at most
    # FOOT_MAX_OFFSET from where the body puts it (no pops), so long contacts still slide in part.
    skating = joints.copy()[: len(features)]
    skating[..., 2] += 0.04 * np.arange(len(skating))[:, None]
    contacts = features[:, -4:]
    before = foot_skating_ratio(skating)
    cleaned = FootPinner(1).apply(0, skating, contacts)
    after = foot_skating_ratio(cleaned)
    assert before > 0.5 and after < 0.8 * before, (before, after)
    # Pelvis, spine and arms untouched; thigh and shin lengths kept.
    untouched = [j for j in range(22) if j not in (4, 5, 7, 8, 10, 11)]
    np.testing.assert_array_equal(cleaned[:, untouched], skating[:, untouched])
    for hip, knee, ankle, _ in LEGS:
        for a, b in ((hip, knee), (knee, ankle)):
            np.testing.assert_allclose(
                np.linalg.norm(cleaned[:, a] - cleaned[:, b], axis=-1),
                np.linalg.norm(skating[:, a] - skating[:, b], axis=-1),
                atol=1e-5,
            )


def test_foot_pinner_leaves_free_motion_alone(humanml3d_sample) -> None:
    joints, _ = humanml3d_sample
    lifted = joints.copy()
    lifted[..., 1] += 1.0
    none = np.zeros((len(joints), 4))
    np.testing.assert_allclose(FootPinner(1).apply(0, lifted, none), lifted, atol=1e-5)
    assert math.isclose(foot_skating_ratio(lifted), 0.0)


@pytest.mark.parametrize("hint", ["none", "toes", "fill"])
def test_the_compiled_two_bone_ik_gives_what_numpy_gives(both_ways: Callable, hint: str) -> None:
    """ik_jit against two_bone_ik's numpy operations, to the bit: bent, straight and folded limbs,
    targets near, out of reach and straight across the root from the limb's end (the half turn),
    with no hint, a hint, and a hint that fills the bend a limb does not show."""
    from motion_env.generation import ik_jit

    rng = np.random.default_rng(5)
    n = 200
    hip = rng.normal(0.0, 0.1, (n, 3)) + [0.0, 0.9, 0.0]
    knee = hip + rng.normal(0.0, 0.1, (n, 3)) + [0.0, -0.4, 0.0]
    ankle = knee + rng.normal(0.0, 0.1, (n, 3)) + [0.0, -0.4, 0.0]
    target = ankle + rng.normal(0.0, 0.3, (n, 3))
    knee[:20] = hip[:20] + 0.5 * (ankle[:20] - hip[:20])  # straight
    ankle[20:40] = hip[20:40] + 0.3 * (knee[20:40] - hip[20:40])  # folded back
    # Targets straight across the root from the limb's end: hanging down, and held out sideways.
    across = ((slice(40, 50), [0.0, -1.0, 0.0]), (slice(50, 60), [-1.0, 0.0, 0.0]))
    for rows, axis in (*across, (slice(60, 70), [-0.6, -0.64, -0.48])):
        knee[rows] = hip[rows] + 0.4 * np.array(axis) + [0.02, 0.01, 0.03]
        ankle[rows], target[rows] = hip[rows] + 0.8 * np.array(axis), hip[rows] - 0.5 * np.array(axis)
    bend_hint = None if hint == "none" else rng.normal(0.0, 0.1, (n, 3))
    fill = 1.0 if hint == "fill" else 0.0
    outputs = both_ways(
        ik_jit,
        "solve_rows",
        lambda: two_bone_ik(hip, knee, ankle, target, bend_hint, hint_length=0.1, hint_fill=fill),
    )
    for got, want in zip(outputs[True], outputs[False], strict=True):
        np.testing.assert_array_equal(got, want)


def _spun(features: np.ndarray) -> np.ndarray:
    """`features` turning on the spot a half turn a frame in places (every wrap of the heading
    visited, steps of exactly pi), with a root that drifts far off."""
    spun = features.copy()
    spun[::3, 0] = np.float32(np.pi / 2)  # the root's rotation velocity is half the heading's step
    spun[1::5, 0] = np.float32(-np.pi / 2)
    spun[:, 1:3] *= 40.0
    return spun


def test_the_compiled_local_pose_gives_what_numpy_gives(both_ways: Callable, humanml3d_sample) -> None:
    """compose_jit.local_pose against local_pose_from_features' numpy operations, to the bit: a
    real clip, the same spinning, a batch of windows, each from frame 0 and from later frames."""
    from motion_env.generation import compose_jit

    _, features = humanml3d_sample
    windows = np.stack([features[:40], features[30:70], _spun(features[:40])])
    for feats in (features, _spun(features), windows):
        for first in (0, 1, feats.shape[-2] - 4, feats.shape[-2] - 1):
            run = lambda f=feats, k=first: rc.local_pose_from_features(f, k)  # noqa: E731
            outputs = both_ways(compose_jit, "local_pose", run)
            np.testing.assert_array_equal(outputs[True], outputs[False])
    bad = features.copy()
    bad[7, 100] = np.nan
    with pytest.raises(ValueError, match="frames \\[7\\]"):  # the numpy path names the frame
        rc.local_pose_from_features(bad, 3)
    huge = features.copy()
    huge[:, 4:] = np.float32(3e38)  # joints past float32's range: numpy's check names them
    with np.errstate(over="ignore", invalid="ignore"), pytest.raises(ValueError, match="infinite"):
        rc.local_pose_from_features(huge, 3)


def test_the_compiled_heading_and_placement_give_what_numpy_gives(both_ways: Callable) -> None:
    """compose_jit.travel_heading, place_on_path and smooth_paths against align_heading_to_travel's,
    recompose's and smooth_path's numpy operations, to the bit: a curving walk, side steps, a
    backward walk, a body standing still, headings that wrap round, one frame (two and three for
    the smoothing's reflection), and a batch."""
    from motion_env.generation import compose_jit

    rng = np.random.default_rng(9)
    walk = _curve(80)
    side = walk.copy()
    side[:, 2] += np.pi / 2
    back = walk.copy()
    back[:, 2] += np.pi
    still = np.repeat(walk[:1], 30, axis=0)
    wrapped = walk.copy()
    wrapped[:, 2] += np.float32(3 * np.pi) + rng.normal(0.0, 0.3, 80).astype(np.float32)
    paths = [walk, side, back, still, wrapped, walk[:1], np.stack([walk, back, wrapped])]
    for path in paths:
        outputs = both_ways(compose_jit, "travel_heading", lambda p=path: rc.align_heading_to_travel(p))
        np.testing.assert_array_equal(outputs[True], outputs[False])
        local = rng.normal(0.0, 0.3, path.shape[:-1] + (22, 3)).astype(np.float32)
        outputs = both_ways(compose_jit, "place_on_path", lambda p=path, q=local: rc.recompose(q, p))
        np.testing.assert_array_equal(outputs[True], outputs[False])
    for path in (walk, walk[:2], walk[:3], walk[:9], wrapped.astype(np.float64), np.stack([walk, back])):
        outputs = both_ways(compose_jit, "smooth_paths", lambda p=path: rc.smooth_path(p, 2.0))
        np.testing.assert_array_equal(outputs[True], outputs[False])
        assert outputs[True].dtype == path.dtype


def test_the_compiled_angle_steps_and_gaussian_match_numpys_and_scipys() -> None:
    """The compiled wrap and unwrap (jit_math) against numpy's on the edges of their ranges (angles
    of odd multiples of pi, steps of exactly +-pi and of 2 pi), and compose_jit's Gaussian against
    scipy's."""
    from motion_env.generation import compose_jit
    from motion_env.models import jit_math

    pi = np.pi
    angles = np.array([-3 * pi, -pi, -pi + 1e-12, 0.0, -0.0, pi - 1e-12, pi, 2 * pi, 3 * pi, 1e3, -1e3])
    wrapped = np.array([jit_math.wrap(a) for a in angles])
    np.testing.assert_array_equal(wrapped, wrap_angle(angles))
    line = np.cumsum([0.1, pi, -pi, 2 * pi, pi + 1e-9, -pi - 1e-9, 3.0, -3.0, 7.0])
    out = np.empty_like(line)
    jit_math.unwrap(line, out)
    np.testing.assert_array_equal(out, np.unwrap(line))
    rng = np.random.default_rng(4)  # the Gaussian in float64, where the order of its sums shows
    for sigma, size in ((5.0, 1), (5.0, 7), (5.0, 300), (2.0, 300), (1.0, 300)):
        values = np.cumsum(rng.normal(0.0, 1.0, size))
        out = np.empty_like(values)
        compose_jit._smooth(values, compose_jit.gaussian_weights(sigma), out)
        np.testing.assert_array_equal(out, gaussian_filter1d(values, sigma, mode="nearest"))


def test_two_bone_ik_keeps_a_nearly_straight_knee_bending_forward() -> None:
    # A running leg almost straight (knee 1 cm in front of the hip-ankle line), its ankle pulled
    # 25 cm forward and 10 cm up: the knee must stay in front (+z), not flip backwards.
    hip = np.array([[0.0, 0.9, 0.0]])
    knee = np.array([[0.0, 0.5, 0.01]])
    ankle = np.array([[0.0, 0.08, 0.0]])
    goal = ankle + [[0.05, 0.1, 0.25]]
    new_knee, new_ankle = two_bone_ik(hip, knee, ankle, goal)
    np.testing.assert_allclose(new_ankle, goal, atol=1e-6)
    axis = (goal - hip) / np.linalg.norm(goal - hip)
    bend = (new_knee - hip) - ((new_knee - hip) @ axis.T) * axis
    assert bend[0, 2] > 0 and abs(bend[0, 0]) < bend[0, 2]
    for length, (a, b) in zip((0.41, 0.42), ((hip, knee), (knee, ankle)), strict=True):
        assert abs(np.linalg.norm(a - b) - length) < 0.01
    # A perfectly straight leg bends the way the hint (the toes) points.
    straight = np.array([[0.0, 0.49, 0.0]])
    k2, _ = two_bone_ik(hip, straight, ankle, goal, bend_hint=np.array([[1.0, 0.0, 0.0]]))
    assert (k2 - hip)[0, 0] > 0.05
