"""The evaluation's routes and metrics (motion_env/evaluate.py), without a model."""

from __future__ import annotations

import re

import numpy as np
import pytest

from motion_env.data.captions import BANDAI_CONTENTS, BANDAI_STYLES, captions_for_bandai
from motion_env.evaluation.routes import (
    RUN_CAPTIONS,
    STYLE_CAPTIONS,
    TURN_LEFT,
    TURN_RIGHT,
    WALK_CAPTIONS,
    WAVE_LEFT,
    WAVE_RIGHT,
    heldout_caption,
    route_summary,
    speed_and_cadence,
    synthetic_cases,
    synthetic_path,
    wrist_heights,
)
from motion_env.motion.skeleton import FPS


@pytest.mark.parametrize("kind", ["line", "arc", "zigzag", "scurve"])
def test_synthetic_paths_keep_their_speed(kind: str) -> None:
    path = synthetic_path(kind, 1.25, 200, np.random.default_rng(0))
    assert path.shape == (200, 2)
    np.testing.assert_allclose(path[0], [0.0, 0.0])
    step = np.linalg.norm(np.diff(path, axis=0), axis=1) * FPS
    np.testing.assert_allclose(step, 1.25, rtol=1e-6)
    assert path[5, 1] > 0  # sets off towards +Z
    if kind == "line":
        np.testing.assert_allclose(path[:, 0], 0.0, atol=1e-9)
    else:
        assert np.abs(path[:, 0]).max() > 0.5  # it turns


def test_synthetic_cases_time_their_waypoints_every_two_to_three_seconds() -> None:
    cases = synthetic_cases(num_frames=200, repeats=1, seed=0)
    assert len(cases) == 8 and {c.group for c in cases} == {"walk", "run"}
    for c in cases:
        gaps = np.diff(np.concatenate([[0], c.waypoints[:, 2]]))
        assert (gaps[:-1] >= 40).all() and (gaps[:-1] <= 60).all() and c.waypoints[-1, 2] == 199
        chord = np.linalg.norm(np.diff(c.waypoints[:, :2], axis=0), axis=1).sum()
        pace = chord / (c.waypoints[-1, 2] - c.waypoints[0, 2]) * FPS  # chords cut the corners
        low, high = (1.0, 1.5) if c.group == "walk" else (2.5, 3.5)
        assert 0.75 * low <= pace <= high


def test_route_summary_follows_the_product_definitions() -> None:
    r = route_summary([np.array([0.1, 0.6]), np.array([0.2, 0.3, 0.1])])
    assert r["root_error_cm"] == pytest.approx(26.0)
    assert r["location_error"] == pytest.approx(1 / 5)
    assert r["trajectory_error"] == pytest.approx(1 / 2)
    assert r["max_miss_cm"] == pytest.approx(60.0)
    assert (r["clips"], r["waypoints"]) == (2, 5)


def test_heldout_captions_use_new_words() -> None:
    assert heldout_caption("run", "elderly", "fallback") == "a frail old person hurries ahead at full tilt"
    assert heldout_caption("dance", "", "the take's own caption") == "the take's own caption"


def test_speed_cadence_and_wrists_on_real_takes(require_data) -> None:
    from motion_env.io.bvh import load_bvh

    bandai = require_data("bandai/dataset-2/bvh")
    walk = load_bvh(bandai / "dataset-2_walk_normal_001.bvh.gz").joints
    run = load_bvh(bandai / "dataset-2_run_normal_001.bvh.gz").joints
    walk_speed, walk_cadence = speed_and_cadence(walk)
    run_speed, run_cadence = speed_and_cadence(run)
    assert 0.8 < walk_speed < 1.8 and 1.2 < walk_cadence < 2.5
    assert run_speed > walk_speed + 0.8 and run_cadence > walk_cadence
    wave = load_bvh(bandai / "dataset-2_wave-right-hand_normal_001.bvh.gz").joints
    assert wrist_heights(wave)["right_minus_left_cm"] > 30


def test_steering_captions_use_words_the_training_captions_never_use() -> None:
    # The steering numbers claim generalisation to new wordings: the words that carry the action
    # in each evaluation caption must stay out of the training captions' vocabulary.
    vocab: set[str] = set()
    for content in BANDAI_CONTENTS:
        for style in BANDAI_STYLES:
            for caption in captions_for_bandai(content, style, n=40, seed=0):
                vocab |= set(re.findall(r"[a-z]+", caption))
    new_words = {
        WALK_CAPTIONS: ("ambles", "unhurried", "gait", "saunters", "clip"),
        RUN_CAPTIONS: ("hurries", "tilt", "pounding", "races", "legs", "bolts", "top"),
        WAVE_RIGHT + WAVE_LEFT: ("greets", "friend"),
        TURN_LEFT + TURN_RIGHT: ("foot", "leftward", "rightward"),
        tuple(c for group in STYLE_CAPTIONS.values() for c in group): ("drained", "drags", "nineties", "pep"),
    }
    for captions, words in new_words.items():
        assert all(any(w in c.split() or w + "," in c.split() for c in captions) for w in words)
        assert not vocab & set(words), f"training captions use {sorted(vocab & set(words))}"
