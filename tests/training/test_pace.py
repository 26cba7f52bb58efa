"""Fitting the pace regressor: ridge regression, clip speeds, the checkpoint the generator loads."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from motion_env.models.checkpoint import load_checkpoint
from motion_env.models.pace import PaceConfig, PaceRegressor
from motion_env.text.encoders import TextEncoder
from motion_env.training.pace import PaceTrainConfig, clip_speed, fit_hidden, fit_ridge, train_pace


def test_fit_ridge_recovers_a_linear_map() -> None:
    rng = np.random.default_rng(0)
    x = rng.normal(size=(200, 5))
    w, b = fit_ridge(x, x @ [1.0, -2.0, 0.0, 0.5, 3.0] + 1.5, alpha=1e-6)
    np.testing.assert_allclose(w, [1.0, -2.0, 0.0, 0.5, 3.0], atol=1e-6)
    assert b == pytest.approx(1.5)


def test_fit_hidden_fits_an_interaction_a_linear_map_cannot() -> None:
    # Like a style that slows runs far more than walks: y depends on the product of two inputs.
    rng = np.random.default_rng(0)
    x = rng.integers(0, 2, size=(400, 2)).astype(np.float32)
    y = 1.0 + 2.0 * x[:, 0] - 1.5 * x[:, 0] * x[:, 1]
    w, b = fit_ridge(x, y, alpha=1e-6)
    linear_error = np.abs(x @ w + b - y).mean()
    model = fit_hidden(x, y, hidden=16, seed=0)
    assert model.config.hidden == 16
    assert np.abs(model.pace(x) - y).mean() < 0.5 * linear_error, linear_error


def test_clip_speed_is_path_length_over_duration() -> None:
    joints = np.zeros((21, 22, 3), np.float32)
    joints[:, 0, 2] = np.arange(21) * 0.1  # 10 cm a frame at 20 fps
    assert clip_speed(joints) == pytest.approx(2.0)


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="captions_per_clip"):
        PaceTrainConfig(captions_per_clip=0)
    with pytest.raises(ValueError, match="alpha"):
        PaceTrainConfig(alpha=-1.0)
    with pytest.raises(ValueError, match="hidden"):
        PaceTrainConfig(hidden=-1)


def test_train_pace_writes_a_checkpoint_the_generator_can_load(
    tiny_dataset: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    out = tmp_path / "pace.pt"
    metrics = train_pace(tiny_dataset, out, PaceTrainConfig(captions_per_clip=2, progress=False), hash_text())
    assert metrics["train_captions"] > 0 and metrics["mae_none"] >= 0
    model, ckpt = load_checkpoint(out, "pace", PaceConfig, PaceRegressor)
    assert model.config.text_dim == 8 and ckpt["text_encoder"] == {"name": "hash", "dim": 8}
    assert np.isfinite(model.pace(np.zeros((1, 8)))).all()
    settings = PaceTrainConfig(captions_per_clip=2, hidden=4, progress=False)
    hidden = train_pace(tiny_dataset, tmp_path / "h.pt", settings, hash_text())
    assert np.isfinite(hidden["mae_none"])
    model, _ = load_checkpoint(tmp_path / "h.pt", "pace", PaceConfig, PaceRegressor)
    assert model.config.hidden == 4 and np.isfinite(model.pace(np.zeros((1, 8)))).all()
    with pytest.raises(FileNotFoundError, match="no dataset"):
        train_pace(tmp_path / "nowhere", out, PaceTrainConfig(), hash_text())
