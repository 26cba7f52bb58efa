"""The path controller: shapes, streaming == rollout, waypoint queue, arrive gating, training, checkpoints."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.checkpoint import save_checkpoint
from motion_env.models.controller import (
    ControllerConfig,
    PathController,
    from_heading_frame_torch,
    to_heading_frame_torch,
)
from motion_env.motion.kinematics import from_heading_frame, to_heading_frame
from motion_env.training.controller import (
    CHECKPOINT_KIND,
    PathData,
    TrainSettings,
    evaluate_controller,
    fit,
    load_controller,
    sample_batch,
)

TINY = ControllerConfig(text_dim=16, text_proj=8, hidden=32, mlp=32)


def _tiny(seed: int = 0, scale: float = 0.3) -> PathController:
    """A tiny controller whose output layer is random (it starts at zero, i.e. standing still)."""
    torch.manual_seed(seed)
    model = PathController(TINY)
    for p in model.out[-1].parameters():
        torch.nn.init.normal_(p, std=scale)
    return model.eval()


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
    assert PathController(ControllerConfig()).num_parameters() > 900_000  # the real one: ~1 M


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


def _toy_data() -> PathData:
    """Straight walks in random directions at random speeds: the waypoints are on a line."""
    rng = np.random.default_rng(0)
    paths = []
    for _ in range(32):
        theta, speed = rng.uniform(-math.pi, math.pi), rng.uniform(0.8, 1.6)
        t = np.arange(80) / 20.0
        paths.append(
            np.stack([math.sin(theta) * speed * t, math.cos(theta) * speed * t, np.full(80, theta)], 1)
        )
    return PathData([p.astype(np.float32) for p in paths], [np.array([0])] * 32, rng.normal(size=(1, 16)))


def test_sample_batch_windows_come_from_the_clips() -> None:
    data = _toy_data()
    batch = sample_batch(data, np.random.default_rng(3), 16, 40)
    assert batch.target.shape == (16, 40, 3) and batch.text.shape == (16, 16)
    torch.testing.assert_close(batch.start, batch.target[:, 0])
    for wp, target in zip(batch.waypoints, batch.target, strict=True):
        if wp is None:
            continue
        timed = wp[~np.isnan(wp[:, 2])]
        inside = timed[timed[:, 2] < 40]
        np.testing.assert_allclose(inside[:, :2], target[inside[:, 2].astype(int), :2].numpy(), atol=1e-5)


def test_training_on_a_toy_reaches_waypoints(tmp_path: Path) -> None:
    data = _toy_data()
    torch.manual_seed(0)
    model = PathController(TINY)
    before = evaluate_controller(model, data, num_windows=32, window=60, snap=False)["root_error_cm"]
    t0 = time.monotonic()
    fit(model, data, TrainSettings(steps=25, batch_size=8, lr=8e-3, window=24, warmup=5), progress=False)
    elapsed = time.monotonic() - t0
    after = evaluate_controller(model, data, num_windows=32, window=60, snap=False)["root_error_cm"]
    assert after < 0.25 * before and after < 40.0, (before, after, elapsed)
    # Checkpoint round trip: the model is rebuilt from the file alone.
    path = save_checkpoint(tmp_path / "c.pt", kind=CHECKPOINT_KIND, config=model.config, model=model)
    loaded, _ = load_controller(path)
    emb = torch.as_tensor(data.embeddings[0], dtype=torch.float32)
    np.testing.assert_allclose(loaded.rollout(emb, [[0, 2, 30]], 40), model.rollout(emb, [[0, 2, 30]], 40))


def test_fit_is_deterministic_and_resumable() -> None:
    data = _toy_data()
    settings = TrainSettings(steps=4, batch_size=4, lr=3e-3, window=16, warmup=2)

    def fresh() -> PathController:
        torch.manual_seed(5)
        return PathController(TINY)

    straight = fresh()
    fit(straight, data, settings, progress=False)
    resumed = fresh()
    opt, done = fit(resumed, data, settings, progress=False, on_step=lambda step, parts: step == 2)
    assert done == 2
    _, done = fit(resumed, data, settings, optimizer=opt, start_step=2, progress=False)
    assert done == 4
    for a, b in zip(straight.state_dict().values(), resumed.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b)
