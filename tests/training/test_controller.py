"""The path-controller trainer on a tiny dataset: a few steps, the checkpoint, exact resuming."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.checkpoint import read_checkpoint, save_checkpoint
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.text.encoders import TextEncoder
from motion_env.training.controller import (
    CHECKPOINT_KIND,
    ControllerTrainConfig,
    PathData,
    evaluate_controller,
    fit,
    load_controller,
    sample_batch,
    train_controller,
)

TINY = ControllerConfig(text_dim=8, text_proj=8, hidden=32, mlp=32)
# A toy controller for the fitting tests: 16-d text, as the toy data below.
TOY = ControllerConfig(text_dim=16, text_proj=8, hidden=32, mlp=32)


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


def _config(**changes: object) -> ControllerTrainConfig:
    base = dict(steps=4, batch_size=4, window=24, warmup=2, eval_windows=8, save_every=2, progress=False)
    return ControllerTrainConfig(**{**base, **changes})


def test_train_controller_checkpoints_and_evaluates(
    tiny_dataset: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    out = tmp_path / "controller.pt"
    m = train_controller(tiny_dataset, out, _config(eval_every=2), TINY, hash_text())
    assert m["step"] == 4 and m["root_error_cm"] > 0 and "untimed_root_error_cm" in m
    model, ckpt = load_controller(out)
    assert model.config == TINY and ckpt["step"] == 4 and ckpt["metrics"] == m
    assert ckpt["settings"] == _config(eval_every=2, encoder="hash").to_dict()
    assert ckpt["text_encoder"] == {"name": "hash", "dim": 8}
    with pytest.raises(ValueError, match="trained with text encoder 'hash'"):
        train_controller(tiny_dataset, out, _config(steps=5), TINY, hash_text("other"))
    wider = ControllerConfig(text_dim=8, text_proj=8, hidden=16, mlp=32)
    with pytest.raises(ValueError, match="cannot resume"):
        train_controller(tiny_dataset, out, _config(steps=5), wider, hash_text())


def test_a_resumed_run_matches_an_uninterrupted_one(
    tiny_dataset: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    straight = tmp_path / "straight.pt"
    train_controller(tiny_dataset, straight, _config(), TINY, hash_text())
    # max_minutes=0 stops after the first step, with a checkpoint; the rest resumes from it.
    cut = tmp_path / "cut.pt"
    assert train_controller(tiny_dataset, cut, _config(max_minutes=0), TINY, hash_text())["step"] == 1
    assert read_checkpoint(cut, "controller")["step"] == 1
    # No model config given: a resumed run takes the checkpoint's.
    assert train_controller(tiny_dataset, cut, _config(), None, hash_text())["step"] == 4
    a, b = read_checkpoint(straight)["model"], read_checkpoint(cut)["model"]
    for name in a:
        torch.testing.assert_close(a[name], b[name], rtol=0, atol=0)


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
    model = PathController(TOY)
    before = evaluate_controller(model, data, num_windows=32, window=60, snap=False)["root_error_cm"]
    t0 = time.monotonic()
    fit(
        model,
        data,
        ControllerTrainConfig(steps=25, batch_size=8, lr=8e-3, window=24, warmup=5),
        progress=False,
    )
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
    settings = ControllerTrainConfig(steps=4, batch_size=4, lr=3e-3, window=16, warmup=2)

    def fresh() -> PathController:
        torch.manual_seed(5)
        return PathController(TOY)

    straight = fresh()
    fit(straight, data, settings, progress=False)
    resumed = fresh()
    opt, done = fit(resumed, data, settings, progress=False, on_step=lambda step, parts: step == 2)
    assert done == 2
    _, done = fit(resumed, data, settings, optimizer=opt, start_step=2, progress=False)
    assert done == 4
    for a, b in zip(straight.state_dict().values(), resumed.state_dict().values(), strict=True):
        torch.testing.assert_close(a, b)


def test_untimed_waypoints_are_spaced_by_distance_whatever_the_pace() -> None:
    from motion_env.training.controller import UNTIMED_SPACING, sample_waypoints

    rng = np.random.default_rng(0)
    for speed in (0.8, 3.0):  # m/s: a walk and a run, 20 s straight ahead
        t = np.arange(400, dtype=np.float32) / 20.0
        path = np.stack([np.zeros_like(t), t * speed, np.zeros_like(t)], axis=1)
        wp, frames = sample_waypoints(path, 0, 80, "untimed", rng, untimed_by="distance")
        assert np.isnan(wp[:, 2]).all() and (np.diff(frames) > 0).all()
        gaps = np.linalg.norm(np.diff(wp[:, :2], axis=0), axis=1)
        lo, hi = UNTIMED_SPACING
        assert ((gaps > lo - 0.2) & (gaps < hi + 0.2)).all(), gaps
        _, by_time = sample_waypoints(path, 0, 80, "untimed", rng)  # the default, as shipped
        assert ((np.diff(by_time) >= 20) & (np.diff(by_time) <= 60)).all()
    with pytest.raises(ValueError, match="untimed_by"):
        ControllerTrainConfig(untimed_by="space")
