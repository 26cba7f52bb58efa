"""The classifier's trainer (motion_env.training.classifier, `motion-env train classifier`) on a tiny
synthetic dataset: a checkpoint the model loads, resuming to the same weights, its settings."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.classifier import classify, load_classifier
from motion_env.training.classifier import ClassifierTrainConfig, labelled_clips, train_classifier

# (action, style, speed m/s) of the synthetic takes; each is written to every split.
KINDS = [("walk", "normal", 1.0), ("walk", "tired", 0.8), ("run", "normal", 3.0), ("run", "tired", 2.5)]
TINY = {"window": 16, "width": 8, "layers": 1, "batch_size": 4, "min_takes": 2, "progress": False}


def _take(speed: float, frames: int, rng: np.random.Generator) -> np.ndarray:
    """A rest pose gliding forward at `speed` m/s with a little noise: (frames, 22, 3)."""
    from motion_env.motion.kinematics import bone_offsets, forward_kinematics

    pos = np.zeros((frames, 3))
    pos[:, 2] = np.arange(frames) * speed / 20
    pos[:, 1] = -float(bone_offsets()[[2, 5, 8], 1].sum())
    rots = np.zeros((frames, 22, 4))
    rots[..., 0] = 1.0
    return forward_kinematics(pos, rots) + rng.normal(0, 0.01, (frames, 22, 3))


@pytest.fixture(scope="module")
def labelled_dataset(tmp_path_factory: pytest.TempPathFactory, write_labelled_dataset) -> Path:
    """A HumanML3D-layout dataset with ``index.csv``: two Bandai takes of each KINDS in train, one
    in val and test."""
    rng = np.random.default_rng(0)
    takes = [
        (f"{split}-{action}_{style}_{k}", split, action, style, _take(speed, 31, rng))
        for split in ("train", "val", "test")
        for action, style, speed in KINDS
        for k in range(2 if split == "train" else 1)
    ]
    return write_labelled_dataset(tmp_path_factory.mktemp("labelled"), takes)


def _weights(path: Path) -> dict[str, torch.Tensor]:
    return torch.load(path, weights_only=True)["model"]


def test_labelled_clips_read_the_index(labelled_dataset: Path) -> None:
    clips = labelled_clips(labelled_dataset, "train")
    assert len(clips) == 8 and {(c.action, c.style) for c in clips} == {(a, s) for a, s, _ in KINDS}


def test_training_writes_a_classifier_the_model_loads(labelled_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "c.pt"
    metrics = train_classifier(labelled_dataset, out, ClassifierTrainConfig(epochs=2, **TINY))
    assert metrics["epoch"] == 2 and 1 <= metrics["best_epoch"] <= 2 and metrics["train_clips"] == 8
    assert metrics["test"]["clips"] == 4 and 0 <= metrics["test"]["action"] <= 1
    model, ckpt = load_classifier(out)
    assert model.config.actions == ("run", "walk") and model.config.styles == ("normal", "tired")
    assert model.config.width == 8 and "resume" not in ckpt and ckpt["settings"]["epochs"] == 2
    assert classify(model, [c.joints for c in labelled_clips(labelled_dataset, "test")])[0].shape == (4, 2)
    # A finished run is not trained again: its metrics come back from the checkpoint.
    assert train_classifier(labelled_dataset, out, ClassifierTrainConfig(epochs=2, **TINY)) == metrics


def test_a_resumed_run_ends_with_the_weights_of_an_uninterrupted_one(
    labelled_dataset: Path, tmp_path: Path
) -> None:
    whole, parts = tmp_path / "whole.pt", tmp_path / "parts.pt"
    train_classifier(labelled_dataset, whole, ClassifierTrainConfig(epochs=3, **TINY))
    stopped = train_classifier(
        labelled_dataset, parts, ClassifierTrainConfig(epochs=3, max_minutes=0.0, **TINY)
    )
    assert stopped["epoch"] == 1 and "resume" in torch.load(parts, weights_only=True)
    load_classifier(parts)  # the best model so far is readable mid-run
    train_classifier(labelled_dataset, parts, ClassifierTrainConfig(epochs=3, **TINY))
    for name, tensor in _weights(whole).items():
        assert torch.equal(tensor, _weights(parts)[name]), name
    with pytest.raises(ValueError, match="cannot resume.*epochs"):
        train_classifier(labelled_dataset, parts, ClassifierTrainConfig(epochs=4, **TINY))


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"epochs": 0}, "ClassifierTrainConfig.epochs must be >= 1, got 0"),
        ({"kernel": 4}, "ClassifierTrainConfig.kernel must be odd, got 4"),
        ({"dropout": 1.0}, r"ClassifierTrainConfig.dropout must be in \[0, 1\), got 1.0"),
        ({"lr": 0.0}, "ClassifierTrainConfig.lr must be > 0"),
    ],
)
def test_bad_settings_name_the_field(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        ClassifierTrainConfig(**changes)


def test_motion_env_train_classifier(labelled_dataset: Path, tmp_path: Path, capsys) -> None:
    from motion_env.cli import main

    out = tmp_path / "cli.pt"
    argv = ["train", "classifier", "--data", str(labelled_dataset), "--out", str(out), "--epochs", "1"]
    argv += ["--window", "16", "--width", "8", "--layers", "1", "--min-takes", "2", "--no-progress"]
    assert main(argv) == 0
    out_text = capsys.readouterr().out  # the log lines, then the metrics as JSON
    printed = json.loads(out_text[out_text.index("{\n") :])
    assert printed["model"] == "classifier" and printed["checkpoint"] == str(out) and printed["epoch"] == 1
    assert load_classifier(out)[0].config.width == 8
