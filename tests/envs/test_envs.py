"""The Gymnasium environments: API conformance, route semantics, rewards, bad actions, vector env.

Most tests drive the envs with ``MotionGenerator.random`` (tiny untrained weights: the motion has no
meaning, but the shapes, the streaming and the determinism are real). The tests of walking quality
(arrival, smoothness) need the shipped model and skip when it is not installed.
"""

from __future__ import annotations

import os
import subprocess
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

os.environ.setdefault("HF_HUB_OFFLINE", "1")
torch.set_num_threads(1)


@pytest.fixture
def gen(random_generator):
    return random_generator


@pytest.fixture
def trained(pretrained_generator):
    return pretrained_generator


# Most tests here check the route semantics with world-point actions, one frame per step; the
# learning defaults (normalised actions, four frames) have their own tests in test_rl.py.
WORLD = {"action_mode": "absolute", "frames_per_step": 1}


def _make(gen, env_id="motion_env/Waypoints-v0", **kwargs):
    return gym.make(env_id, generator=gen, **{**WORLD, **kwargs})


# ----------------------------------------------------------------------------------------------
# Registration and API conformance
# ----------------------------------------------------------------------------------------------


def test_importing_registers_every_id_without_torch():
    code = (
        "import sys, gymnasium as gym, motion_env\n"
        "assert 'torch' not in sys.modules, 'registration imported torch'\n"
        f"assert all(i in gym.registry for i in {list(ENVIRONMENTS)!r})\n"
        "spec = gym.spec('motion_env/Waypoints-v0')\n"
        "assert spec.max_episode_steps and spec.vector_entry_point\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    motion_env.envs.registration.register_envs()  # idempotent


@pytest.mark.parametrize("env_id", list(ENVIRONMENTS))
def test_check_env_passes_for_every_registered_id(gen, env_id):
    env = _make(gen, env_id, render_mode="rgb_array", render_size=(96, 64))
    with warnings.catch_warnings():
        # Unbounded observations and metre-valued actions are deliberate (see the env docstrings).
        warnings.filterwarnings("ignore", message=".*(infinity|normalized space).*")
        check_env(env.unwrapped)
    env.close()


@pytest.mark.parametrize("env_id", list(ENVIRONMENTS))
def test_stable_baselines3_env_checker_passes(gen, env_id):
    sb3_checker = pytest.importorskip(
        "stable_baselines3.common.env_checker", reason="'rl' extra not installed"
    )
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*normalized Box action space.*")
        sb3_checker.check_env(_make(gen, env_id).unwrapped)  # includes the GoalEnv compute_reward checks


def test_observation_layout_and_info(gen):
    env = _make(gen, frames_per_step=3)
    obs, info = env.reset(seed=1, options={"text": "a person walks", "waypoints": [[0, 3], [2, 5]]})
    assert env.observation_space.contains(obs)
    flat = gym.wrappers.FlattenObservation(env)
    caption = gen.controller.config.text_proj
    assert flat.observation_space.shape == (4 + 2 + 6 + 3 + 3 + 66 + caption,)
    assert info["step_joints"].shape == (3, 22, 3)  # after reset: the first frame, three times
    assert (info["step_joints"] == info["joints"]).all()
    obs, reward, terminated, truncated, info = env.step(np.array([0.0, 3.0], np.float32))
    assert info["joints"].shape == (22, 3) and info["joints"].dtype == np.float32
    assert info["step_joints"].shape == (3, 22, 3)
    np.testing.assert_array_equal(info["joints"], info["step_joints"][-1])
    assert info["frame"] == 4  # one frame at reset, three per step
    pelvis = info["joints"][0]
    np.testing.assert_allclose(obs["root"][:2], pelvis[[0, 2]], atol=1e-5)
    np.testing.assert_allclose(np.hypot(obs["root"][2], obs["root"][3]), 1.0, atol=1e-5)
    pose = obs["pose"].reshape(22, 3)
    np.testing.assert_allclose(pose[0], [0.0, pelvis[1], 0.0], atol=1e-5)  # pelvis: origin, its height
    # Pose distances to the pelvis are preserved by the heading-frame rotation.
    world = info["joints"][:, [0, 2]] - pelvis[[0, 2]]
    np.testing.assert_allclose(
        np.linalg.norm(pose[:, [0, 2]], axis=1), np.linalg.norm(world, axis=1), atol=1e-5
    )
    # The target is the route target seen from the character.
    theta = np.arctan2(obs["root"][3], obs["root"][2])
    back = from_heading_frame(obs["target"], theta) + obs["root"][:2]
    np.testing.assert_allclose(back, info["route_target"], atol=1e-4)
    assert np.isclose(reward, sum(v for k, v in info.items() if k.startswith("reward_")))


def test_same_seed_and_options_give_the_same_poses(gen):
    options = {"text": "a person jogs", "waypoints": [[1, 2], [3, 3]]}

    def run(seed):
        env = _make(gen)
        obs, info = env.reset(seed=seed, options=options)
        frames = [info["joints"]]
        for t in range(12):
            obs, _, _, _, info = env.step(np.array([1.0, 2.0] if t < 6 else [-1.0, 0.5], np.float32))
            frames.append(info["joints"])
        return np.stack(frames)

    np.testing.assert_array_equal(run(3), run(3))
    assert not np.allclose(run(3), run(4))


def test_random_reset_draws_caption_route_and_start_from_the_seed(gen):
    env = _make(gen, text_pool=["a person walks", "a person runs"], random_start=True)
    _, a = env.reset(seed=7)
    route = env.unwrapped.route  # the whole route (K, 3); info has only its length
    _, b = env.reset(seed=7)
    np.testing.assert_array_equal(route, env.unwrapped.route)
    assert a["text"] in ("a person walks", "a person runs")
    assert a["text"] == b["text"] and a["route_length"] == len(route)
    env.reset(seed=8)
    assert not np.array_equal(route, env.unwrapped.route)
    assert 2 <= len(route) <= 4
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"goal": [1, 1]})
    with pytest.raises(ValueError, match="waypoints"):
        env.reset(options={"waypoints": [[0, np.nan]]})
    with pytest.raises(ValueError, match="start"):
        env.reset(options={"start": [0, 0]})


