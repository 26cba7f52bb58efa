"""Caption recognition (motion_env.evaluation.recognition, `motion-env eval captions`): the scores,
the settings, the command's checks, and the shipped classifier on the real held-out takes."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.evaluation.recognition import RecognitionSettings, recognition_scores
from motion_env.models.classifier import DEFAULT_CLASSIFIER, classify, load_classifier
from motion_env.training.classifier import labelled_clips


def test_recognition_scores_count_pairs_among_the_top_three() -> None:
    pa = np.array([[0.7, 0.2, 0.1], [0.1, 0.3, 0.6]])
    ps = np.array([[0.6, 0.4], [0.9, 0.1]])
    out = recognition_scores(pa, ps, [0, 1], [1, -1])
    assert out["action"] == 0.5 and out["style"] == 0.0 and out["pair_top3"] == 1.0 and out["clips"] == 2


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"seeds": 0}, "RecognitionSettings.seeds must be an integer >= 1, got 0"),
        ({"seed": -1}, "RecognitionSettings.seed must be an integer >= 0"),
        ({"split": ""}, "RecognitionSettings.split"),
    ],
)
def test_settings_name_the_bad_field(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        RecognitionSettings(data="data/mocap", **changes)


def test_cli_checks_its_arguments(tmp_path, capsys) -> None:
    from motion_env.cli import main

    (tmp_path / "index.csv").write_text("name\n")
    assert main(["eval", "captions", "--data", str(tmp_path)]) == 2
    assert "--split test" in capsys.readouterr().err
    (tmp_path / "test.txt").write_text("")
    assert main(["eval", "captions", "--data", str(tmp_path), "--classifier", str(tmp_path / "c.pt")]) == 2
    assert "--classifier" in capsys.readouterr().err
    assert main(["eval", "captions", "--data", str(tmp_path), "--seeds", "0"]) == 2
    assert "seeds must be an integer >= 1" in capsys.readouterr().err


def test_mirrored_takes_carry_the_mirrored_label(built_dataset) -> None:
    clips = {c.name: c for c in labelled_clips(built_dataset, "test")}
    pairs = [(n, "M" + n) for n in clips if "wave-left-hand" in n and not n.startswith("M")]
    assert pairs, "no one-hand wave in the test split"
    for name, mirrored in pairs:
        assert clips[name].action == "wave-left-hand" and clips[mirrored].action == "wave-right-hand"


def test_shipped_classifier_recognises_real_held_out_takes(built_dataset) -> None:
    if not DEFAULT_CLASSIFIER.is_file():
        pytest.skip(f"no classifier at {DEFAULT_CLASSIFIER} (motion-env train classifier --data data/mocap)")
    model, ckpt = load_classifier()
    assert ckpt["metrics"]["test"]["action"] >= 0.95 and ckpt["metrics"]["test"]["style"] >= 0.95
    actions = {a: i for i, a in enumerate(model.config.actions)}
    clips = [c for c in labelled_clips(built_dataset, "test") if c.action in actions][::8]
    pa, _ = classify(model, [c.joints for c in clips])
    assert (pa.argmax(1) == [actions[c.action] for c in clips]).mean() >= 0.95
