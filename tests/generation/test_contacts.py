"""A run's toes on the floor counted as planted (generation/contacts.py)."""

from __future__ import annotations

import numpy as np

from motion_env.generation.contacts import RUN_SPEED, TOE_HEIGHT, with_run_toes
from motion_env.motion.skeleton import FOOT_JOINTS, FPS

LEFT_TOE = FOOT_JOINTS[1]


def _body(frames: int, pelvis_speed: float, toe_speed: float, toe_height: float) -> np.ndarray:
    """(T, 22, 3): every joint carried forward (+z) at `pelvis_speed`, the left toe at
    `toe_speed` and `toe_height` (m)."""
    t = np.arange(frames)[:, None]
    joints = np.zeros((frames, 22, 3))
    joints[..., 1] = 0.5
    joints[..., 2] = pelvis_speed / FPS * t
    joints[:, LEFT_TOE, 2] = toe_speed / FPS * t[:, 0]
    joints[:, LEFT_TOE, 1] = toe_height
    return joints


def test_a_runs_slow_low_toe_is_planted_and_nothing_else_is() -> None:
    flags = np.zeros((10, 4), np.float32)
    run = with_run_toes(_body(10, 3.0, 0.5, 0.02), flags)
    assert run[:, 1].tolist() == [1.0] * 10 and not run[:, [0, 2, 3]].any()
    assert not with_run_toes(_body(10, 0.9 * RUN_SPEED, 0.2, 0.02), flags).any()  # a walk
    assert not with_run_toes(_body(10, 3.0, 0.5, TOE_HEIGHT + 0.01), flags).any()  # lifted
    assert not with_run_toes(_body(10, 3.0, 1.6, 0.02), flags).any()  # swinging: over half the pelvis
    # The decoder's own flags stay: the rule only adds.
    decoded = np.ones((10, 4), np.float32) * 0.7
    np.testing.assert_array_equal(with_run_toes(_body(10, 0.0, 0.0, 0.3), decoded), decoded)


def test_the_stream_token_by_token_gives_the_whole_clips_contacts() -> None:
    # Backward differences: a token with the frame before it is the clip's rule on its frames.
    rng = np.random.default_rng(0)
    joints = _body(24, 3.0, 0.0, 0.02)
    joints[:, LEFT_TOE] += rng.normal(scale=[0.02, 0.01, 0.05], size=(24, 3))  # a toe now slow, now fast
    flags = (rng.random((24, 4)) > 0.7).astype(np.float32)
    whole = with_run_toes(joints, flags)
    assert 0 < whole[:, 1].sum() < 24
    tokens = [with_run_toes(joints[f : f + 4], flags[f : f + 4], joints[f - 1]) for f in range(4, 24, 4)]
    np.testing.assert_array_equal(np.concatenate(tokens), whole[4:])
    batch = with_run_toes(
        np.stack([joints[4:8], joints[8:12]]), np.stack([flags[4:8], flags[8:12]]), joints[[3, 7]]
    )
    np.testing.assert_array_equal(batch.reshape(8, 4), whole[4:12])