# ----------------------------------------------------------------------------------------------
# What an action does to the route
# ----------------------------------------------------------------------------------------------


def test_actions_follow_snap_or_detour(gen):
    route = np.array([[0.0, 3.0], [3.0, 5.0], [6.0, 5.0]], np.float32)
    env = _make(gen)
    obs, info = env.reset(seed=0, options={"text": "a person walks", "waypoints": route})
    assert info["following_route"] and info["route_index"] == 0

    # Issuing the route target keeps following the route.
    obs, _, _, _, info = env.step(info["route_target"])
    assert info["following_route"] and info["route_index"] == 0
    np.testing.assert_allclose(info["command"], route[0])

    # A point off the route is a detour: the command changes, the route target does not.
    obs, _, _, _, info = env.step(np.array([-2.0, 1.0], np.float32))
    assert not info["following_route"] and info["route_index"] == 0
    np.testing.assert_allclose(info["command"], [-2.0, 1.0])
    np.testing.assert_allclose(info["route_target"], route[0])

    # A later route waypoint resumes the route from there (the skipped one earns nothing).
    obs, _, _, _, info = env.step(route[2] + 0.01)
    assert info["following_route"] and info["route_index"] == 2
    assert info["reward_arrival"] == 0.0
    np.testing.assert_allclose(info["command"], route[2])

    # An earlier (already skipped) waypoint is just a point: a detour.
    obs, _, _, _, info = env.step(route[0])
    assert not info["following_route"] and info["route_index"] == 2


def test_relative_actions(gen):
    env = _make(gen, action_mode="relative")
    assert env.action_space.high[0] == 30.0
    obs, info = env.reset(seed=0, options={"waypoints": [[2.0, 4.0], [0.0, 8.0]]})
    # Echoing the observed target keeps following the route.
    obs, _, _, _, info = env.step(obs["target"])
    assert info["following_route"] and info["route_index"] == 0
    # One metre straight ahead of the pelvis, in world coordinates.
    theta = np.arctan2(obs["root"][3], obs["root"][2])
    expected = obs["root"][:2] + from_heading_frame(np.array([0.0, 1.0]), theta)
    obs, _, _, _, info = env.step(np.array([0.0, 1.0], np.float32))
    assert not info["following_route"]
    np.testing.assert_allclose(info["command"], expected, atol=1e-4)


