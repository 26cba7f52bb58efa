"""Tests of motion_env.replay.robot: the replay's checks on a robot's qpos (evaluate_robot).

Every corrupted trajectory is built from the robot's own keyframe, on the two robots of
``../shared/robots`` (skipped, with the reason, when the folder is absent).
"""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from motion_env.replay import format_report
from motion_env.replay.plausibility import load_thresholds, thresholds_path
from motion_env.replay.robot import (
    ROBOT_CHECKS,
    SHARED_CHECKS,
    evaluate_robot,
    load_robot_thresholds,
)
from motion_env.replay.robot_kinematic import GeomPoints, collision_geoms, find_feet, measure_robot

FPS = 50
# Per robot: a joint pushed past its upper bound (rad), and an arm driven into the torso (joint
# values inside their ranges).
CASES = {
    "unitree_g1": {
        "feet": ("left_ankle_roll_link", "right_ankle_roll_link"),
        "beyond": ("left_elbow_joint", 0.3),
        "into_torso": {"left_shoulder_roll_joint": -0.45},
        "torso": "torso_link",
    },
    "booster_t1": {
        "feet": ("left_foot_link", "right_foot_link"),
        "beyond": ("Left_Elbow_Yaw", 0.3),
        "into_torso": {"Left_Elbow_Pitch": 1.0, "Left_Elbow_Yaw": -2.0},
        "torso": "Trunk",
    },
}
_MODELS: dict[str, mujoco.MjModel] = {}


@pytest.fixture(params=sorted(CASES))
def robot(request, require_robot) -> tuple[str, mujoco.MjModel]:
    """(name, compiled model) of each robot, compiled once per session."""
    name = request.param
    path = require_robot(name)
    if name not in _MODELS:
        _MODELS[name] = mujoco.MjModel.from_xml_path(str(path))
    return name, _MODELS[name]


def _stand(model: mujoco.MjModel, seconds: float = 1.5) -> np.ndarray:
    """The robot's first keyframe held still, (T, nq) at FPS."""
    return np.repeat(model.key_qpos[:1], round(seconds * FPS), axis=0)


def _joint(model: mujoco.MjModel, name: str) -> int:
    return int(mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name))


def test_standing_in_the_keyframe_is_plausible(robot) -> None:
    name, model = robot
    result = evaluate_robot(_stand(model), model, FPS)
    assert result["plausible"] is True and result["judged"] is True, result["summary"]
    checks = result["checks"]
    assert set(checks) == set(ROBOT_CHECKS)
    assert checks["penetration"]["value"] < 0.005  # the keyframe's feet touch the floor
    assert (
        checks["root_force"]["value"] < 0.1 and checks["root_torque"]["value"] < 0.1
    )  # the floor carries it
    assert checks["joint_limits"]["value"] == 0.0 and checks["self_collision"]["value"] == 0.0
    assert result["feet"] == list(CASES[name]["feet"])
    assert result["mass_kg"] == pytest.approx(float(model.body_subtreemass[1]))


def test_qpos0_put_on_the_floor_is_plausible(robot) -> None:
    _, model = robot
    qpos = np.repeat(model.qpos0[None], FPS, axis=0)
    qpos[:, 2] -= measure_robot(qpos[:3], model, FPS).lowest[0]  # lower the root onto the floor
    result = evaluate_robot(qpos, model, FPS)
    assert result["plausible"] is True, result["summary"]


def test_sunk_and_raised_are_caught(robot) -> None:
    _, model = robot
    stand = _stand(model)
    depth = evaluate_robot(stand, model, FPS)["checks"]["penetration"]["value"]
    sunk = stand.copy()
    sunk[:, 2] -= 0.10
    result = evaluate_robot(sunk, model, FPS)
    assert result["failed"] == ["penetration"]
    assert result["checks"]["penetration"]["value"] == pytest.approx(0.10 + depth, abs=1e-3)
    raised = stand.copy()
    raised[:, 2] += 0.30
    result = evaluate_robot(raised, model, FPS)
    assert result["failed"] == ["floating", "root_force"]
    assert result["checks"]["floating"]["value"] == pytest.approx(len(raised) / FPS)
    assert result["checks"]["root_force"]["value"] == pytest.approx(9.81, abs=0.01)  # nothing holds it up


