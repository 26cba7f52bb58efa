"""The shipped robots: folders, mapping tables, the guessed mapping of an MJCF without a table."""

from __future__ import annotations

import filecmp
import json
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest

from motion_env.retarget import known_robots, load_robot
from motion_env.retarget.guess import guess_table
from motion_env.retarget.robot import ROBOTS_DIR, TABLE_NAME
from motion_env.retarget.table import describe_table, read_table

ROBOTS = {"unitree_g1": ("g1.xml", 36), "booster_t1": ("t1.xml", 30)}


def test_known_robots() -> None:
    assert set(known_robots()) == set(ROBOTS)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_robot_folder_is_complete(name: str) -> None:
    folder = ROBOTS_DIR / name
    body, _ = ROBOTS[name]
    for file in ("LICENSE", "README.md", "scene.xml", body, TABLE_NAME):
        assert (folder / file).is_file(), file
    assert "41ee089" in (folder / "README.md").read_text()  # provenance
    # Every mesh the body XML names is shipped (and nothing else).
    used = {mesh.file for mesh in mujoco.MjSpec.from_file(str(folder / "scene.xml")).meshes}
    shipped = {p.name for p in (folder / "assets").iterdir()}
    assert used == shipped


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_table_loads_and_fits_the_model(name: str) -> None:
    table = read_table(ROBOTS_DIR / name / TABLE_NAME)
    robot = load_robot(name)
    assert robot.model.nq == ROBOTS[name][1] and robot.table == table
    assert robot.root_qpos == 0 and len(robot.joint_names) == robot.model.nq - 7
    tracked = {t.human for t in robot.tasks if t.position_cost > 0}
    assert {"left_hip", "right_hip", "left_ankle", "right_ankle", "left_wrist", "right_wrist"} <= tracked
    assert {t.orientation for t in robot.tasks} >= {"pelvis", "torso", "left_foot", "right_foot"}
    assert robot.foot_geoms.geoms.size > 0
    # The robot stands in its rest pose: legs below the hips, the feet the lowest part.
    assert robot.rest_points["left_ankle"][2] < robot.rest_points["left_hip"][2] - 0.4
    assert robot.rest_points["left_ankle"][1] > 0 > robot.rest_points["right_ankle"][1]  # left is +y


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_shipped_models_match_the_originals(name: str, require_robot) -> None:
    original, shipped = require_robot(name).parent, ROBOTS_DIR / name
    body, _ = ROBOTS[name]
    files = ["LICENSE", "scene.xml", body, *(f"assets/{p.name}" for p in (original / "assets").iterdir())]
    _, mismatch, errors = filecmp.cmpfiles(original, shipped, files, shallow=False)
    assert not mismatch and not errors


def test_guess_from_body_names_on_the_g1_body() -> None:
    path = ROBOTS_DIR / "unitree_g1" / "g1.xml"
    with pytest.warns(UserWarning, match="from its body names: left_hip -> left_hip_pitch_link") as seen:
        table = guess_table(mujoco.MjModel.from_xml_path(str(path)), path)
    assert len(seen) == 1  # both arms and hands found: only the mapping is said
    frames = {t.human: t.frame for t in table.tasks if t.human}
    assert frames["left_hip"] == "left_hip_pitch_link" and frames["right_knee"] == "right_knee_link"
    assert frames["left_ankle"] == "left_ankle_pitch_link" and frames["right_wrist"].startswith("right_wrist")
    assert table.root == "pelvis"
    assert table.feet == {"left": "left_ankle_roll_link", "right": "right_ankle_roll_link"}
    orient = {t.orientation: t.frame for t in table.tasks if t.orientation}
    assert orient["pelvis"] == "pelvis" and orient["torso"] == "torso_link"


def test_guess_on_the_t1_finds_legs_without_arms_and_says_so() -> None:
    path = ROBOTS_DIR / "booster_t1" / "t1.xml"
    with pytest.warns(UserWarning) as seen:
        table = guess_table(mujoco.MjModel.from_xml_path(str(path)), path)
    messages = [str(w.message) for w in seen]
    assert any("no left arm" in m and "the left arm is not tracked" in m for m in messages)
    assert any("no right arm" in m for m in messages)
    assert any("left_knee -> Shank_Left" in m for m in messages)
    frames = {t.human: t.frame for t in table.tasks if t.human}
    # Its arm links are AL1..AL3 and AR1..AR3: no name says "shoulder".
    assert frames == {
        "left_hip": "Hip_Pitch_Left", "left_knee": "Shank_Left", "left_ankle": "Ankle_Cross_Left",
        "right_hip": "Hip_Pitch_Right", "right_knee": "Shank_Right", "right_ankle": "Ankle_Cross_Right",
    }  # fmt: skip
    assert table.root == "Trunk" and {t.frame for t in table.tasks if t.orientation == "pelvis"} == {"Waist"}


