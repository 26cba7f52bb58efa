"""Distilling the look-ahead head: settings, a short run end to end, the file the generator loads."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import torch

from motion_env.models.checkpoint import export_checkpoint, save_checkpoint, text_encoder_record
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.lookahead import LOOKAHEAD_FILE, load_lookahead
from motion_env.text.encoders import TextEncoder
from motion_env.training.lookahead import LookaheadTrainConfig, train_lookahead


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="stride"):
        LookaheadTrainConfig(stride=0)
    with pytest.raises(ValueError, match="reach"):
        LookaheadTrainConfig(reach=-1.0)


def _weights(folder: Path, encoder: TextEncoder) -> PathController:
    torch.manual_seed(0)
    ctrl = PathController(ControllerConfig(text_dim=int(encoder.dim), text_proj=8, hidden=16, mlp=16))
    torch.nn.init.normal_(ctrl.out[-1].weight, std=0.3)  # a controller that moves
    save_checkpoint(
        folder / "controller.pt", kind="controller", config=ctrl.config, model=ctrl,
        text_encoder=text_encoder_record(encoder),
    )  # fmt: skip
    return ctrl


def test_train_lookahead_learns_the_controllers_window(
    tiny_dataset: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    ctrl = _weights(tmp_path, hash_text())
    settings = dict(
        weights=str(tmp_path), rollouts=3, val_rollouts=1, rows=8, burn_in=10, after=4, batch_size=64,
        warmup=5, progress=False, resume=False,
    )  # fmt: skip
    untrained = train_lookahead(
        tiny_dataset,
        tmp_path / "a.pt",
        LookaheadTrainConfig(steps=1, lr=1e-9, **settings),
        text_encoder=hash_text(),
    )
    trained = train_lookahead(
        tiny_dataset, tmp_path / "b.pt", LookaheadTrainConfig(steps=150, **settings), text_encoder=hash_text()
    )
    assert trained["pos_cm"] < 0.5 * untrained["pos_cm"]
    export_checkpoint(tmp_path / "b.pt", tmp_path / LOOKAHEAD_FILE)
    head, ckpt = load_lookahead(tmp_path, ctrl)
    assert head is not None and ckpt["metrics"]["pos_cm"] == trained["pos_cm"]
    assert all(v.dtype == torch.float16 for v in ckpt["model"].values())  # shipped as float16
    with pytest.raises(ValueError, match="trained with text encoder"):
        train_lookahead(
            tiny_dataset, tmp_path / "c.pt", LookaheadTrainConfig(**settings), text_encoder=hash_text("other")
        )
    with pytest.raises(FileNotFoundError, match="no dataset"):
        train_lookahead(tmp_path / "nowhere", tmp_path / "c.pt", LookaheadTrainConfig(**settings))
