"""Tests of motion_env.replay.plausibility: the checks, the verdict and the report (evaluate)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest

from motion_env.io.bvh import load_bvh
from motion_env.motion.types import Motion
from motion_env.replay import corruptions, evaluate, format_report
from motion_env.replay.plausibility import CHECKS, SKATE_WINDOW, load_thresholds, min_frames


def test_evaluate_is_the_function_of_the_package() -> None:
    import motion_env.replay
    from motion_env.replay import plausibility as checks

    assert motion_env.replay.evaluate is checks.evaluate and callable(motion_env.replay.evaluate)


def test_standing_still_is_plausible_and_corruptions_are_named(standing_clip) -> None:
    clip = standing_clip(3.0)
    ok = evaluate(clip)
    assert ok["plausible"], ok["summary"]
    assert ok["checks"]["root_force"]["value"] < 0.5  # the floor carries the weight
    floating = evaluate(corruptions.raised(clip))
    assert not floating["plausible"] and "floating" in floating["failed"]
    assert "root_force" in floating["failed"]  # nothing holds the body up
    sunk = evaluate(corruptions.sunk(clip))
    assert sunk["failed"] == ["penetration"]
    assert sunk["checks"]["penetration"]["value"] == pytest.approx(0.15, abs=0.01)


def test_report_is_json_with_frames_and_words(standing_clip) -> None:
    clip = corruptions.raised(standing_clip(3.0), start=20)
    result = evaluate(clip)
    json.dumps(result)  # serialisable as it is
    check = result["checks"]["floating"]
    assert set(check) == {"value", "threshold", "unit", "passed", "frames", "worst_frame", "message"}
    assert check["frames"] == [[20, 39]] and check["value"] == pytest.approx(1.0)
    assert "frames 20-39" in check["message"] and "in the air" in check["message"]
    assert set(result["checks"]) == set(CHECKS)
    text = format_report(result, title="clip")
    assert "NOT PLAUSIBLE" in text and "floating" in text


def test_too_short_clips_are_not_judged(standing_clip) -> None:
    # The longest window of the checks (foot skating's second) is the shortest clip judged.
    assert min_frames() == round(SKATE_WINDOW * 20) == 20
    assert min_frames(30) == 30 and min_frames(1) == 3
    for frames in (1, 2, 19):
        result = evaluate(standing_clip(frames / 20))
        assert result["plausible"] is None and result["judged"] is False and result["min_frames"] == 20
        assert result["summary"] == f"too short to judge: {frames} frames, at least 20 needed (1.0 s)"
        assert result["failed"] == [] and set(result["checks"]) == set(CHECKS)
        json.dumps(result)
        text = format_report(result)
        assert "verdict: CANNOT BE JUDGED (too short" in text and "PLAUSIBLE" not in text
    judged = evaluate(standing_clip(1.0))
    assert judged["plausible"] is True and judged["judged"] is True
    # A check that fails on a short clip is reported, but it is no verdict either.
    lifted = evaluate(corruptions.raised(standing_clip(0.1), seconds=0.1, start=0))
    assert lifted["plausible"] is None and "root_force" in lifted["failed"]
    assert "failing even so:" in lifted["summary"]
    assert "failing even so: " in format_report(lifted)
    # Counted at 20 fps, after the resampling: 25 frames at 30 fps are 17 frames at 20 fps.
    fast = evaluate(Motion(standing_clip(1.25).joints[:25], fps=30.0))
    assert fast["judged"] is False and fast["frames"] == 17 and fast["resampled_from_fps"] == 30.0


def test_held_out_real_takes_are_plausible_and_corruptions_caught(held_out_takes) -> None:
    thresholds = load_thresholds()
    for path in held_out_takes:
        motion = load_bvh(path)
        real = evaluate(motion, thresholds=thresholds)
        assert real["plausible"], f"{path.name}: {real['summary']}"
        for name, corrupt in corruptions.ALL.items():
            failed = set(evaluate(corrupt(motion), thresholds=thresholds)["failed"])
            assert failed & corruptions.CAUGHT_BY[name], f"{path.name} {name}: failed {sorted(failed)}"


def test_evaluate_of_ten_seconds_is_fast(bandai) -> None:
    motion = load_bvh(bandai / "dataset-2_walk_normal_001.bvh.gz")  # 9 s
    motion = Motion(np.concatenate([motion.joints, motion.joints[-1:].repeat(200 - motion.num_frames, 0)]))
    evaluate(motion)  # warm-up: model compilation is cached per shape
    start = time.perf_counter()
    evaluate(motion)
    assert time.perf_counter() - start < 3.0
