"""The environments' ``robot=`` option: ``info["robot_qpos"]``, the emitted frame on a robot."""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import pytest

import motion_env  # noqa: F401  (registers the environments)

pytest.importorskip("mink", reason="the optional 'robots' extra (mink) is not installed")
os.environ.setdefault("HF_HUB_OFFLINE", "1")


def test_waypoints_env_emits_robot_qpos_every_step(random_generator) -> None:
    from motion_env.retarget import StreamRetargeter, load_robot
    from motion_env.retarget.limits import range_violations

    nq = load_robot("unitree_g1").model.nq
    env = gym.make(
        "motion_env/Waypoints-v0", generator=random_generator, robot="unitree_g1",
        action_mode="absolute", frames_per_step=1,
    )  # fmt: skip
    _, info = env.reset(seed=0, options={"text": "a person walks", "waypoints": [[0, 3]]})
    frames = [info["joints"]]
    qpos = [info["robot_qpos"]]
    for _ in range(5):
        *_, info = env.step(info["route_target"])
        frames.append(info["joints"])
        qpos.append(info["robot_qpos"])
    qpos = np.stack(qpos)
    assert qpos.shape == (6, nq) and qpos.dtype == np.float32 and np.isfinite(qpos).all()
    assert range_violations(load_robot("unitree_g1").model, qpos.astype(np.float64), 1e-5) == 0
    # The same as streaming the emitted frames through the retargeter by hand.
    rt = StreamRetargeter("unitree_g1")
    expected = np.stack([rt.step(np.asarray(f, np.float64)[None])[0] for f in frames])
    np.testing.assert_allclose(qpos, expected, atol=1e-4)
    # A new episode starts the retargeter over: same first frame, same robot pose.
    _, again = env.reset(seed=0, options={"text": "a person walks", "waypoints": [[0, 3]]})
    np.testing.assert_array_equal(again["robot_qpos"], qpos[0])
    env.close()

    plain = gym.make("motion_env/Waypoints-v0", generator=random_generator)
    assert "robot_qpos" not in plain.reset(seed=0)[1]
    with pytest.raises(ValueError, match="unknown robot"):
        gym.make("motion_env/Waypoints-v0", generator=random_generator, robot="no_such_robot")


def test_vector_env_emits_robot_qpos_per_character(random_generator) -> None:
    envs = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point",
        generator=random_generator, robot="unitree_g1", action_mode="absolute",
    )  # fmt: skip
    _, infos = envs.reset(seed=0)
    nq = infos["robot_qpos"].shape[1]
    assert infos["robot_qpos"].shape == (2, nq) and infos["robot_qpos"].dtype == np.float32
    for _ in range(3):
        *_, infos = envs.step(infos["route_target"])
        assert infos["robot_qpos"].shape == (2, nq) and np.isfinite(infos["robot_qpos"]).all()
    envs.close()
