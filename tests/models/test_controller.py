"""The path controller: shapes, streaming == rollout, waypoint queue, arrive gating, training, checkpoints."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.waypoint_features import from_heading_frame_torch, to_heading_frame_torch
from motion_env.motion.kinematics import from_heading_frame, to_heading_frame

TINY = ControllerConfig(text_dim=16, text_proj=8, hidden=32, mlp=32)


def _tiny(seed: int = 0, scale: float = 0.3) -> PathController:
    torch.manual_seed(seed)
    return PathController.drifting(TINY, scale).eval()


def test_heading_frame_twins_match_motion() -> None:
    rng = np.random.default_rng(0)
    vec, theta = rng.normal(size=(5, 2)), rng.uniform(-4, 4, size=5)
    np.testing.assert_allclose(
        to_heading_frame_torch(torch.tensor(vec), torch.tensor(theta)).numpy(), to_heading_frame(vec, theta)
    )
    np.testing.assert_allclose(
        from_heading_frame_torch(torch.tensor(vec), torch.tensor(theta)).numpy(),
        from_heading_frame(vec, theta),
    )


def test_rollout_shapes_and_start() -> None:
    model = _tiny()
    emb = torch.randn(3, 16)
    starts = np.array([[0, 0, 0], [1, 2, 0.5], [-3, 1, -2.0]], np.float32)
    wps = [[[0, 2, 40], [2, 4, 100]], None, [[1, 1], [2, 2]]]
    out = model.rollout_batch(emb, wps, 50, starts)
    assert out.shape == (3, 50, 3) and out.dtype == np.float32 and np.isfinite(out).all()
    np.testing.assert_allclose(out[:, 0], starts)
    single = model.rollout(emb[1], None, 50, start=starts[1])
    np.testing.assert_allclose(single, out[1], atol=1e-5)
    assert model.num_parameters() > 0
    assert 350_000 < PathController(ControllerConfig()).num_parameters() < 450_000  # the shipped size


def test_streaming_equals_rollout_and_seeds() -> None:
    model = _tiny()
    emb = torch.randn(2, 16)
    wps = [[[0, 2, 30], [2, 4, 60]], [[1, 0], [1, 3]]]
    gen = torch.Generator().manual_seed(7)
    full = model.rollout_batch(emb, wps, 40, generator=gen)
    with torch.no_grad():
        state = model.init_state(emb, wps, generator=torch.Generator().manual_seed(7))
        frames = [state.root.numpy()]
        for _ in range(39):
            state = model.step(state)
            frames.append(state.root.numpy())
    np.testing.assert_allclose(np.stack(frames, 1), full, atol=1e-6)
    again = model.rollout_batch(emb, wps, 40, generator=torch.Generator().manual_seed(7))
    other = model.rollout_batch(emb, wps, 40, generator=torch.Generator().manual_seed(8))
    np.testing.assert_array_equal(again, full)
    assert np.abs(other - full).max() > 1e-4


def test_waypoint_queue_advances() -> None:
    model = _tiny(scale=0.0)  # stands still: only the queue logic moves
    wps = [[[0, 5, 3], [0, 6, 10], [0, 7, np.nan]], [[0, 0.1], [5, 5]]]
    with torch.no_grad():
        state = model.init_state(torch.zeros(2, 16), wps)
        # Character 1 starts within the arrive radius of its untimed first waypoint: skipped at once.
        assert state.queue.tolist() == [0, 1]
        for _ in range(3):
            state = model.step(state)
        assert state.queue.tolist() == [1, 1]  # frame 3 reached: the timed waypoint is passed
        for _ in range(20):
            state = model.step(state)
        assert state.queue.tolist() == [2, 1]  # the last waypoint is never dropped
        # New waypoints mid-rollout: timed ones already in the past are skipped.
        state = model.set_waypoints(state, [[1, 1, 5], [2, 2, 50], [3, 3, 80]], index=0)
        assert state.queue.tolist() == [1, 1] and state.count.tolist() == [3, 2]
        state = model.set_text(state, torch.ones(16), index=1)
        assert torch.equal(state.text[1], torch.ones(16)) and torch.equal(state.text[0], torch.zeros(16))
        state = model.set_waypoints(state, None, index=1)
        assert state.count.tolist() == [3, 0]
        state = model.step(state)


def test_streaming_with_changes_matches_the_same_changes_in_a_loop() -> None:
    model = _tiny(1)
    emb = torch.randn(1, 16)
    with torch.no_grad():
        a = model.init_state(emb, [[[0, 3, 40]]])
        b = model.init_state(emb, [[[0, 3, 40]]])
        for i in range(30):
            if i == 10:
                a = model.set_waypoints(a, [[3, 3, 50]])
                b = model.set_waypoints(b, [[3, 3, 50]], index=0)
            a, b = model.step(a), model.step(b)
        torch.testing.assert_close(a.root, b.root)
        c = model.init_state(emb, [[[0, 3, 40]]])
        for _ in range(30):
            c = model.step(c)
        assert (a.root - c.root).abs().max() > 1e-4  # the new route changed the path


def test_reset_character_restarts_one_of_a_batch() -> None:
    model = _tiny(3)
    emb = torch.randn(2, 16)
    wp = [[2, 2, 30]]
    with torch.no_grad():
        state = model.init_state(emb, [wp, None])
        for _ in range(12):
            state = model.step(state)
        before = state.root.clone()
        state = model.reset_character(state, 1, emb[0], wp, start=(1.0, -1.0, 0.5))
        torch.testing.assert_close(state.root[0], before[0])
        torch.testing.assert_close(state.root[1], torch.tensor([1.0, -1.0, 0.5]))
        assert state.frame.tolist() == [12, 0] and state.count.tolist() == [1, 1]
        fresh = model.init_state(emb[:1], [wp], np.array([[1.0, -1.0, 0.5]], np.float32))
        for _ in range(10):
            state, fresh = model.step(state), model.step(fresh)
        torch.testing.assert_close(state.root[1], fresh.root[0])
    with pytest.raises(IndexError):
        model.reset_character(state, 2, emb[0])


def test_arrive_gating_settles_on_the_last_waypoint() -> None:
    model = _tiny(2, scale=1.0)  # a wild random network
    target = np.array([[0.1, 0.15]], np.float32)
    out = model.rollout(torch.randn(16), target, 80, start=(0, 0, 0))
    assert np.linalg.norm(out[-1, :2] - target[0]) < 1e-3
    assert abs(out[-1, 2] - out[-10, 2]) < 1e-3  # no spinning on the spot


def test_bad_inputs_raise() -> None:
    model = _tiny()
    with pytest.raises(ValueError, match="text_emb"):
        model.init_state(torch.zeros(2, 15))
    with pytest.raises(ValueError, match="strictly increasing"):
        model.rollout(torch.zeros(16), [[0, 1, 10], [0, 2, 5]], 20)
    with pytest.raises(ValueError, match="NaN or infinite"):
        model.rollout(torch.zeros(16), [[0, np.nan]], 20)
    with pytest.raises(ValueError, match="start"):
        model.rollout(torch.zeros(16), None, 20, start=(0, np.inf, 0))
    with pytest.raises(ValueError, match="num_frames"):
        model.rollout(torch.zeros(16), None, 0)
    with pytest.raises(ValueError, match="2 characters"):
        model.init_state(torch.zeros(2, 16), [None])
    with pytest.raises(ValueError, match="arrive_radius"):
        ControllerConfig(arrive_radius=0)
