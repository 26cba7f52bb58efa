"""Root paths, waypoint validation, token path features and waypoint errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from motion_env.models import path_features
from motion_env.motion import trajectory as paths
from motion_env.motion.kinematics import heading_from_joints, rotate_y

SAMPLE = Path(__file__).resolve().parents[3] / "shared" / "data" / "humanml3d_sample"


def _sample_joints() -> np.ndarray:
    f = SAMPLE / "new_joints" / "012314.npy"
    if not f.is_file():
        pytest.skip(f"real HumanML3D sample not found at {f}")
    return np.load(f).astype(np.float32)


def _line(num: int, speed: float, theta: float) -> np.ndarray:
    t = np.arange(num) / 20.0
    return np.stack([math.sin(theta) * speed * t, math.cos(theta) * speed * t, np.full(num, theta)], 1)


def test_root_path_from_real_joints() -> None:
    joints = _sample_joints()
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


def test_token_path_features_straight_walk() -> None:
    feats = path_features.token_path_features(_line(61, 1.4, 0.7), rate=4)
    assert feats.shape == (16, path_features.D_PATH) and feats.dtype == np.float32
    # Walking forward at 1.4 m/s: forward velocity 1.4, no lateral motion, no turn, over both horizons.
    np.testing.assert_allclose(feats[:-1, [1, 4]], 1.4, atol=1e-4)
    np.testing.assert_allclose(feats[:-1, [0, 2, 3, 5]], 0, atol=1e-4)
    np.testing.assert_allclose(feats[-1], 0, atol=1e-6)  # last frame: nothing ahead


def test_token_path_features_invariant_to_placement_and_sees_turns() -> None:
    t = np.arange(80) / 20.0
    theta = 0.8 * t  # turning left at 0.8 rad/s while walking forward at 1 m/s
    x = np.cumsum(np.sin(theta)) / 20.0
    z = np.cumsum(np.cos(theta)) / 20.0
    path = np.stack([x, z, theta], 1)
    feats = path_features.token_path_features(path, rate=4)
    moved = path.copy()
    pts = rotate_y(np.stack([path[:, 0], np.zeros(80), path[:, 1]], 1), 2.0)
    moved[:, 0], moved[:, 1] = pts[:, 0] + 5.0, pts[:, 2] - 3.0
    moved[:, 2] = paths.wrap_angle(path[:, 2] + 2.0)  # wrapped headings are unwrapped internally
    np.testing.assert_allclose(path_features.token_path_features(moved, 4), feats, atol=1e-4)
    np.testing.assert_allclose(feats[:10, [2, 5]], 0.8, atol=1e-3)
    assert (feats[:10, 0] > 0).all()  # the path bends towards the character's left
    with pytest.raises(ValueError, match="rate"):
        path_features.token_path_features(path, 0)


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
