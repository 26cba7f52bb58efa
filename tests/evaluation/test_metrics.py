"""Metrics as docs/metrics.md defines them: foot skating, route summaries, speed, cadence, wrists."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.evaluation.metrics import foot_skating_ratio, route_summary, speed_and_cadence, wrist_heights
from motion_env.motion.skeleton import FOOT_JOINTS


def test_route_summary_follows_the_metric_definitions() -> None:
    r = route_summary([np.array([0.1, 0.6]), np.array([0.2, 0.3, 0.1])])
    assert r["root_error_cm"] == pytest.approx(26.0)
    assert r["location_error"] == pytest.approx(1 / 5)
    assert r["trajectory_error"] == pytest.approx(1 / 2)
    assert r["max_miss_cm"] == pytest.approx(60.0)
    assert (r["clips"], r["waypoints"]) == (2, 5)


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


def test_foot_skating_ratio_definition() -> None:
    n = 21
    joints = np.zeros((n, 22, 3), np.float32)
    joints[:, :, 1] = 1.0
    assert foot_skating_ratio(joints) == 0.0
    joints[:, FOOT_JOINTS[1], 1] = 0.02  # a toe on the floor ...
    assert foot_skating_ratio(joints) == 0.0
    joints[:, FOOT_JOINTS[1], 0] = np.arange(n) * 0.03  # ... sliding 3 cm per frame
    assert foot_skating_ratio(joints) == 1.0
    joints[:, FOOT_JOINTS[1], 0] = np.arange(n) * 0.02  # 2 cm per frame is allowed
    assert foot_skating_ratio(joints) == 0.0
    assert foot_skating_ratio(joints[:1]) == 0.0
