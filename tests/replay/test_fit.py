"""Tests of motion_env.replay.fit: joint positions -> humanoid qpos."""

from __future__ import annotations

import mujoco
import numpy as np

from motion_env.motion.types import Motion
from motion_env.replay import evaluate, measure
from motion_env.replay.fit import clip_rest_directions, fit_qpos
from motion_env.replay.mjcf import load_model, model_index


def test_fit_reproduces_poses_of_the_model(forward_kinematics) -> None:
    """Random poses of the humanoid -> joint positions -> fit -> the same joint positions."""
    rng = np.random.default_rng(0)
    model = load_model()
    qpos = np.tile(model.qpos0, (12, 1))
    index = model_index(model)
    for adr in index.ball_qpos:
        axis_angle = rng.normal(scale=0.35, size=(12, 3))
        for t in range(12):
            mujoco.mju_axisAngle2Quat(qpos[t, adr : adr + 4], axis_angle[t], np.linalg.norm(axis_angle[t]))
    for t in range(12):
        mujoco.mju_axisAngle2Quat(qpos[t, 3:7], np.array([0.0, 0.0, 1.0]), rng.uniform(-3, 3))
    qpos[:, :3] += rng.normal(scale=0.5, size=(12, 3))
    joints = forward_kinematics(model, qpos)
    rest = clip_rest_directions(joints)
    fitted = load_model(rest_directions=rest)
    back = forward_kinematics(fitted, fit_qpos(joints, fitted, model_index(fitted), rest))
    np.testing.assert_allclose(back, joints, atol=1e-4)


def test_fit_error_is_small_on_a_real_clip(humanml3d_sample) -> None:
    joints, _ = humanml3d_sample
    motion = Motion(joints)
    m = measure(motion)
    assert m.fit_error.mean() < 0.01 and m.fit_error.max() < 0.03  # metres
    result = evaluate(motion)
    assert result["fit_error"]["mean_cm"] < 1.0