def test_route_waypoints_are_passed_and_the_last_one_terminates(gen):
    # The first two waypoints lie where the character stands: passed at once, with a bonus each.
    route = [[0.0, 0.0], [0.05, 0.0], [0.0, 6.0]]
    env = _make(gen, arrival_bonus=2.0)
    _, info = env.reset(seed=0, options={"waypoints": route})
    assert info["route_index"] == 2
    _, reward, terminated, _, info = env.step(info["route_target"])
    assert not terminated and info["route_index"] == 2

    env.unwrapped.set_route([[0.0, 0.1]])
    _, reward, terminated, _, info = env.step(info["route_target"])
    assert terminated and info["is_success"] and info["reward_arrival"] == 2.0

    env = _make(gen, terminate_on_arrival=False)
    env.reset(seed=0, options={"waypoints": [[0.0, 0.0]]})
    _, _, terminated, _, info = env.step(np.array([0.0, 0.0], np.float32))
    assert not terminated and info["is_success"]


def test_progress_reward_is_the_distance_gained(gen):
    env = _make(gen, progress_weight=2.0)
    obs, info = env.reset(seed=5, options={"waypoints": [[4.0, 4.0], [8.0, 8.0]]})
    for _ in range(8):
        before = info["distance"]
        obs, reward, _, _, info = env.step(np.array([-3.0, 0.0], np.float32))
        assert info["route_index"] == 0
        assert np.isclose(info["reward_progress"], 2.0 * (before - info["distance"]), atol=1e-5)
        assert np.isclose(info["reward_time"], -0.1 / 20)  # the time cost: 0.1 per second
        assert np.isclose(reward, sum(v for k, v in info.items() if k.startswith("reward_")))


def test_collision_term_when_the_pelvis_is_inside_an_obstacle(gen):
    env = _make(gen, obstacles=[[0.0, 0.0, 2.0]], collision_penalty=0.5)
    env.reset(seed=0, options={"waypoints": [[5.0, 5.0]]})
    _, _, _, _, info = env.step(np.array([5.0, 5.0], np.float32))
    assert info["reward_collision"] == -0.5
    with pytest.raises(ValueError, match="obstacles"):
        _make(gen, obstacles=[[0.0, 0.0, -1.0]])


# ----------------------------------------------------------------------------------------------
# Bad input
# ----------------------------------------------------------------------------------------------


def test_bad_actions_are_clipped_or_rejected_and_the_episode_goes_on(gen):
    env = _make(gen)
    _, info = env.reset(seed=0)
    for bad in ([np.nan, 1.0], [np.inf, 0.0], [1.0, -np.inf]):
        with pytest.raises(ValueError, match="NaN or infinite"):
            env.step(np.array(bad, np.float32))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(3, np.float32))
    assert env.unwrapped._batch.stream.frame_index[0] == 1  # nothing was emitted
    _, _, _, _, info = env.step(np.array([1e9, -1e9], np.float32))
    assert info["action_clipped"] and info["frame"] == 2
    np.testing.assert_allclose(info["command"], [10.0, -10.0])

    env = _make(gen, invalid_action="hold")
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([2.0, 2.0], np.float32))
    _, reward, _, _, info = env.step(np.array([np.nan, np.nan], np.float32))
    assert info["action_invalid"] and np.isfinite(reward)
    np.testing.assert_allclose(info["command"], [2.0, 2.0])
    with pytest.raises(ValueError, match="invalid_action"):
        _make(gen, invalid_action="ignore")
    with pytest.raises(ValueError, match="frames_per_step"):
        _make(gen, frames_per_step=0)


# ----------------------------------------------------------------------------------------------
# Mid-episode edits, rendering, memory
# ----------------------------------------------------------------------------------------------


def test_set_text_mid_episode(gen):
    env = _make(gen)
    env.reset(seed=0, options={"text": "a person walks"})
    env.step(np.array([1.0, 1.0], np.float32))
    env.unwrapped.set_text("a person waves")
    _, _, _, _, info = env.step(np.array([1.0, 1.0], np.float32))
    assert info["text"] == "a person waves" and env.unwrapped._batch.stream.texts == ["a person waves"]
    with pytest.raises(ValueError, match="text"):
        env.unwrapped.set_text("")


def test_render_rgb_array(gen):
    env = _make(gen, render_mode="rgb_array", render_size=(160, 120), obstacles=[[1.0, 2.0, 0.5]])
    env.reset(seed=0)
    env.step(np.array([1.0, 1.0], np.float32))
    image = env.render()
    assert image.shape == (120, 160, 3) and image.dtype == np.uint8
    assert image.std() > 5  # a picture, not a blank frame


def test_render_mujoco_humanoid(gen):
    env = _make(gen, render_mode="rgb_array", render_style="humanoid", render_size=(128, 96))
    env.reset(seed=0)
    env.step(np.array([1.0, 1.0], np.float32))
    try:
        image = env.render()
    except RuntimeError as exc:
        pytest.skip(f"no offscreen OpenGL here: {exc}")
    assert image.shape == (96, 128, 3) and image.dtype == np.uint8 and image.std() > 5
    env.close()
    with pytest.raises(ValueError, match="render_style"):
        _make(gen, render_style="photo")