def test_a_joint_beyond_its_range_is_caught(robot) -> None:
    name, model = robot
    joint, extra = CASES[name]["beyond"]
    j = _joint(model, joint)
    qpos = _stand(model)
    qpos[20:30, model.jnt_qposadr[j]] = model.jnt_range[j, 1] + extra
    result = evaluate_robot(qpos, model, FPS)
    assert result["failed"] == ["joint_limits"]
    check = result["checks"]["joint_limits"]
    assert check["value"] == pytest.approx(np.rad2deg(extra)) and check["frames"] == [[20, 29]]
    assert joint.replace("_", " ") in check["message"] and "10 joint-frames" in check["message"]
    # Within a rounding of the bound (float32 storage) is no violation.
    qpos[20:30, model.jnt_qposadr[j]] = np.float32(model.jnt_range[j, 1])
    assert evaluate_robot(qpos, model, FPS)["plausible"] is True


def test_an_arm_driven_into_the_torso_is_caught(robot) -> None:
    name, model = robot
    qpos = _stand(model)
    for joint, value in CASES[name]["into_torso"].items():
        j = _joint(model, joint)
        assert model.jnt_range[j, 0] <= value <= model.jnt_range[j, 1]  # a legal pose, yet a collision
        qpos[:, model.jnt_qposadr[j]] = value
    m, result = evaluate_robot(qpos, model, FPS, measurements=True)
    assert result["failed"] == ["self_collision"]
    assert result["checks"]["self_collision"]["value"] > 0.04
    assert CASES[name]["torso"] in m.self_pair[0]
    assert CASES[name]["torso"].replace("_", " ") in result["checks"]["self_collision"]["message"]


def test_a_root_sliding_with_frozen_legs_skates(robot) -> None:
    _, model = robot
    qpos = _stand(model, 2.5)
    moving = np.clip((np.arange(len(qpos)) / FPS - 0.5) / 1.0, 0.0, 1.0)  # 1.5 m from 0.5 s to 1.5 s
    qpos[:, 0] += 1.5 * moving
    result = evaluate_robot(qpos, model, FPS)
    assert result["failed"][0] == "foot_skating"
    assert result["checks"]["foot_skating"]["value"] == pytest.approx(1.5, abs=0.1)
    # Friction (coefficient 1, as for the humanoid) can start and stop the slide (3.9 N/kg at
    # most, within the root force's threshold today): the slide is the skating check's to catch.
    assert set(result["failed"]) <= {"foot_skating", "root_force", "root_torque"}


def test_report_frames_are_the_clip_s_frames_and_rates_agree(robot) -> None:
    _, model = robot
    raised = _stand(model, 3.0)
    raised[50:100, 2] += 0.30  # 1 s in the air, at 50 fps
    result = evaluate_robot(raised, model, FPS)
    assert result["checks"]["floating"]["frames"] == [[50, 99]]
    assert result["failed"] == ["floating", "root_force"]  # jumps up and down, held up between
    # Skating and the root force are judged at 20 fps (the calibration's rate) whatever the rate.
    slide = _stand(model, 2.5)
    slide[:, 0] += 1.5 * np.clip((np.arange(len(slide)) / FPS - 0.5) / 1.0, 0.0, 1.0)
    at_50 = evaluate_robot(slide, model, FPS)["checks"]
    slow = np.repeat(model.key_qpos[:1], 50, axis=0)  # the same slide at 20 fps
    slow[:, 0] += 1.5 * np.clip((np.arange(50) / 20 - 0.5) / 1.0, 0.0, 1.0)
    at_20 = evaluate_robot(slow, model, 20)["checks"]
    for name in ("foot_skating", "root_force", "root_torque"):
        assert at_50[name]["value"] == pytest.approx(at_20[name]["value"], rel=0.05, abs=0.05), name


def test_too_short_clips_are_not_judged(robot) -> None:
    _, model = robot
    short = evaluate_robot(_stand(model, 0.98), model, FPS)  # 49 frames at 50 fps
    assert short["judged"] is False and short["plausible"] is None and short["min_frames"] == FPS
    assert short["summary"] == f"too short to judge: 49 frames, at least {FPS} needed (1.0 s)"
    assert "CANNOT BE JUDGED" in format_report(short)
    assert evaluate_robot(_stand(model, 1.0), model, FPS)["judged"] is True
    slow = evaluate_robot(np.repeat(model.key_qpos[:1], 20, axis=0), model, 20)
    assert slow["judged"] is True and slow["plausible"] is True


def test_report_is_json_in_the_shape_of_the_humanoid_s(robot, require_robot) -> None:
    name, model = robot
    raised = _stand(model)
    raised[:, 2] += 0.30
    result = evaluate_robot(raised, str(require_robot(name)), FPS)  # a path works too
    json.dumps(result)
    for check in result["checks"].values():
        assert set(check) == {"value", "threshold", "unit", "passed", "frames", "worst_frame", "message"}
    assert result["checks"]["floating"]["frames"] == [[0, len(raised) - 1]]
    text = format_report(result, title=name)
    assert "NOT PLAUSIBLE" in text and f"robot {result['robot']}" in text and "fit:" not in text


