"""The naturalness report (motion_env.evaluation.naturalness, `motion-env eval natural`) on a small
synthetic dataset, the tiny random generator and an untrained classifier."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.evaluation.metrics import diversity, frechet_distance, joint_acceleration, joint_jerk
from motion_env.evaluation.naturalness import (
    NaturalnessSettings,
    evaluate_naturalness,
    extended_path,
    mix_weights,
    naturalness_takes,
    travel_waypoints,
)
from motion_env.models.classifier import save_classifier
from motion_env.motion.trajectory import root_path_from_joints
from motion_env.text.encoders import TextEncoder

# Takes per action of the synthetic test split: "walk" is reported, "wave-right-hand" has too few.
TAKES = {"walk": 3, "wave-right-hand": 2}
SPEEDS = {"walk": 1.2, "wave-right-hand": 0.0}  # m/s: the waves stand still
FRAMES = 41


def _walk(rng: np.random.Generator, frames: int, speed: float) -> np.ndarray:
    """A rest pose swinging its hips along a gentle curve at `speed` m/s: (frames, 22, 3)."""
    from motion_env.motion.kinematics import bone_offsets, forward_kinematics
    from motion_env.motion.rotations import quat_from_yaw

    t = np.arange(frames) / 20
    yaw = rng.uniform(-0.3, 0.3) * t
    pos = np.cumsum(np.stack([np.sin(yaw), np.zeros_like(t), np.cos(yaw)], 1) * speed / 20, axis=0)
    pos[:, 1] = -float(bone_offsets()[[2, 5, 8], 1].sum())
    rots = np.zeros((frames, 22, 4))
    rots[..., 0] = 1.0
    rots[:, 0] = quat_from_yaw(yaw)
    swing = 0.4 * np.sin(2 * np.pi * max(speed, 0.5) * t)
    for joint, sign in ((1, 1), (2, -1)):  # hips swing about x
        rots[:, joint, 0], rots[:, joint, 1] = np.cos(sign * swing / 2), np.sin(sign * swing / 2)
    return forward_kinematics(pos, rots)


@pytest.fixture(scope="module")
def natural_dataset(tmp_path_factory: pytest.TempPathFactory, write_labelled_dataset) -> Path:
    """A HumanML3D-layout dataset with ``index.csv``: TAKES walks and waves in the test split."""
    rng = np.random.default_rng(0)
    takes = []
    for action, count in TAKES.items():
        for k in range(count):
            joints = _walk(rng, FRAMES + 1, SPEEDS[action])
            takes.append((f"dataset-1_{action}_normal_{k:03d}", "test", action, "normal", joints))
    return write_labelled_dataset(tmp_path_factory.mktemp("natural"), takes)


class _HashText(TextEncoder):
    """A stand-in for MiniLM (same width, no model to load): a fixed random vector per caption length."""

    name, dim = "hash", 384

    def _embed(self, texts: list[str]) -> torch.Tensor:
        return torch.stack([torch.randn(384, generator=torch.Generator().manual_seed(len(t))) for t in texts])


@pytest.fixture(scope="module")
def tiny_generator():
    """The untrained test generator (seed 0) reading captions with :class:`_HashText`."""
    from motion_env.generation.generator import MotionGenerator

    return MotionGenerator.random(seed=0, text_encoder=_HashText())


@pytest.fixture
def classifier_file(tiny_classifier, tmp_path: Path) -> Path:
    return save_classifier(tmp_path / "classifier.pt", tiny_classifier)


def test_waypoints_every_second_only_where_the_take_travels() -> None:
    frames = np.arange(95)
    path = np.zeros((95, 3), np.float32)
    assert travel_waypoints(path) is None  # in place: the caption decides
    path[:, 1] = np.minimum(frames, 50) * 0.05  # 1 m/s for 50 frames, then still
    wp = travel_waypoints(path)
    assert wp[:, 2].tolist() == [20, 40, 60]  # the second ending at 60 still moved 0.5 m
    np.testing.assert_allclose(wp[:, 1], path[[20, 40, 60], 1])
    path[:, 1] = frames * 0.05
    assert travel_waypoints(path)[:, 2].tolist() == [20, 40, 60, 80, 94]  # and the last frame


def test_smoothness_and_distribution_metrics() -> None:
    seconds = np.arange(10, dtype=np.float64)[:, None, None] / 20
    joints = np.zeros((10, 22, 3)) + 0.5 * 2.0 * seconds**2  # 2 m/s^2 along every axis
    np.testing.assert_allclose(joint_acceleration(joints), np.sqrt(3) * 2.0, rtol=1e-6)
    np.testing.assert_allclose(joint_jerk(joints), 0.0, atol=1e-6)
    rng = np.random.default_rng(0)
    a = rng.normal(size=(200, 4))
    assert frechet_distance(a, a) == pytest.approx(0.0, abs=1e-6)
    assert frechet_distance(a, a + [3.0, 0, 0, 4.0]) == pytest.approx(25.0, rel=1e-6)
    assert diversity(np.array([[0.0, 0.0], [3.0, 4.0]])) == 5.0
    with pytest.raises(ValueError, match="N >= 2"):
        frechet_distance(a[:1], a)


def test_weights_resample_the_reference() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(40, 3)), rng.normal(size=(60, 3)) + 1.0
    # Equal weights change nothing; a zero weight drops the row; integer weights repeat rows.
    assert frechet_distance(a, b, np.full(60, 7.0)) == pytest.approx(frechet_distance(a, b))
    half = np.r_[np.ones(30), np.zeros(30)]
    assert frechet_distance(a, b, half) == pytest.approx(frechet_distance(a, b[:30]))
    assert diversity(b, half) == pytest.approx(diversity(b[:30]))
    assert diversity(b, np.ones(60)) == pytest.approx(diversity(b))
    twice = np.r_[np.full(30, 2.0), np.ones(30)]
    repeated = np.concatenate([b[:30], b])
    mean_gap = (repeated.mean(0) - a.mean(0)) @ (repeated.mean(0) - a.mean(0))
    weighted_gap = ((twice @ b) / twice.sum() - a.mean(0)) @ ((twice @ b) / twice.sum() - a.mean(0))
    assert weighted_gap == pytest.approx(mean_gap)
    with pytest.raises(ValueError, match=r"weights must be \(60,\)"):
        frechet_distance(a, b, np.ones(59))
    with pytest.raises(ValueError, match="not all 0"):
        diversity(b, np.zeros(60))


def test_mix_weights_give_each_action_its_clips_share() -> None:
    # 2 clips of an action with 8 takes, 2 of one with 2 takes: each action weighs 2 in all.
    w = mix_weights([2, 2], [8, 2])
    assert w.tolist() == [0.25] * 8 + [1.0] * 2
    with pytest.raises(ValueError, match=">= 1 take per action"):
        mix_weights([2], [0])


def test_the_real_takes_themselves_score_near_zero_whatever_the_mix() -> None:
    """Clips that are the real takes, 2 of each action, against every take: the weighted reference
    has the clips' mix; unweighted, the frequent action dominates the reference and the distance."""
    rng = np.random.default_rng(2)
    rare = rng.normal(size=(4, 2)) + [6.0, 0.0]
    common = rng.normal(size=(96, 2))
    real = np.concatenate([rare, common])
    clips = np.concatenate([rare[:2], common[:2]])
    weighted = frechet_distance(clips, real, mix_weights([2, 2], [4, 96]))
    assert weighted < 0.25 * frechet_distance(clips, real)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"per_action": 1}, "NaturalnessSettings.per_action must be an integer >= 2"),
        ({"stage": "gpt"}, "NaturalnessSettings.stage must be one of"),
        ({"seed": -1}, "NaturalnessSettings.seed"),
        ({"min_takes": 2}, "NaturalnessSettings.min_takes"),
        ({"split": " "}, "NaturalnessSettings.split"),
        ({"actions": ()}, "NaturalnessSettings.actions"),
        ({"actions": ("walk", " ")}, "NaturalnessSettings.actions"),
    ],
)
def test_settings_name_the_bad_field(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        NaturalnessSettings(data="d", **changes)


def test_takes_by_action_with_enough_takes(natural_dataset: Path) -> None:
    takes = naturalness_takes(natural_dataset, "test")
    assert list(takes) == ["walk"] and len(takes["walk"]) == 3
    first = takes["walk"][0]
    assert first.text == "a person does a walk" and first.joints.shape == (FRAMES, 22, 3)


@pytest.mark.parametrize("stage", ["generated", "streamed", "vqvae", "real-path"])
def test_report_on_the_random_model(tiny_generator, natural_dataset, classifier_file, stage: str) -> None:
    settings = NaturalnessSettings(
        data=natural_dataset, per_action=2, stage=stage, classifier=classifier_file
    )
    result = evaluate_naturalness(tiny_generator, settings, progress=False)
    assert list(result.actions) == ["walk"] and len(result.takes["walk"]) == 2
    row = result.actions["walk"]
    assert row.takes == 3 and row.clips == 2 and result.overall.clips == 2
    assert row.accel_ratio > 0 and row.jerk_ratio > 0 and 0 <= row.pops <= 1 and row.real_pops == 0.0
    assert row.fd is not None and row.fd >= 0 and row.diversity is not None and row.real_diversity > 0
    assert row.fd_real_vs_real is None  # halves of 1 and 2 takes: no covariance for one
    assert row.plausible is None or 0 <= row.plausible <= 1
    assert row.plausible is None or sum(row.replay_failures.values()) >= (1 - row.plausible) * row.clips
    data = json.loads(json.dumps(result.to_dict()))
    assert data["stage"] == stage and data["actions"]["walk"]["clips"] == 2
    text = result.format()
    assert "walk" in text and "\nall " in text


def test_streamed_and_whole_clips_make_the_same_request(tiny_generator, natural_dataset) -> None:
    # Same caption, start and timed waypoints: frame by frame, the root passes the take's
    # waypoints as the whole clip does (both snap the path through them).
    from motion_env.evaluation.naturalness import make_again

    take = naturalness_takes(natural_dataset, "test")["walk"][0]
    whole, streamed = make_again(tiny_generator, take, 0), make_again(tiny_generator, take, 0, "streamed")
    assert streamed.shape == whole.shape == take.joints.shape
    wp = travel_waypoints(extended_path(root_path_from_joints(take.joints)))
    inside = wp[wp[:, 2] < len(take.joints)]
    assert len(inside) >= 2
    for x, z, frame in inside:
        for joints in (whole, streamed):
            np.testing.assert_allclose(joints[int(frame), 0, [0, 2]], [x, z], atol=1e-3)
    assert np.abs(streamed - whole).max() > 1e-3  # the causal stages are not the whole clip's
    with pytest.raises(ValueError, match="stage must be one of"):
        make_again(tiny_generator, take, 0, "vqvae")  # no seed to make it with: not a maker


def test_the_real_path_stage_walks_the_takes_own_path(tiny_generator, natural_dataset) -> None:
    # The tokens and the body go along the take's root path, not the (untrained) controller's.
    from motion_env.evaluation.naturalness import _on_real_path

    take = naturalness_takes(natural_dataset, "test")["walk"][0]
    made = _on_real_path(tiny_generator, take, 0)
    assert made.shape == take.joints.shape and np.isfinite(made).all()
    real = root_path_from_joints(take.joints)[:, :2]
    np.testing.assert_allclose(made[0, 0, [0, 2]], real[0], atol=1e-3)  # the start stays put
    assert np.linalg.norm(made[:, 0, [0, 2]] - real, axis=1).max() < 0.3  # balance shifts it a little at most
    assert np.linalg.norm(real[-1] - real[0]) > 1.0  # the take travels, so the check means something


def test_cli_writes_the_report(tiny_generator, natural_dataset, classifier_file, tmp_path, capsys) -> None:
    from motion_env.cli import main

    weights = tiny_generator.save(tmp_path / "weights")
    out = tmp_path / "natural.json"
    argv = ["eval", "natural", "--data", str(natural_dataset), "--weights", str(weights), "--stage", "vqvae"]
    argv += ["--per-action", "2", "--classifier", str(classifier_file), "--json", str(out)]
    assert main(argv) == 0
    assert "walk" in capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["stage"] == "vqvae" and data["command"].startswith("motion-env eval natural")
    assert main(argv) == 2  # the JSON exists: refused without --overwrite
    assert "exists" in capsys.readouterr().err
    assert main([*argv[:-2], "--per-action", "1"]) == 2
    assert "per_action" in capsys.readouterr().err
    assert main([*argv[:-2], "--actions", "walk,run"]) == 2  # no run takes in this split
    assert "actions ['run']" in capsys.readouterr().err


def test_a_subset_of_actions_gives_their_rows_of_a_full_run(
    tmp_path, write_labelled_dataset, tiny_generator, classifier_file
) -> None:
    rng = np.random.default_rng(1)
    takes = [
        (
            f"dataset-1_{action}_normal_{k:03d}",
            "test",
            action,
            "normal",
            _walk(rng, FRAMES + 1, SPEEDS[action]),
        )
        for action in ("wave-right-hand", "walk")
        for k in range(5)
    ]
    data = write_labelled_dataset(tmp_path / "two", takes)
    settings = NaturalnessSettings(data=data, per_action=2, stage="vqvae", classifier=classifier_file)
    full = evaluate_naturalness(tiny_generator, settings, progress=False)
    assert list(full.actions) == ["walk", "wave-right-hand"]
    subset = evaluate_naturalness(
        tiny_generator,
        NaturalnessSettings(**{**vars(settings), "actions": ("wave-right-hand",)}),
        progress=False,
    )
    assert list(subset.actions) == list(subset.takes) == ["wave-right-hand"]
    row = subset.actions["wave-right-hand"]
    assert (
        row.fd_real_vs_real is not None and row == full.actions["wave-right-hand"]
    )  # same takes, halves, numbers
    assert subset.overall.clips == 2 and subset.overall.takes == 5
    with pytest.raises(ValueError, match=r"actions \['run'\].*there are: walk, wave-right-hand"):
        evaluate_naturalness(
            tiny_generator,
            NaturalnessSettings(**{**vars(settings), "actions": ("run", "walk")}),
            progress=False,
        )
