"""The studio without a page: floor clicks, routes, the session's edits and frames, the files kept."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.motion.types import Motion
from motion_env.studio.geometry import (
    BONES,
    bone_colors,
    bone_segments,
    floor_point,
    followed_camera,
    resample_path,
)
from motion_env.studio.keep import clip_file
from motion_env.studio.route_progress import Route
from motion_env.studio.session import MAX_CHARACTERS, StudioSession


def test_floor_point() -> None:
    np.testing.assert_allclose(floor_point((0, 2, 0), (0.6, -0.8, 0.0)), [1.5, 0.0])
    assert floor_point((0, 2, 0), (0, 0.5, 1)) is None  # the sky
    assert floor_point((0, 2, 0), (1, 0, 0)) is None  # along the floor
    assert floor_point((0, -1, 0), (0, -1, 0)) is None  # from under the floor
    assert floor_point((0, 2, 0), (1, -1e-3, 0)) is None  # 2 km away: off the floor
    assert floor_point((0, 2, 0), (np.nan, -1, 0)) is None


def test_the_followed_camera_keeps_its_angle_and_distance() -> None:
    eye, target = np.array([4.0, 2.5, 5.0]), np.array([0.0, 0.9, 0.0])
    pelvis = np.array([0.6, 0.7, 1.4])
    new_eye, new_target = followed_camera(eye, target, pelvis)
    assert new_target == pytest.approx((0.6, 0.9, 1.4))  # over the character, at the chosen height
    assert new_eye - new_target == pytest.approx(eye - target)  # the user's angle and distance
    # Walking on, the view moves by what the character moved; a camera reported late (from before
    # the last move) lands in the same place.
    later = pelvis + (0.5, 0.0, 1.0)
    moved = followed_camera(new_eye, new_target, later)
    assert moved[0] == pytest.approx(new_eye + (0.5, 0.0, 1.0))
    stale = followed_camera(eye, target, later)
    assert stale[0] == pytest.approx(moved[0]) and stale[1] == pytest.approx(moved[1])


def test_bones_and_colours() -> None:
    assert BONES.shape == (21, 2) and (BONES[:, 0] < BONES[:, 1]).all()
    joints = np.random.default_rng(0).normal(size=(3, 22, 3))
    seg = bone_segments(joints)
    assert seg.shape == (3, 21, 2, 3)
    np.testing.assert_allclose(seg[1, 0, 1], joints[1, BONES[0, 1]], rtol=1e-6)
    colors = bone_colors()
    left_knee_bone = int(np.nonzero(BONES[:, 1] == 4)[0][0])
    right_knee_bone = int(np.nonzero(BONES[:, 1] == 5)[0][0])
    assert tuple(colors[left_knee_bone, 0]) == (31, 111, 209)  # LEFT_COLOR
    assert tuple(colors[right_knee_bone, 0]) == (240, 140, 26)  # RIGHT_COLOR


def test_resample_path() -> None:
    pts = resample_path([[0, 0], [0, 0.1], [0, 2.0], [2.0, 2.0]], spacing=0.5)
    steps = np.linalg.norm(np.diff(np.concatenate([[[0, 0]], pts]), axis=0), axis=1)
    assert len(pts) == 8 and np.allclose(pts[-1], [2, 2]) and steps.max() <= 0.5 + 1e-9
    np.testing.assert_allclose(resample_path([[1, 1], [1.1, 1]], 0.5), [[1.1, 1]])
    with pytest.raises(ValueError, match="at least one point"):
        resample_path(np.zeros((0, 2)))


def test_route_bookkeeping() -> None:
    route = Route()
    assert route.ahead(0) is None and route.target() is None
    route.add((0, 2))
    route.add((2, 2), frame=100)
    with pytest.raises(ValueError, match="must come after the last one"):
        route.add((3, 3), frame=50)
    assert len(route) == 2  # a refused waypoint changes nothing
    assert route.advance(np.array([0.1, 1.8]), 10) and route.next == 1
    assert not route.reached
    # Moved after its time: sent untimed.
    assert np.isnan(route.ahead(150)[0, 2]) and route.ahead(50)[0, 2] == 100
    route.advance(np.array([2.0, 2.1]), 60)
    assert route.reached and route.next == 1
    route.add((4, 4))  # a finished route starts again at its new waypoint
    assert not route.reached and route.next == 2
    route.move(0, (1, 1))
    assert route.next == 0 and np.allclose(route.points[0, :2], (1, 1))
    with pytest.raises(IndexError, match="no waypoint 9"):
        route.move(8, (0, 0))
    route.replace(None)
    assert len(route) == 0


def test_session_follows_waypoints_and_keeps_the_clip(generator) -> None:
    session = StudioSession(generator, ["a person walks forward"], seed=0)
    assert session.add_waypoint(0, (1.5, 2.5)) == 1
    assert session.add_waypoint(0, (-1.0, 5.0), seconds=6.0) == 2
    for _ in range(30):
        session.tick()
    session.set_caption(0, "  a person jogs  ")
    for _ in range(150):
        snap = session.tick()
    assert session.arrived(0, (1.5, 2.5)) and session.arrived(0, (-1.0, 5.0))
    assert snap.reached == [True] and snap.captions == ["a person jogs"]
    stats = session.stats(0)
    assert stats.frame == 181 and stats.waypoints_left == 0 and stats.step_ms_max >= stats.step_ms

    clip = session.clip(0)
    assert clip.num_frames == 181 and clip.text == "a person jogs"
    assert clip.meta["captions"] == "0: a person walks forward | 31: a person jogs"
    assert session.clip(0, last_seconds=2).num_frames == 40
    for kind, suffix in (("npz", ".npz"), ("bvh", ".bvh")):
        name, data = clip_file(clip, kind, "take")
        assert name == "take" + suffix and len(data) > 1000
    with pytest.raises(ValueError, match="one of"):
        clip_file(clip, "fbx", "take")

    session.reset(seed=3)
    assert session.frame == 1 and session.seed == 3
    assert len(session.snapshot().routes[0]) == 2  # the route stays for the new episode


def test_robot_csv(generator, tmp_path) -> None:
    pytest.importorskip("mink")
    session = StudioSession(generator, ["a person walks forward"], seed=0)
    for _ in range(40):
        session.tick()
    name, data = clip_file(session.clip(0), "csv", "take")
    lines = data.decode().splitlines()
    assert name == "take.csv" and any(line.startswith("# columns: ") for line in lines)
    assert abs(len([line for line in lines if not line.startswith("#")]) - 100) <= 1  # 2 s at 50 fps


def test_robot_files_in_every_format(generator, tmp_path) -> None:
    pytest.importorskip("mink")
    from motion_env.retarget import load_robot_motion

    session = StudioSession(generator, ["a person walks forward"], seed=0)
    for _ in range(20):
        session.tick()
    for kind, name in (
        ("lafan_csv", "take_lafan_csv.csv"),
        ("mjlab", "take_mjlab.npz"),
        ("gmr", "take_gmr.pkl"),
    ):
        filename, data = clip_file(session.clip(0), kind, "take", robot="booster_t1")
        assert filename == name
        path = tmp_path / filename
        path.write_bytes(data)
        clip = load_robot_motion(path, robot="booster_t1")
        assert clip.robot == "booster_t1" and len(clip.qpos) > 10


def test_the_robot_view_poses_every_body_every_frame(generator) -> None:
    pytest.importorskip("mink", reason='the robot view needs mink: -e ".[robots]"')
    session = StudioSession(generator, ["a person walks forward", "a person waves"], seed=0)
    assert session.snapshot().robot is None
    session.set_robot("unitree_g1", index=1)
    snap = session.snapshot()
    pose, start = snap.robot, snap.joints[1, 0, [0, 2]]  # at once, for the frame on show
    assert pose.robot == "unitree_g1" and pose.character == 1
    assert np.linalg.norm(pose.root[[0, 2]] - start) < 0.1  # Y up, where its character stands
    for _ in range(20):
        snap = session.tick()
        pose = snap.robot
        assert pose.positions.shape == (31, 3) and pose.wxyz.shape == (31, 4)
        assert np.isfinite(pose.positions).all() and 0.5 < pose.root[1] < 1.0
        assert np.linalg.norm(pose.wxyz, axis=1) == pytest.approx(1.0)
        # Its steps are the character's, scaled by its shorter legs.
        walked = np.linalg.norm(snap.joints[1, 0, [0, 2]] - start)
        assert np.linalg.norm(pose.root[[0, 2]] - snap.joints[1, 0, [0, 2]]) < 0.1 + 0.4 * walked
    session.set_robot("booster_t1", index=0)
    assert session.tick().robot.robot == "booster_t1"
    session.reset()
    assert session.snapshot().robot.character == 0  # it stays across a reset
    session.set_robot(None)
    assert session.tick().robot is None


def test_robot_meshes_are_the_visual_geoms() -> None:
    pytest.importorskip("mink")
    from motion_env.retarget.robot import load_robot
    from motion_env.studio.robot_view import robot_meshes

    meshes = robot_meshes(load_robot("unitree_g1").model)
    assert len(meshes) == 35  # the visual meshes, not their collision copies
    for mesh in meshes:
        assert mesh.faces.max() < len(mesh.vertices) and mesh.body > 0


def test_the_a_star_agent_walks_around_an_obstacle(generator) -> None:
    session = StudioSession(generator, ["a person walks forward"], seed=1)
    session.add_obstacle((0.0, 3.0), 1.0)
    session.set_goal(0, (0.0, 6.0))
    route = session.snapshot().routes[0]
    assert len(route) >= 2  # around, not through
    pelvis = []
    for _ in range(220):
        pelvis.append(session.tick().joints[0, 0, [0, 2]])
    assert session.arrived(0, (0.0, 6.0), radius=0.6)
    assert np.linalg.norm(np.array(pelvis) - (0.0, 3.0), axis=1).min() > 1.0  # never inside it
    session.add_obstacle((0.0, 8.0), 0.5)  # the agent re-plans; nothing breaks
    session.clear_goal(0)
    assert session.snapshot().goals == [None]


def test_bad_edits_are_refused_with_a_reason(generator) -> None:
    session = StudioSession(generator, ["a person walks"], seed=0)
    cases = [
        (lambda: session.add_waypoint(0, (99.0, 0.0)), ValueError, "off the floor"),
        (lambda: session.add_waypoint(0, (np.nan, 0.0)), ValueError, "two finite numbers"),
        (lambda: session.add_waypoint(0, (20.0, 20.0), seconds=0.5), ValueError, "too fast"),
        (lambda: session.add_waypoint(0, (1.0, 1.0), seconds=-2), ValueError, "seconds >= 0"),
        (lambda: session.add_waypoint(3, (1.0, 1.0)), IndexError, "no character 3"),
        (lambda: session.move_waypoint(0, 0, (1.0, 1.0)), IndexError, "no waypoint 1"),
        (lambda: session.set_caption(0, "   "), ValueError, "empty"),
        (lambda: session.add_obstacle((1.0, 1.0), 0.0), ValueError, "radius"),
        (lambda: session.reset(seed=-1), ValueError, "seed"),
        (lambda: session.set_path(0, np.zeros((0, 2))), ValueError, "at least one point"),
    ]
    for call, kind, message in cases:
        with pytest.raises(kind, match=message):
            call()
    assert len(session.snapshot().routes[0]) == 0 and session.snapshot().obstacles.shape == (0, 3)
    # A goal walled in: refused, and no agent is left behind.
    for angle in np.linspace(0, 2 * np.pi, 24, endpoint=False):
        session.add_obstacle((5 + 1.5 * np.cos(angle), 5 + 1.5 * np.sin(angle)), 0.5)
    with pytest.raises(ValueError, match="no path"):
        session.set_goal(0, (5.0, 5.0))
    assert session.snapshot().goals == [None]
    with pytest.raises(ValueError, match="1 to 16"):
        StudioSession(generator, ["a person walks"] * (MAX_CHARACTERS + 1))


def test_a_crowd_with_its_own_captions(generator) -> None:
    captions = ["a person walks forward", "a person jogs", "a person waves the right hand"]
    session = StudioSession(generator, captions, seed=0)
    session.add_waypoint(1, (0.0, 4.0))
    session.set_path(2, [[1.5, 0.0], [1.5, 1.0], [2.5, 2.0]])
    for _ in range(40):
        snap = session.tick()
    assert snap.joints.shape == (3, 22, 3) and snap.captions == captions
    assert np.ptp(snap.joints[:, 0, 0]) > 1.0  # side by side, not on top of each other
    assert len(snap.routes[2]) == 5  # 2.41 m drawn: a waypoint every 0.5 m
    assert len(snap.routes[0]) == 0
    clip = session.clip(2)
    assert isinstance(clip, Motion) and clip.text == captions[2]


def test_joint_targets_are_met_at_their_frame(generator) -> None:
    # Where the joints go without targets (the same seed gives the same frames).
    free = StudioSession(generator, ["a person walks forward"], seed=0)
    for _ in range(70):
        free.tick()
    natural = free.clip(0).joints
    right, left, head = JOINT_INDEX["right_wrist"], JOINT_INDEX["left_wrist"], JOINT_INDEX["head"]

    session = StudioSession(generator, ["a person walks forward"], seed=0)
    for _ in range(29):
        session.tick()
    want = natural[50, right] + (0.1, 0.2, 0.1)  # within reach of where the hand would be
    assert session.set_joint_target(0, "right_wrist", want[[0, 2]], want[1]) == 50  # 1 s from frame 30
    for _ in range(10):
        session.tick()
    # A second one, half a second ahead: the first one stays.
    want2 = natural[50, left] + (-0.1, 0.15, 0.0)
    assert session.set_joint_target(0, left, want2[[0, 2]], want2[1], seconds=0.5) == 50
    targets = session.snapshot().joint_targets[0]
    assert targets.shape == (2, 5) and targets[:, 1].tolist() == [left, right]
    assert session.stats(0).targets_left == 2
    for _ in range(15):
        session.tick()
    joints = session.clip(0).joints
    assert np.linalg.norm(joints[50, right] - want) < 0.01
    assert np.linalg.norm(joints[50, left] - want2) < 0.01
    stats = session.stats(0)
    assert stats.targets_left == 0 and stats.control.startswith("2 targets: mean error")
    assert len(session.snapshot().joint_targets[0]) == 2  # met, still drawn for a second
    for _ in range(25):
        session.tick()
    assert len(session.snapshot().joint_targets[0]) == 0

    # Cleared before its frame: not met, the head goes its own way.
    up = joints[-1, 0] + (0.0, 1.0, 0.3)
    frame = session.set_joint_target(0, "head", up[[0, 2]], up[1], seconds=1.0)
    session.clear_joint_targets(0)
    assert len(session.snapshot().joint_targets[0]) == 0
    for _ in range(25):
        session.tick()
    assert np.linalg.norm(session.clip(0).joints[frame, head] - up) > 0.3
    assert session.stats(0).control.startswith("2 targets")

    # A head limit: the head stays under it once it has eased in.
    session.set_head_limit(0, 1.4)
    for _ in range(40):
        session.tick()
    assert session.clip(0).joints[-25:, head, 1].max() <= 1.4 + 1e-3 < natural[:, head, 1].max()
    assert session.stats(0).head_limit == 1.4
    session.set_head_limit(0, None)
    assert session.stats(0).head_limit is None


def test_bad_joint_targets_are_refused_with_a_reason(generator) -> None:
    session = StudioSession(generator, ["a person walks"], seed=0)
    cases = [
        (
            lambda: session.set_joint_target(0, "right_wrist", (1.0, 1.0), 3.0),
            "height must be from 0 to 2.5 m",
        ),
        (
            lambda: session.set_joint_target(0, "right_wrist", (1.0, 1.0), -0.1),
            "height must be from 0 to 2.5",
        ),
        (lambda: session.set_joint_target(0, "right_wrist", (1.0, 1.0), np.nan), "height must be"),
        (lambda: session.set_joint_target(0, "right_wrist", (1.0, 1.0), 1.0, 0.2), "time must be from 0.5"),
        (lambda: session.set_joint_target(0, "right_wirst", (1.0, 1.0), 1.0), "no joint 'right_wirst'"),
        (lambda: session.set_joint_target(0, "right_wrist", (99.0, 1.0), 1.0), "off the floor"),
        (lambda: session.set_head_limit(0, 0.2), "head's height limit must be from 0.6 to 2.5 m"),
    ]
    for call, message in cases:
        with pytest.raises(ValueError, match=message):
            call()
    with pytest.raises(IndexError, match="no character 2"):
        session.set_joint_target(2, "head", (0.0, 1.0), 1.5)
    assert len(session.snapshot().joint_targets[0]) == 0 and session.stats(0).head_limit is None