def test_guess_without_a_hand_tracks_the_arm(tmp_path: Path) -> None:
    spec = mujoco.MjSpec.from_file(str(ROBOTS_DIR / "unitree_g1" / "g1.xml"))
    spec.delete(spec.body("left_wrist_roll_link"))  # the left hand and its wrist links
    with pytest.warns(UserWarning) as seen:
        table = guess_table(spec.compile(), tmp_path / "g1_one_hand.xml")
    said = [str(w.message) for w in seen]
    assert any("no left hand" in m and "the left hand is not tracked, the arm is" in m for m in said)
    assert any("left_elbow -> left_elbow_link, right_hip" in m for m in said)
    mapped = {t.human for t in table.tasks if t.human}
    assert {"left_shoulder", "left_elbow", "right_wrist"} <= mapped and "left_wrist" not in mapped
    assert "not tracked: left_wrist (left arm)" in describe_table(table)


def test_describe_table_names_every_task() -> None:
    text = describe_table(load_robot("booster_t1").table)
    assert text.startswith("robot booster_t1: ") and "root body Trunk" in text
    assert "site BODY_25:LWrist" in text and "<- left_wrist position (cost 5)" in text
    assert "body Waist" in text and "<- pelvis orientation (cost 2)" in text
    assert "not tracked" not in text


def test_retarget_onto_an_mjcf_without_a_table(waving_clip) -> None:
    """The G1's body XML alone (no floor, no table): the guessed mapping tracks legs and arms."""
    import motion_env
    from motion_env.retarget.quality import measure

    clip = waving_clip(frames=20)
    with warnings.catch_warnings():  # the guessed mapping is said (once per process)
        warnings.simplefilter("ignore")
        result = motion_env.retarget(clip, robot=ROBOTS_DIR / "unitree_g1" / "g1.xml", fps=20)
    assert result.qpos.shape == (20, 36) and result.robot.endswith("g1.xml")
    numbers = measure(result, clip)
    assert numbers["range_violations"] == 0 and numbers["penetration_cm"] <= 1.5
    assert numbers["hand_corr"] > 0.9


def test_a_table_is_data(tmp_path: Path) -> None:
    """A third robot is a table: here the G1 with its hands only on the wrists' bodies."""
    raw = json.loads((ROBOTS_DIR / "unitree_g1" / TABLE_NAME).read_text())
    raw["robot"], raw["model"] = "g1_variant", str(ROBOTS_DIR / "unitree_g1" / "scene.xml")
    for task in raw["tasks"]:
        if task.get("human", "").endswith("wrist"):
            task.update(type="body", frame=task["human"].replace("wrist", "wrist_yaw_link"))
    path = tmp_path / "g1_variant.json"
    path.write_text(json.dumps(raw))
    robot = load_robot(path)
    assert robot.name == "g1_variant" and robot.key == str(path.resolve())
    assert np.isfinite(robot.rest_points["left_wrist"]).all()


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_kinematics_lowest_point_is_exact(name: str) -> None:
    """The lowest point of all collision geoms equals a pass over every geom's hull, also when a
    knee or a hand is lower than the feet (the robot turned over, sunk into the floor)."""
    robot = load_robot(name)
    rng = np.random.default_rng(0)
    qpos = np.tile(robot.home, (12, 1))
    limited = robot.model.jnt_limited.astype(bool)
    low, high = robot.model.jnt_range[limited].T
    qpos[:, robot.model.jnt_qposadr[limited]] = rng.uniform(low, high, (12, limited.sum()))
    qpos[::3, 3:7] = (0.0, 1.0, 0.0, 0.0)  # upside down: the head is lowest
    data = mujoco.MjData(robot.model)
    geoms = robot.body_geoms.geoms
    xpos, xmat = np.empty((12, geoms.size, 3)), np.empty((12, geoms.size, 9))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(robot.model, data)
        xpos[t], xmat[t] = data.geom_xpos[geoms], data.geom_xmat[geoms]
    exact = robot.body_geoms.lowest(xpos, xmat).min(axis=1)
    np.testing.assert_allclose(robot.kinematics(qpos).lowest, exact, atol=1e-12)
