"""The environments as RL libraries use them: every vectorisation mode, the learning defaults
(normalised actions with a follow switch, four frames per step, the time cost), same-step
autoreset and stable-baselines3 on the native vector env (:func:`motion_env.make_sb3_env`)."""

from __future__ import annotations

import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

import motion_env
from motion_env.envs.registration import ENVIRONMENTS
from motion_env.motion.kinematics import from_heading_frame

torch.set_num_threads(1)
MODES = ("sync", "async", "vector_entry_point")


@pytest.fixture
def gen(random_generator):
    return random_generator


@pytest.mark.parametrize("env_id", list(ENVIRONMENTS))
def test_check_env_is_silent_with_the_defaults(gen, env_id):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any checker warning fails the test
        check_env(gym.make(env_id, generator=gen).unwrapped)


@pytest.mark.parametrize("env_id", list(ENVIRONMENTS))
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("frames_per_step", [1, 3])
def test_every_vectorisation_mode_runs_across_autoresets(gen, env_id, mode, frames_per_step):
    envs = gym.make_vec(
        env_id, num_envs=2, vectorization_mode=mode, generator=gen, frames_per_step=frames_per_step,
        max_episode_steps=3,
    )  # fmt: skip
    obs, infos = envs.reset(seed=0)
    assert envs.observation_space.contains(obs)
    assert infos["step_joints"].shape == (2, frames_per_step, 22, 3)
    envs.action_space.seed(0)
    ends = 0
    for _ in range(8):  # two autoresets at least (episodes of three steps)
        obs, reward, terminated, truncated, infos = envs.step(envs.action_space.sample())
        ends += int((terminated | truncated).sum())
        assert envs.observation_space.contains(obs) and reward.shape == (2,)
        assert infos["step_joints"].shape == (2, frames_per_step, 22, 3)
        assert infos["route_length"].shape == (2,) and infos["joints"].shape == (2, 22, 3)
    assert ends >= 2
    envs.close()


