"""Root paths, waypoint validation, token path features and waypoint errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from motion_env.motion import trajectory as paths
from motion_env.motion.kinematics import heading_from_joints


def _line(num: int, speed: float, theta: float) -> np.ndarray:
    t = np.arange(num) / 20.0
    return np.stack([math.sin(theta) * speed * t, math.cos(theta) * speed * t, np.full(num, theta)], 1)


def test_root_path_from_real_joints(humanml3d_sample) -> None:
    joints = humanml3d_sample[0]
    raw = paths.root_path_from_joints(joints, smooth_sigma=0)
    smooth = paths.root_path_from_joints(joints)
    assert raw.shape == smooth.shape == (len(joints), 3) and raw.dtype == np.float32
    np.testing.assert_allclose(raw[:, 0], joints[:, 0, 0])
    np.testing.assert_allclose(raw[:, 1], joints[:, 0, 2])
    np.testing.assert_allclose(paths.wrap_angle(raw[:, 2] - heading_from_joints(joints)), 0, atol=1e-5)
    assert np.abs(np.diff(raw[:, 2])).max() < math.pi  # unwrapped
    # Smoothing removes frame-to-frame jitter but keeps the turns.
    assert np.abs(np.diff(smooth[:, 2], 2)).sum() < np.abs(np.diff(raw[:, 2], 2)).sum()
    assert abs((smooth[-1, 2] - smooth[0, 2]) - (raw[-1, 2] - raw[0, 2])) < 0.3
    with pytest.raises(ValueError, match=r"\(T, 22, 3\)"):
        paths.root_path_from_joints(joints[:, :21])


def test_validate_waypoints_accepts_and_fills_nan_times() -> None:
    wp = paths.validate_waypoints([[0, 2], [2, 4]])
    assert wp.shape == (2, 3) and wp.dtype == np.float32 and np.isnan(wp[:, 2]).all()
    mixed = paths.validate_waypoints(np.array([[0, 1, 10], [1, 1, np.nan], [2, 2, 30]]))
    np.testing.assert_array_equal(mixed[[0, 2], 2], [10, 30])


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        ([], "empty"),
        (np.zeros((0, 3)), "empty"),
        ([1.0, 2.0], r"shape \(K, 2\) or \(K, 3\).*one waypoint"),
        ([[1, 2, 3, 4]], r"shape \(K, 2\) or \(K, 3\)"),
        ([[0, np.nan]], "NaN or infinite x/z at rows \\[0\\]"),
        ([[0, 1], [np.inf, 1]], "rows \\[1\\]"),
        ([[0, 1, -5]], ">= 0"),
        ([[0, 1, np.inf]], "finite"),
        ([[0, 1, 20], [1, 1, 20]], "strictly increasing"),
        ([[0, 1, 40], [1, 1, np.nan], [2, 2, 30]], "row 2 \\(t=30\\)"),
        ([["a", "b"]], "numeric"),
    ],
)
def test_validate_waypoints_errors(bad: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        paths.validate_waypoints(bad)


def test_relative_waypoints_in_heading_frame() -> None:
    # Facing +X (theta = pi/2): a point 2 m along +X is straight ahead; -Z is on the left.
    rel = paths.relative_waypoints(np.array([1.0, 1.0]), math.pi / 2, np.array([[3.0, 1.0], [1.0, 0.0]]))
    np.testing.assert_allclose(rel, [[0.0, 2.0], [1.0, 0.0]], atol=1e-6)


def test_waypoint_errors_timed_and_untimed() -> None:
    path = _line(60, 1.0, 0.0)  # z = t
    err = paths.waypoint_errors(path, [[0.0, 1.0, 20], [0.3, 2.0, np.nan], [0.0, 0.0, 500]])
    # timed on the path; untimed closest approach 0.3 m; past the end measured at the last frame
    np.testing.assert_allclose(err, [0.0, 0.3, 2.95], atol=1e-5)


def test_gait_free_path_removes_step_sway_and_keeps_the_route() -> None:
    t = np.arange(200) / 20.0
    heading = np.linspace(0.0, 1.0, 200)
    # 1.3 m/s forward with a 2 Hz surge and a 1 Hz, 4 cm sideways sway, as a walking pelvis.
    z = 1.3 * t + 0.02 * np.sin(2 * np.pi * 2.0 * t)
    x = 0.04 * np.sin(2 * np.pi * 1.0 * t)
    path = np.stack([x, z, heading], -1).astype(np.float32)
    smooth = paths.gait_free_path(path)
    np.testing.assert_array_equal(smooth[:, 2], path[:, 2])
    inner = slice(20, -20)
    assert np.abs(smooth[inner, 0]).max() < 0.4 * 0.04  # the 1 Hz sway mostly gone
    speed = np.diff(smooth[inner, 1]) * 20
    assert np.abs(speed - 1.3).max() < 0.05  # the 2 Hz surge gone, the pace kept
    np.testing.assert_allclose(paths.gait_free_path(path, sigma=0), path)
    with pytest.raises(ValueError, match="root_path"):
        paths.gait_free_path(np.zeros((10, 2)))
