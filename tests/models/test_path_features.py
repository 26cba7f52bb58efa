"""Per-token path features: what the body GPT reads about the root path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from motion_env.models import path_features
from motion_env.motion import trajectory as paths
from motion_env.motion.kinematics import rotate_y


def _line(num: int, speed: float, theta: float) -> np.ndarray:
    t = np.arange(num) / 20.0
    return np.stack([math.sin(theta) * speed * t, math.cos(theta) * speed * t, np.full(num, theta)], 1)


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


def test_the_compiled_first_token_features_give_what_numpy_gives(both_ways) -> None:
    """path_features_jit against first_token_path_features' numpy operations, to the bit: turning
    paths whose headings wrap round, paths shorter than a token and than a second, one frame."""
    from motion_env.models import path_features_jit

    rng = np.random.default_rng(6)
    turning = np.cumsum(rng.normal(0.0, 0.1, (5, 40, 3)), axis=1)
    turning[..., 2] = np.cumsum(rng.normal(0.0, 1.5, (5, 40)), axis=1)  # steps past pi: wraps
    for paths_ in (turning, turning[:, :3], turning[:, :12], turning[:, :1], turning[:1]):
        run = lambda p=paths_: path_features.first_token_path_features(p.astype(np.float32), 4)  # noqa: E731
        outputs = both_ways(path_features_jit, "first_token_features", run)
        np.testing.assert_array_equal(outputs[True], outputs[False])
        assert outputs[True].dtype == np.float32 and outputs[True].shape == (
            len(paths_),
            path_features.D_PATH,
        )
