"""The evaluation's routes and metrics (motion_env/evaluate.py), without a model."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.evaluation.route_following import synthetic_cases, synthetic_path
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
