"""The action/style classifier of real takes (motion_env.models.classifier): its features, shapes,
invariances, checkpoint, and the shipped weights."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import pytest
import torch

from motion_env.models.classifier import (
    CHECKPOINT_KIND,
    DEFAULT_CLASSIFIER,
    FEATURE_DIM,
    ClassifierConfig,
    classify,
    clip_embeddings,
    load_classifier,
    pose_features,
    save_classifier,
)
from motion_env.motion.kinematics import rotate_y

# The shipped classifier's labels and architecture (motion_env/weights/classifier.pt).
SHIPPED_ACTIONS = (
    "raise-up-both-hands", "raise-up-left-hand", "raise-up-right-hand", "run", "walk", "walk-turn-left",
    "walk-turn-right", "wave-both-hands", "wave-left-hand", "wave-right-hand",
)  # fmt: skip
SHIPPED_STYLES = ("active", "elderly", "exhausted", "feminine", "masculine", "normal", "youthful")


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
    assert clip_embeddings(tiny_classifier, [_clip(5), _clip(70)]).shape == (2, 2 * cfg.width)
    assert clip_embeddings(tiny_classifier, []).shape == (0, 2 * cfg.width)


def test_classification_ignores_start_position_and_heading(tiny_classifier) -> None:
    joints = _clip(50)
    clips = [joints, rotate_y(joints, 2.0) + np.array([-4.0, 0.0, 9.0])]
    pa, ps = classify(tiny_classifier, clips)
    np.testing.assert_allclose(pa[0], pa[1], atol=1e-4)
    np.testing.assert_allclose(ps[0], ps[1], atol=1e-4)
    emb = clip_embeddings(tiny_classifier, clips)
    np.testing.assert_allclose(emb[0], emb[1], atol=1e-4)


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
    assert torch.load(path, weights_only=True)["kind"] == CHECKPOINT_KIND
    assert float(loaded.feature_mean[0]) == 0.25
    clips = [_clip(30), _clip(90, seed=1)]
    for got, want in zip(classify(loaded, clips), classify(tiny_classifier, clips), strict=True):
        np.testing.assert_allclose(got, want, atol=2e-2)  # float16 weights in the file
    full = save_classifier(tmp_path / "f.pt", tiny_classifier, half=False)
    for got, want in zip(classify(load_classifier(full)[0], clips), classify(tiny_classifier, clips)):
        np.testing.assert_allclose(got, want, atol=1e-6)
    with pytest.raises(FileNotFoundError, match="motion-env train classifier"):
        load_classifier(tmp_path / "none.pt")


def test_the_shipped_classifier_loads_as_trained() -> None:
    if not DEFAULT_CLASSIFIER.is_file():
        pytest.skip(f"no classifier at {DEFAULT_CLASSIFIER} (motion-env train classifier --data data/mocap)")
    model, ckpt = load_classifier()
    assert model.config == ClassifierConfig(actions=SHIPPED_ACTIONS, styles=SHIPPED_STYLES)
    assert ckpt["metrics"]["test"]["action"] >= 0.95 and ckpt["metrics"]["test"]["style"] >= 0.95
    assert not model.training and model.feature_std.min() > 0
