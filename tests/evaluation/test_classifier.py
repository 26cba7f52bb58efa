"""The action/style classifier (motion_env.evaluation.classifier) and the caption-recognition
evaluation around it (motion_env.evaluation.recognition, scripts/evaluate_captions.py)."""

from __future__ import annotations

import importlib.util
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.evaluation.classifier import (
    DEFAULT_CLASSIFIER,
    FEATURE_DIM,
    ClassifierConfig,
    classify,
    labelled_clips,
    load_classifier,
    pose_features,
    save_classifier,
)
from motion_env.evaluation.recognition import recognition_scores
from motion_env.motion.kinematics import rotate_y

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "evaluate_captions.py"


def _clip(frames: int = 40, seed: int = 0) -> np.ndarray:
    """A synthetic clip (T, 22, 3): a random pose that wobbles, walks forward and turns."""
    rng = np.random.default_rng(seed)
    pose = rng.normal(0.0, 0.3, (22, 3)) + np.array([0.0, 1.0, 0.0])
    t = np.arange(frames)[:, None, None]
    joints = pose[None] + 0.02 * rng.normal(size=(frames, 22, 3))
    joints = rotate_y(joints, 0.01 * t[..., 0])
    joints[..., 2] += 0.05 * t[..., 0]
    return joints.astype(np.float32)


def test_features_have_the_documented_shape() -> None:
    assert pose_features(_clip(30)).shape == (30, FEATURE_DIM)
    with pytest.raises(ValueError, match="T >= 2"):
        pose_features(_clip(30)[:1])


@pytest.mark.parametrize("heading", [0.0, 1.3, -2.9])
def test_features_ignore_start_position_and_heading(heading: float) -> None:
    joints = _clip()
    moved = rotate_y(joints, heading) + np.array([3.0, 0.2, -7.5])
    np.testing.assert_allclose(pose_features(moved), pose_features(joints), atol=1e-4)


def test_model_shapes_and_probabilities(tiny_classifier) -> None:
    cfg = tiny_classifier.config
    a, s = tiny_classifier(
        torch.zeros(5, cfg.window, FEATURE_DIM), torch.ones(5, cfg.window, dtype=torch.bool)
    )
    assert a.shape == (5, len(cfg.actions)) and s.shape == (5, len(cfg.styles))
    # Clips shorter and longer than the window, by padding and by windows.
    pa, ps = classify(tiny_classifier, [_clip(5), _clip(16), _clip(70)])
    assert pa.shape == (3, 3) and ps.shape == (3, 2)
    np.testing.assert_allclose(pa.sum(1), 1.0, atol=1e-5)
    np.testing.assert_allclose(ps.sum(1), 1.0, atol=1e-5)


def test_classification_ignores_start_position_and_heading(tiny_classifier) -> None:
    joints = _clip(50)
    pa, ps = classify(tiny_classifier, [joints, rotate_y(joints, 2.0) + np.array([-4.0, 0.0, 9.0])])
    np.testing.assert_allclose(pa[0], pa[1], atol=1e-4)
    np.testing.assert_allclose(ps[0], ps[1], atol=1e-4)


def test_config_rejects_bad_values() -> None:
    with pytest.raises(ValueError, match="kernel must be odd"):
        ClassifierConfig(actions=("a", "b"), styles=("x", "y"), kernel=4)
    with pytest.raises(ValueError, match="actions"):
        ClassifierConfig(actions=("a",), styles=("x", "y"))


def test_checkpoint_round_trip(tiny_classifier, tmp_path) -> None:
    with torch.no_grad():
        tiny_classifier.feature_mean.fill_(0.25)  # the normalisation buffers travel with the weights
    path = save_classifier(tmp_path / "c.pt", tiny_classifier, metrics={"test": {"action": 1.0}})
    loaded, ckpt = load_classifier(path)
    assert loaded.config == tiny_classifier.config
    assert ckpt["config"] == asdict(tiny_classifier.config) and ckpt["metrics"]["test"]["action"] == 1.0
    assert torch.load(path, weights_only=True)["kind"] == "motion_classifier"
    assert float(loaded.feature_mean[0]) == 0.25
    clips = [_clip(30), _clip(90, seed=1)]
    for got, want in zip(classify(loaded, clips), classify(tiny_classifier, clips), strict=True):
        np.testing.assert_allclose(got, want, atol=2e-2)  # float16 weights in the file
    with pytest.raises(FileNotFoundError, match="train_classifier"):
        load_classifier(tmp_path / "none.pt")


def test_recognition_scores_count_pairs_among_the_top_three() -> None:
    pa = np.array([[0.7, 0.2, 0.1], [0.1, 0.3, 0.6]])
    ps = np.array([[0.6, 0.4], [0.9, 0.1]])
    out = recognition_scores(pa, ps, [0, 1], [1, -1])
    assert out["action"] == 0.5 and out["style"] == 0.0 and out["pair_top3"] == 1.0 and out["clips"] == 2


def _script():
    spec = importlib.util.spec_from_file_location("evaluate_captions", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize(
    ("extra", "message"),
    [(["--seeds", "0"], "--seeds must be >= 1"), ([], "no index.csv"), (["--threads", "0"], "--threads")],
)
def test_script_checks_its_arguments(tmp_path, capsys, extra: list[str], message: str) -> None:
    with pytest.raises(SystemExit) as exc:
        _script().main(["--data", str(tmp_path), *extra])
    assert exc.value.code == 2 and message in capsys.readouterr().err


def test_cli_checks_its_arguments(tmp_path, capsys) -> None:
    from motion_env.cli import main

    (tmp_path / "index.csv").write_text("name\n")
    assert main(["eval", "captions", "--data", str(tmp_path)]) == 2
    assert "--split test" in capsys.readouterr().err
    (tmp_path / "test.txt").write_text("")
    assert main(["eval", "captions", "--data", str(tmp_path), "--classifier", str(tmp_path / "c.pt")]) == 2
    assert "--classifier" in capsys.readouterr().err


def test_mirrored_takes_carry_the_mirrored_label(built_dataset) -> None:
    clips = {c.name: c for c in labelled_clips(built_dataset, "test")}
    pairs = [(n, "M" + n) for n in clips if "wave-left-hand" in n and not n.startswith("M")]
    assert pairs, "no one-hand wave in the test split"
    for name, mirrored in pairs:
        assert clips[name].action == "wave-left-hand" and clips[mirrored].action == "wave-right-hand"


def test_shipped_classifier_recognises_real_held_out_takes(built_dataset) -> None:
    if not DEFAULT_CLASSIFIER.is_file():
        pytest.skip(
            f"no classifier at {DEFAULT_CLASSIFIER} (python scripts/train_classifier.py --data data/mocap)"
        )
    model, ckpt = load_classifier()
    assert ckpt["metrics"]["test"]["action"] >= 0.95 and ckpt["metrics"]["test"]["style"] >= 0.95
    actions = {a: i for i, a in enumerate(model.config.actions)}
    clips = [c for c in labelled_clips(built_dataset, "test") if c.action in actions][::8]
    pa, _ = classify(model, [c.joints for c in clips])
    assert (pa.argmax(1) == [actions[c.action] for c in clips]).mean() >= 0.95
