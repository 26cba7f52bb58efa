"""Tests of the causal, frame-by-frame retargeter (:class:`motion_env.retarget.StreamRetargeter`)."""

from __future__ import annotations

import numpy as np
import pytest

import motion_env
from motion_env.retarget import StreamRetargeter
from motion_env.retarget.limits import range_violations


def _stream(rt: StreamRetargeter, joints: np.ndarray) -> np.ndarray:
    """(T, B, nq) of joints (T, B, 22, 3) fed one frame at a time."""
    return np.stack([rt.step(frame) for frame in joints])


def test_stream_matches_the_clip_retargeter_without_smoothing(waving_clip) -> None:
    clip = waving_clip(frames=24)
    rt = StreamRetargeter("unitree_g1")
    streamed = _stream(rt, clip.joints[:, None])[:, 0]
    # Same stages, same frames, no low-pass: the whole-clip result at the stream's 20 fps.
    whole = motion_env.retarget(clip, "unitree_g1", fps=20, smoothing=0).qpos
    assert streamed.shape == whole.shape == (24, rt.nq)
    assert np.abs(streamed - whole).max() < 1e-5
    assert range_violations(rt.robot.model, streamed) == 0


def test_batch_rows_are_independent_and_reset_starts_over(waving_clip) -> None:
    clip = waving_clip(frames=12)
    one = _stream(StreamRetargeter("unitree_g1"), clip.joints[:, None])[:, 0]
    rt = StreamRetargeter("unitree_g1", batch=2)
    still = np.repeat(clip.joints[:1], len(clip.joints), axis=0)
    both = _stream(rt, np.stack([clip.joints, still], axis=1))
    np.testing.assert_allclose(both[:, 0], one, atol=1e-9)
    rt.reset(0)
    np.testing.assert_allclose(rt.qpos[0], rt.robot.home)
    again = _stream(rt, np.stack([clip.joints, still], axis=1))
    np.testing.assert_allclose(again[:, 0], one, atol=1e-9)


def test_bad_inputs() -> None:
    rt = StreamRetargeter("unitree_g1", batch=2)
    with pytest.raises(ValueError, match=r"\(2, 22, 3\)"):
        rt.step(np.zeros((1, 22, 3)))
    with pytest.raises(ValueError):
        rt.step(np.full((2, 22, 3), np.nan))
    with pytest.raises(ValueError, match="batch"):
        StreamRetargeter("unitree_g1", batch=0)