def test_same_step_autoreset_returns_the_new_episode_and_the_final_one(gen):
    envs = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=3, vectorization_mode="vector_entry_point", generator=gen,
        max_episode_steps=2, autoreset_mode="same_step",
    )  # fmt: skip
    _, infos = envs.reset(seed=0)
    actions = np.zeros((3, 3), np.float32)
    _, _, _, _, infos = envs.step(actions)
    assert "final_obs" not in infos
    obs, reward, terminated, truncated, infos = envs.step(actions)
    assert truncated.all() and infos["_final_obs"].all()
    # The returned observation starts the new episode; the final one is the old episode's last.
    assert (infos["frame"] == 1).all()
    assert all(info["frame"] == 1 + 2 * 4 for info in infos["final_info"])
    assert all(envs.single_observation_space.contains(o) for o in infos["final_obs"])
    first = infos["step_joints"][:, 0]
    assert (infos["step_joints"] == first[:, None]).all()  # a fresh start: its first frame F times
    _, _, terminated, truncated, infos = envs.step(actions)
    assert not (terminated | truncated).any() and "final_obs" not in infos
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec("motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     generator=gen, autoreset_mode="disabled")  # fmt: skip


def test_normalised_actions_steer_in_the_characters_frame_and_can_follow_the_route(gen):
    env = gym.make("motion_env/Waypoints-v0", generator=gen, reach=2.0)
    assert env.action_space.shape == (3,) and (env.action_space.high == 1).all()
    obs, info = env.reset(seed=0, options={"waypoints": [[0.0, 4.0], [3.0, 6.0]]})
    assert info["following_route"]
    obs, _, _, _, info = env.step(np.array([0.5, 1.0, -1.0], np.float32))  # follow <= 0: a detour
    assert not info["following_route"]
    theta = np.arctan2(obs["root"][3], obs["root"][2])
    # The command was set from the pose before the step: 2 m x (0.5, 1.0) in the heading frame.
    assert np.linalg.norm(info["command"] - obs["root"][:2]) < 2.0 * np.hypot(0.5, 1.0) + 0.5
    _, _, _, _, info = env.step(np.array([0.0, 0.0, 0.3], np.float32))  # follow > 0: the route
    assert info["following_route"] and np.allclose(info["command"], info["route_target"])
    np.testing.assert_allclose(from_heading_frame(obs["target"], theta) + obs["root"][:2],
                               [0.0, 4.0], atol=1e-4)  # fmt: skip
    steer = gym.make("motion_env/Waypoints-v0", generator=gen, follow_action=False)
    assert steer.action_space.shape == (2,)


def test_observation_shows_the_route_ahead_its_state_and_the_caption(gen):
    env = gym.make("motion_env/Waypoints-v0", generator=gen)
    route = [[0.0, 3.0], [2.0, 5.0], [4.0, 5.0]]
    obs, _ = env.reset(seed=0, options={"text": "a person jogs", "waypoints": route})
    theta = np.arctan2(obs["root"][3], obs["root"][2])
    ahead = from_heading_frame(obs["route_ahead"].reshape(3, 2), theta) + obs["root"][:2]
    np.testing.assert_allclose(ahead, [[2.0, 5.0], [4.0, 5.0], [4.0, 5.0]], atol=1e-4)  # last repeated
    np.testing.assert_allclose(obs["route_state"], [1.0, 0.0, 2 / 3], atol=1e-6)
    caption = env.unwrapped._batch.stream.caption_features()[0]
    np.testing.assert_allclose(obs["caption"], caption, atol=1e-6)
    env.unwrapped.set_text("a person walks slowly")
    assert not np.allclose(env.unwrapped._observation()["caption"], caption)


def test_stepping_after_termination_warns_and_pays_nothing(gen):
    env = gym.make("motion_env/Waypoints-v0", generator=gen).unwrapped  # no checker wrappers
    env.reset(seed=0, options={"waypoints": [[0.0, 0.0]]})  # ends where it starts
    _, reward, terminated, _, _ = env.step(np.zeros(3, np.float32))
    assert terminated
    with pytest.warns(UserWarning, match="after the episode terminated"):
        _, reward, terminated, _, info = env.step(np.zeros(3, np.float32))
    assert reward == 0.0 and terminated
    assert all(v == 0.0 for k, v in info.items() if k.startswith("reward_"))


# ----------------------------------------------------------------------------------------------
# stable-baselines3 on the native vector env
# ----------------------------------------------------------------------------------------------


def test_make_sb3_env_follows_sb3s_vecenv_contract(gen):
    sb3 = pytest.importorskip("stable_baselines3", reason="the optional 'rl' extra is not installed")
    from stable_baselines3.common.vec_env import VecCheckNan, VecEnv

    env = motion_env.make_sb3_env("motion_env/Waypoints-v0", num_envs=3, generator=gen, max_episode_steps=2)
    assert isinstance(env, VecEnv) and env.num_envs == 3
    env.seed(5)
    obs = env.reset()
    assert {k: v.shape[0] for k, v in obs.items()} == dict.fromkeys(obs, 3)
    checked = VecCheckNan(env, raise_exception=True)
    for t in range(4):
        obs, reward, dones, infos = checked.step(np.stack([env.action_space.sample() for _ in range(3)]))
        assert reward.dtype == np.float32 and dones.shape == (3,) and len(infos) == 3
        if t % 2 == 1:  # every second step ends every episode (max_episode_steps=2)
            assert dones.all()
            for info in infos:
                assert info["TimeLimit.truncated"] and env.observation_space.contains(
                    info["terminal_observation"]
                )
            assert (obs["route_state"][:, 0] == 1).all()  # the new episodes follow their routes
    assert env.env_method("set_text", "a person jogs", indices=[1]) == [None]
    assert env.get_attr("num_envs") == [3, 3, 3] and env.env_is_wrapped(gym.Wrapper) == [False] * 3
    model = sb3.PPO("MultiInputPolicy", env, n_steps=8, batch_size=12, n_epochs=1, device="cpu")
    model.learn(total_timesteps=24)
    env.close()


def test_sac_with_her_runs_on_the_goal_reach_vector_env(gen):
    sb3 = pytest.importorskip("stable_baselines3", reason="the optional 'rl' extra is not installed")
    env = motion_env.make_sb3_env("motion_env/GoalReach-v0", num_envs=2, generator=gen, max_episode_steps=3)
    model = sb3.SAC(
        "MultiInputPolicy", env, replay_buffer_class=sb3.HerReplayBuffer, learning_starts=8, batch_size=8,
        device="cpu",
    )  # fmt: skip
    model.learn(total_timesteps=16)  # HER relabels through env_method("compute_reward", ...)
    achieved, desired = np.zeros((5, 2)), np.ones((5, 2))
    (reward,) = env.env_method("compute_reward", achieved, desired, None, indices=[0])
    assert reward.shape == (5,)
    env.close()


def test_make_sb3_env_rejects_bad_arguments_and_names_a_missing_sb3(gen, monkeypatch):
    with pytest.raises(ValueError, match="num_envs must be an int >= 1"):
        motion_env.make_sb3_env("motion_env/Waypoints-v0", num_envs=0, generator=gen)
    with pytest.raises(ValueError, match="motion_env id"):
        motion_env.make_sb3_env("CartPole-v1", num_envs=2)
    with pytest.raises(ValueError, match="autoreset_mode"):
        motion_env.make_sb3_env("motion_env/Waypoints-v0", 2, generator=gen, autoreset_mode="next_step")
    from motion_env.envs import sb3 as adapter

    monkeypatch.setattr(adapter, "_CLASS", None)
    monkeypatch.setitem(sys.modules, "stable_baselines3.common.vec_env", None)  # "not installed"
    with pytest.raises(ImportError, match=r'pip install "motion-env\[rl\]"'):
        motion_env.make_sb3_env("motion_env/Waypoints-v0", num_envs=2, generator=gen)


def test_gymnasiums_record_video_works_with_the_rl_extra(gen, tmp_path):
    pytest.importorskip("moviepy", reason="the optional 'rl' extra (moviepy) is not installed")
    env = gym.make("motion_env/Waypoints-v0", generator=gen, render_mode="rgb_array", render_size=(96, 64),
                   max_episode_steps=3)  # fmt: skip
    env = gym.wrappers.RecordVideo(env, str(tmp_path), episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        *_, terminated, truncated, _ = env.step(env.action_space.sample())
        done = terminated or truncated
    env.close()
    videos = list(tmp_path.glob("*.mp4"))
    assert len(videos) == 1 and videos[0].stat().st_size > 0


def test_learning_curves_script_trains_evaluates_and_plots(tmp_path):
    pytest.importorskip("stable_baselines3", reason="the optional 'rl' extra is not installed")
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "scripts" / "learning_curves.py"
    spec = importlib.util.spec_from_file_location("learning_curves", path)
    script = importlib.util.module_from_spec(spec)
    sys.modules["learning_curves"] = script  # dataclasses look their module up there
    spec.loader.exec_module(script)
    args = script.Args(
        name="smoke", random_model=True, num_envs=2, timesteps=16, eval_episodes=2, out=str(tmp_path),
        env_kwargs="max_episode_steps=2", algo_kwargs="n_steps=8,batch_size=16,n_epochs=1",
    )  # fmt: skip
    result = script.main(args)
    assert result["episodes"] and all(steps <= 16 for steps, _ in result["episodes"])
    assert 0.0 <= result["eval_success"] <= 1.0 and result["algo_kwargs"]["n_steps"] == "8"
    assert script.main(script.Args(plot=True, out=str(tmp_path))).is_file()
    with pytest.raises(ValueError, match="name=value"):
        script.parse_env_kwargs("frames_per_step")


def test_joint_targets_and_height_limits_reach_the_env_stream(gen):
    from motion_env.motion.skeleton import JOINT_INDEX
    from motion_env.objectives import HeightLimit, KeepOut

    env = gym.make("motion_env/Waypoints-v0", generator=gen, frames_per_step=1).unwrapped
    _, info = env.reset(seed=0, options={"waypoints": [[0.0, 3.0]]})
    targets = np.full((30, 22, 3), np.nan, np.float32)
    wrist = JOINT_INDEX["right_wrist"]
    targets[15, wrist] = info["joints"][0] + np.array([0.3, 0.4, 0.2], np.float32)  # frame 16
    env.set_joint_targets(targets)
    env.set_objectives([HeightLimit(joint="head", max_height=1.2, frames=(30, 60))])
    for _ in range(16):
        _, _, _, _, info = env.step(np.array([0.0, 0.0, 1.0], np.float32))
    assert info["frame"] == 17  # frame 16 was the last one emitted
    np.testing.assert_allclose(info["joints"][wrist], targets[15, wrist], atol=0.01)
    for _ in range(20):
        _, _, _, _, info = env.step(np.array([0.0, 0.0, 1.0], np.float32))
    assert info["joints"][JOINT_INDEX["head"], 1] <= 1.2 + 1e-3
    assert "cm" in env.control_summary()
    with pytest.raises(ValueError, match="HeightLimit"):
        env.set_objectives([KeepOut(center=(0.0, 1.0), radius=0.3)])
    envs = gym.make_vec("motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        generator=gen)  # fmt: skip
    envs.reset(seed=0)
    envs.unwrapped.set_joint_targets(targets, index=1)
    with pytest.raises(IndexError):
        envs.unwrapped.set_objectives([], index=2)
