"""run_episode: every frame of an episode, its return and its end, for a given and a random agent."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from motion_env.evaluation.episode import run_episode

ROUTE = {"text": "a person walks", "waypoints": [[0.0, 2.0], [1.0, 4.0]]}


def _env(gen, steps: int = 6, frames_per_step: int = 2) -> gym.Env:
    return gym.make(
        "motion_env/Waypoints-v0", generator=gen, max_episode_steps=steps, frames_per_step=frames_per_step
    )


def test_an_episode_keeps_every_frame_and_sums_the_rewards(random_generator) -> None:
    env = _env(random_generator)
    ahead = np.array([0.0, 1.0, 1.0], np.float32)  # straight ahead, following the route
    seen = []
    episode = run_episode(env, lambda obs: seen.append(obs) or ahead, seed=3, options=ROUTE)
    # The same episode stepped by hand: the reset frame, then each step's frames.
    _, info = env.reset(seed=3, options=ROUTE)
    frames, rewards = [info["joints"][None]], []
    for _ in seen:
        _, reward, terminated, truncated, info = env.step(ahead)
        frames.append(info["step_joints"])
        rewards.append(reward)
    assert terminated or truncated
    assert len(seen) == 6 or terminated  # the time limit, unless the route was done first
    assert episode.joints.shape == (1 + len(seen) * 2, 22, 3)
    np.testing.assert_array_equal(episode.joints, np.concatenate(frames))
    assert np.isclose(episode.total_return, sum(rewards))
    assert episode.terminated == terminated and episode.info["is_success"] == info["is_success"]


def test_the_random_agent_is_seeded_by_the_episode_seed(random_generator) -> None:
    env = _env(random_generator, steps=4)
    first = run_episode(env, None, seed=5, options=ROUTE)
    again = run_episode(env, None, seed=5, options=ROUTE)  # the same actions, not the next ones
    other = run_episode(env, None, seed=6, options=ROUTE)
    np.testing.assert_array_equal(first.joints, again.joints)
    assert first.total_return == again.total_return
    assert not np.array_equal(first.joints, other.joints)
