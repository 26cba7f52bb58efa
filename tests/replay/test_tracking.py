"""Tests of motion_env.replay.tracking (PD tracking, reported next to the checks)."""

from __future__ import annotations

import pytest

from motion_env.io.bvh import load_bvh
from motion_env.replay import corruptions
from motion_env.replay.tracking import track


def test_tracking_keeps_a_standing_take_up(bandai) -> None:
    motion = load_bvh(bandai / "dataset-2_raise-up-both-hands_normal_001.bvh.gz")
    result = track(motion)
    assert not result["fell"] and result["stayed_up_s"] == pytest.approx(motion.duration)
    assert result["mean_joint_error_cm"] < 10.0
    falling = track(corruptions.raised(motion, height=1.0, seconds=10.0, start=0))
    assert falling["stayed_up_s"] <= motion.duration