def _rss_mib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def test_long_episode_keeps_memory_flat(gen):
    env = _make(gen, terminate_on_arrival=False, max_episode_steps=12_000)
    _, info = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for t in range(10_000):
        action = rng.uniform(-5, 5, 2).astype(np.float32) if t % 100 == 50 else info["command"]
        _, _, _, truncated, info = env.step(action)
        if t == 500:
            base = _rss_mib()
    assert not truncated and info["frame"] == 10_001
    assert len(env.unwrapped._batch.trails[0]) <= env.unwrapped.config.trail_length
    assert _rss_mib() - base < 10.0


# ----------------------------------------------------------------------------------------------
# GoalReach-v0
# ----------------------------------------------------------------------------------------------


def test_goal_reach_compute_reward_works_on_batches(gen):
    env = _make(gen, "motion_env/GoalReach-v0")
    obs, info = env.reset(seed=0, options={"goal": [2.0, 3.0]})
    np.testing.assert_allclose(obs["desired_goal"], [2.0, 3.0])
    obs, reward, _, _, info = env.step(obs["desired_goal"])
    assert reward == env.unwrapped.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == -1.0
    achieved = np.array([[0.0, 0.0], [2.0, 3.2], [5.0, 5.0]], np.float32)
    desired = np.tile(np.float32([2.0, 3.0]), (3, 1))
    np.testing.assert_array_equal(
        env.unwrapped.compute_reward(achieved, desired, [info] * 3), [-1.0, 0.0, -1.0]
    )
    assert env.unwrapped.compute_reward(achieved, achieved, None).tolist() == [0.0, 0.0, 0.0]  # hindsight
    dense = _make(gen, "motion_env/GoalReach-v0", reward_type="dense").unwrapped
    np.testing.assert_allclose(
        dense.compute_reward(achieved, desired, None), [-np.hypot(2, 3), -0.2, -np.hypot(3, 2)], rtol=1e-5
    )
    _, info = env.reset(seed=4)
    assert 1.5 <= np.linalg.norm(env.unwrapped.goal) <= 4.0 + 1e-5


# ----------------------------------------------------------------------------------------------
# The batched vector env
# ----------------------------------------------------------------------------------------------


def test_vector_env_runs_n_characters_in_one_stream(gen):
    envs = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=3, vectorization_mode="vector_entry_point", generator=gen, **WORLD
    )
    assert envs.unwrapped._batch.stream is None
    obs, infos = envs.reset(seed=0)
    assert envs.unwrapped._batch.stream.batch_size == 3
    assert envs.observation_space.contains(obs) and infos["joints"].shape == (3, 22, 3)
    obs, reward, terminated, truncated, infos = envs.step(infos["route_target"])
    assert reward.shape == terminated.shape == truncated.shape == (3,)
    assert infos["step_joints"].shape == (3, 1, 22, 3) and infos["_joints"].all()
    with pytest.raises(ValueError, match="shape"):
        envs.step(np.zeros((2, 2), np.float32))
    envs.close()


def test_vector_env_autoresets_on_the_next_step(gen):
    envs = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point", generator=gen,
        max_episode_steps=3, **WORLD,
    )  # fmt: skip
    # A route that ends where the characters stand: they terminate on the first step.
    obs, infos = envs.reset(seed=0, options={"waypoints": [[0.0, 0.0]]})
    _, reward, terminated, truncated, infos = envs.step(np.zeros((2, 2), np.float32))
    assert terminated.all() and not truncated.any()
    _, reward, terminated, truncated, infos = envs.step(np.zeros((2, 2), np.float32))
    assert not terminated.any() and (reward == 0).all() and (infos["frame"] == 1).all()

    # Truncation at max_episode_steps, then a fresh episode.
    obs, infos = envs.reset(seed=1)
    for _ in range(3):
        _, _, terminated, truncated, infos = envs.step(infos["route_target"])
    assert truncated.all() and not terminated.any()
    _, _, terminated, truncated, infos = envs.step(infos["route_target"])
    assert not truncated.any() and (infos["frame"] == 1).all()


