"""The path-controller trainer on a tiny dataset: a few steps, the checkpoint, exact resuming."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from motion_env.models.checkpoint import read_checkpoint
from motion_env.models.controller import ControllerConfig
from motion_env.text.encoders import TextEncoder
from motion_env.training.controller import ControllerTrainConfig, load_controller, train_controller

TINY = ControllerConfig(text_dim=8, text_proj=8, hidden=32, mlp=32)


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
