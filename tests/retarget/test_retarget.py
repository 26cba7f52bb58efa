"""`motion_env.retarget`: the qpos layout, joint ranges, the floor, smoothness, the residuals."""

from __future__ import annotations

import numpy as np
import pytest

import motion_env
from motion_env.motion.types import Motion
from motion_env.retarget import IKSettings, RobotMotion, load_robot
from motion_env.retarget.limits import clip_to_limits, range_violations, soft_limited
from motion_env.retarget.quality import measure

ROBOTS = ("unitree_g1", "booster_t1")


@pytest.mark.parametrize("robot", ROBOTS)
def test_qpos_layout(robot: str, waving_clip) -> None:
    clip = waving_clip(frames=21)
    result = motion_env.retarget(clip, robot=robot, fps=50)
    model = load_robot(robot).model
    assert isinstance(result, RobotMotion) and result.robot == robot and result.fps == 50
    assert result.qpos.shape == (51, model.nq)  # 1 s at 20 fps -> 1 s at 50 fps
    assert np.isfinite(result.qpos).all()
    np.testing.assert_allclose(np.linalg.norm(result.root_rot, axis=1), 1.0, atol=1e-9)
    names = [model.joint(j).name for j in range(1, model.njnt)]
    assert list(result.joint_names) == names and result.dof_pos.shape[1] == len(names)
    # The robot faces +x (the human faces +Z) and stands upright, feet on the floor.
    assert np.abs(result.root_rot[:, 3]).max() < 0.1  # qz: no turn
    assert result.residuals.shape == (51, len(result.residual_names))
    assert {"left_wrist", "right_wrist", "left_ankle", "right_ankle"} <= set(result.residual_names)


def test_the_package_is_the_function(waving_clip) -> None:
    from motion_env.retarget import retarget

    clip = waving_clip(frames=8)
    a = motion_env.retarget(clip, fps=20)
    b = retarget(clip.joints, "unitree_g1", 20)  # a plain (T, 22, 3) array at 20 fps
    np.testing.assert_array_equal(a.qpos, b.qpos)


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_hand_follows_the_human(robot: str, waving_clip) -> None:
    clip = waving_clip(frames=40, raise_to=2.2)
    result = motion_env.retarget(clip, robot=robot, fps=20)
    numbers = measure(result, clip)
    assert numbers["range_violations"] == 0 and numbers["penetration_cm"] <= 1.5
    assert numbers["hand_corr"] > 0.9
    assert numbers["stand_float_cm"] <= 4.0
    wrist = result.residual_names.index("right_wrist")
    assert result.residuals[:, wrist].max() < 0.05


@pytest.mark.parametrize("robot", ROBOTS)
def test_out_of_reach_is_best_effort_within_limits(robot: str, waving_clip) -> None:
    """Hands far above the head and behind it, for a few frames: no joint leaves its range, the
    residual says how far the hands stayed from their targets."""
    clip = waving_clip(frames=20)
    joints = clip.joints.copy()
    for name in ("left_wrist", "right_wrist", "left_elbow", "right_elbow"):
        j = motion_env.skeleton.JOINT_INDEX[name]
        joints[6:11, j] = joints[6:11, 15] + np.array([0.0, 0.8, -0.8], np.float32)  # above, behind the head
    result = motion_env.retarget(Motion(joints), robot=robot, fps=20)
    assert range_violations(load_robot(robot).model, result.qpos) == 0
    wrist = result.residual_names.index("left_wrist")
    assert result.residuals[8, wrist] > 0.2  # out of reach, and reported
    assert result.residuals[0, wrist] < 0.05


@pytest.mark.slow
@pytest.mark.parametrize("robot", ROBOTS)
def test_real_walk_feet_on_the_floor(robot: str, real_walk: Motion) -> None:
    result = motion_env.retarget(real_walk, robot=robot, fps=50)
    numbers = measure(result, real_walk)
    assert numbers["range_violations"] == 0
    assert numbers["penetration_cm"] <= 1.5  # no sinking
    assert numbers["stand_float_cm"] <= 4.0  # no floating while the human stands
    assert numbers["max_jump_rad"] <= 0.35
    assert numbers["foot_corr"] >= 0.6 and numbers["hand_corr"] >= 0.8
    assert 0.5 <= numbers["distance_ratio"] <= 1.1
    ankles = [k for k, n in enumerate(result.residual_names) if n.endswith("ankle")]
    assert result.residuals[:, ankles].mean() < 0.04


def test_soft_limited_ranges_are_centred_shares() -> None:
    model = load_robot("unitree_g1").model
    soft = soft_limited(model, 0.9)
    hinges = np.flatnonzero(model.jnt_limited)
    mid, half = model.jnt_range[hinges].mean(1), np.diff(model.jnt_range[hinges], axis=1)[:, 0] / 2
    np.testing.assert_allclose(soft.jnt_range[hinges, 0], mid - 0.9 * half)
    np.testing.assert_allclose(soft.jnt_range[hinges, 1], mid + 0.9 * half)
    assert soft_limited(model, 1.0) is model
    # clip_to_limits clips hinges (numpy ints against mujoco's enum: compared as ints).
    qpos = np.tile(model.qpos0, (2, 1))
    qpos[:, model.jnt_qposadr[hinges]] = 10.0
    clipped = clip_to_limits(soft, qpos.copy())
    np.testing.assert_allclose(clipped[0, model.jnt_qposadr[hinges]], soft.jnt_range[hinges, 1])
    assert range_violations(model, qpos) == 2 * len(hinges) and range_violations(soft, clipped) == 0
    with pytest.raises(ValueError, match=r"soft_limit must be a share of the joint range in \(0, 1\]"):
        soft_limited(model, 1.5)


@pytest.mark.parametrize("robot", ROBOTS)
def test_joints_stay_inside_the_soft_range(robot: str, waving_clip) -> None:
    """An arm raised as far as it goes, hands out of reach: every joint stays inside 90 % of its
    range; asked for 80 %, inside 80 %."""
    clip = waving_clip(frames=30, raise_to=2.8)
    bot = load_robot(robot)
    for share in (0.9, 0.8):
        result = motion_env.retarget(clip, robot=robot, fps=20, soft_limit=share)
        assert measure(result, clip, soft_limit=share)["soft_range_violations"] == 0
        limited = np.flatnonzero(bot.model.jnt_limited)
        q = result.qpos[:, bot.model.jnt_qposadr[limited]]
        low, high = bot.model.jnt_range[limited].T
        share_used = np.abs(q - (low + high) / 2) / ((high - low) / 2)
        assert share_used.max() <= share + 1e-9
    with pytest.raises(ValueError, match="soft_limit must be a share"):
        motion_env.retarget(clip, robot=robot, soft_limit=0)


@pytest.mark.parametrize("robot", ROBOTS)
def test_arms_do_not_go_through_the_body(robot: str, crossing_clip) -> None:
    """Arms crossed over the chest: followed blindly, the forearms go through the torso (and the
    hands into the hips at rest); with the collision constraints, no geoms overlap."""
    clip = crossing_clip()
    blind = motion_env.retarget(clip, robot=robot, fps=20, ik=IKSettings(avoid_self_collision=False))
    assert measure(blind, clip)["self_collision_cm"] > 5.0
    kept = motion_env.retarget(clip, robot=robot, fps=20)
    numbers = measure(kept, clip)
    assert numbers["self_collision_cm"] < 0.5 and numbers["soft_range_violations"] == 0