def test_lowest_point_agrees_with_mujoco(robot) -> None:
    _, model = robot
    data = mujoco.MjData(model)
    data.qpos[:] = model.key_qpos[0]
    data.qpos[2] = 0.4
    data.qpos[3:7] = [np.cos(0.5), 0.2, np.sin(0.5), 0.0]
    data.qpos[3:7] /= np.linalg.norm(data.qpos[3:7])
    mujoco.mj_forward(model, data)
    geoms = collision_geoms(model)
    shapes = GeomPoints(model, geoms)
    ours = shapes.lowest_per_geom(shapes.bottoms(data))
    floor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    theirs = [mujoco.mj_geomDistance(model, data, int(g), floor, 10.0, None) for g in geoms]
    np.testing.assert_allclose(ours, theirs, atol=1e-3)


def test_thresholds_shared_with_the_humanoid_and_the_robot_s_own() -> None:
    human = load_thresholds()
    default = load_robot_thresholds()
    assert set(default) == set(ROBOT_CHECKS)
    assert all(default[c] == human[c] for c in SHARED_CHECKS)
    assert default["joint_limits"] < 0.1 and 0 < default["self_collision"] <= 0.05
    changed = load_robot_thresholds({"self_collision": 0.1, "speed": 1.0})
    assert changed["self_collision"] == 0.1 and "speed" not in changed
    # A humanoid calibration file gives the shared checks only: its joint range is a human one.
    assert load_robot_thresholds(thresholds_path())["joint_limits"] == default["joint_limits"]
    with pytest.raises(ValueError, match="root_force"):
        load_robot_thresholds({"root_force": "high"})


def test_bad_inputs_are_named(robot, tmp_path) -> None:
    _, model = robot
    stand = _stand(model, 1.0)
    with pytest.raises(ValueError, match=r"shape \(T, "):
        evaluate_robot(stand[:, :-1], model, FPS)
    broken = stand.copy()
    broken[7, 9] = np.nan
    with pytest.raises(ValueError, match=r"frames \[7\]"):
        evaluate_robot(broken, model, FPS)
    tilted = stand.copy()
    tilted[3, 3:7] = [2.0, 0, 0, 0]
    with pytest.raises(ValueError, match="quaternion"):
        evaluate_robot(tilted, model, FPS)
    with pytest.raises(ValueError, match="fps"):
        evaluate_robot(stand, model, 0)
    with pytest.raises(FileNotFoundError):
        evaluate_robot(stand, tmp_path / "none.xml", FPS)
    with pytest.raises(ValueError, match="feet"):
        evaluate_robot(stand, model, FPS, feet=("left_hand", "right_hand"))


TOY_LEG = """
      <body name="{side}_leg" pos="0 {y} -0.1">
        <joint name="{s}_hip" axis="0 1 0" range="-1 1"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.04" mass="2"/>
        <body name="{s}_foot" pos="0 0 -0.48">
          <joint name="{s}_ankle" axis="0 1 0" range="-0.5 0.5"/>
          <geom type="box" size="0.1 0.05 0.02" pos="0.03 0 -0.02" mass="0.5"/>
        </body>
      </body>"""
# A toy biped whose feet are named only by pattern (L_leg/l_foot, R_leg/r_foot).
LEGS = TOY_LEG.format(side="L", s="l", y=0.1) + TOY_LEG.format(side="R", s="r", y=-0.1)
TOY = f"""
<mujoco model="toy biped">
  <worldbody>
    <geom name="floor" type="plane" size="0 0 0.05"/>
    <body name="base" pos="0 0 0.62">
      <freejoint/>
      <geom type="box" size="0.1 0.15 0.1" mass="10"/>{LEGS}
    </body>
  </worldbody>
</mujoco>
"""


def test_any_robot_with_feet_named_by_pattern() -> None:
    model = mujoco.MjModel.from_xml_string(TOY)
    assert [model.body(b).name for b in find_feet(model)] == ["l_foot", "r_foot"]
    qpos = np.repeat(model.qpos0[None], FPS, axis=0)
    result = evaluate_robot(qpos, model, FPS)
    assert result["plausible"] is True, result["summary"]
    qpos[:, 0] += np.linspace(0, 1.0, FPS)
    assert "foot_skating" in evaluate_robot(qpos, model, FPS)["failed"]
    with pytest.raises(ValueError, match="free root"):
        evaluate_robot(
            np.zeros((FPS, 1)), mujoco.MjModel.from_xml_string(TOY.replace("<freejoint/>", "")), FPS
        )