def test_vector_env_is_deterministic_given_the_seed(gen):
    def run():
        envs = gym.make_vec("motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point",
                            generator=gen, **WORLD)  # fmt: skip
        _, infos = envs.reset(seed=11)
        frames = []
        for _ in range(6):
            _, _, _, _, infos = envs.step(infos["route_target"])
            frames.append(infos["joints"])
        return np.stack(frames)

    np.testing.assert_array_equal(run(), run())


# ----------------------------------------------------------------------------------------------
# With the shipped model: the walking itself
# ----------------------------------------------------------------------------------------------


ROUTE = np.array([[0.0, 2.5], [2.0, 4.5], [4.0, 4.0]], np.float32)


def _walk_route(generator, seed: int, edits: bool) -> tuple[np.ndarray, bool]:
    """Issue ROUTE's waypoints as actions (policies.WaypointPolicy) until the episode ends.

    With `edits`, the caption changes at step 30 and the agent makes a 20-step detour ahead-left
    of the route at step 50, then goes back to issuing the route. Returns (joints, terminated).
    """
    from policies import WaypointPolicy

    env = gym.make("motion_env/Waypoints-v0", generator=generator, max_episode_steps=800, **WORLD)
    obs, info = env.reset(seed=seed, options={"text": "a person walks forward", "waypoints": ROUTE})
    policy = WaypointPolicy(ROUTE)
    frames = [info["joints"]]
    terminated = truncated = False
    while not (terminated or truncated):
        step = len(frames) - 1
        if edits and step == 30:
            env.unwrapped.set_text("a person walks slowly")
        detour = edits and 50 <= step < 70
        action = np.array([0.5, 5.0], np.float32) if detour else policy.act(obs)
        obs, _, terminated, truncated, info = env.step(action)
        frames.append(info["joints"])
    return np.stack(frames), terminated


@pytest.mark.slow
@pytest.mark.parametrize("edits", [False, True], ids=["route", "route-with-caption-and-path-edits"])
def test_issuing_the_route_reaches_its_end_without_pops(trained, edits):
    joints, terminated = _walk_route(trained, seed=0, edits=edits)
    assert terminated, f"did not reach the last waypoint in {len(joints)} frames"
    assert np.linalg.norm(joints[-1, 0, [0, 2]] - ROUTE[-1]) < 0.75
    steps = np.linalg.norm(np.diff(joints, axis=0), axis=-1)  # (T-1, 22)
    frame, joint = np.unravel_index(steps.argmax(), steps.shape)
    assert steps.max() <= 0.35, f"joint {joint} moved {steps.max():.2f} m from frame {frame} to {frame + 1}"


def test_info_carries_the_caption_warning(gen) -> None:
    """info["caption_warning"]: a str, '' for an ordinary caption; the warning itself comes once."""
    env = gym.make("motion_env/Waypoints-v0", generator=gen)
    _, info = env.reset(seed=0, options={"text": "a person walks"})
    assert info["caption_warning"] == ""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, info = env.reset(seed=0, options={"text": "una persona camina"})
        for _ in range(3):
            *_, info = env.step(env.action_space.sample())
        env.reset(seed=1, options={"text": "una persona camina"})
    assert "Spanish" in info["caption_warning"]
    assert sum("una persona camina" in str(w.message) for w in caught) == 1
    envs = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point", generator=gen
    )
    with pytest.warns(UserWarning, match="not in the Latin script"):
        _, infos = envs.reset(seed=0, options={"text": "一个人在走路"})
    assert infos["caption_warning"].shape == (2,) and all("Latin" in w for w in infos["caption_warning"])


def test_lookahead_argument_selects_the_streams_look_ahead(gen):
    from motion_env.models.lookahead import LookaheadConfig, LookaheadHead

    c = gen.pipeline.controller.config
    with pytest.raises(ValueError, match="lookahead"):
        _make(gen, lookahead="fast")
    with pytest.raises(ValueError, match="lookahead must be 'exact' or 'head'"):
        _make(gen, lookahead="head").reset(seed=0)  # these weights have no head
    gen.pipeline.lookahead = LookaheadHead(LookaheadConfig.for_controller(c, width=8, layers=1))
    try:
        modes = {}
        for mode in ("auto", "head", "exact"):
            env = _make(gen, lookahead=mode, frames_per_step=1, follow_action=False)
            env.reset(seed=0)
            modes[mode] = env.unwrapped._batch.stream.lookahead
            env.step(np.array([0.5, 0.5], np.float32))  # a new target: the head predicts the second ahead
            env.close()
        assert modes == {"auto": "head", "head": "head", "exact": "exact"}
    finally:
        gen.pipeline.lookahead = None
