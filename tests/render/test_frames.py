"""Tests of motion_env.render.frames (render_frame) and the stick-figure renderer behind it."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.render import render_frame
from motion_env.render.scene import HIGHLIGHT_COLOR, LEFT_COLOR, RIGHT_COLOR, TARGET_COLOR


def test_render_frame_shape_and_left_right_colours(walker, mask, small):
    motion = walker(1, arms_out=True)
    img = render_frame(motion.joints[0], **small)
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    left, right = mask(img, LEFT_COLOR), mask(img, RIGHT_COLOR)
    assert left.sum() > 30 and right.sum() > 30
    assert not mask(img, HIGHLIGHT_COLOR).any()
    # The camera looks at the pelvis: the figure is centred horizontally.
    cols = np.nonzero(left | right)[1]
    assert abs(cols.mean() - 80) < 15


@pytest.mark.parametrize("heading, left_on_screen_right", [(0.0, True), (np.pi, False)])
def test_render_frame_is_not_mirrored(heading, left_on_screen_right, walker, mask, small):
    # The default camera sees a character facing +Z from its front-left, so its left hand (+X)
    # is on the right of the picture; turned around, it is on the left.
    joints = walker(1, heading=heading, arms_out=True).joints[0]
    img = render_frame(joints, **small)
    left_x = np.nonzero(mask(img, LEFT_COLOR))[1].mean()
    right_x = np.nonzero(mask(img, RIGHT_COLOR))[1].mean()
    assert (left_x > right_x) == left_on_screen_right


def test_render_frame_overlays_and_highlight(walker, mask, small):
    joints = walker(1).joints[0]
    plain = render_frame(joints, inset=False, **small)
    red = render_frame(joints, highlight=True, inset=False, **small)
    assert mask(red, HIGHLIGHT_COLOR).sum() > 200  # skeleton and border
    assert not mask(red, LEFT_COLOR).any()
    with_target = render_frame(joints, target=[1.0, 0.5], inset=False, **small)
    assert mask(with_target, TARGET_COLOR).sum() > 10 and not mask(plain, TARGET_COLOR).any()
    with_obstacle = render_frame(joints, obstacles=[[0.8, 0.8, 0.3]], inset=False, **small)
    assert np.abs(with_obstacle.astype(int) - plain).sum() > 1000
    # A far waypoint route turns the map on by default; it only occupies the top-right corner.
    mapped = render_frame(joints, waypoints=[[0, 5], [5, 10]], path=[[0, 0], [0, 0.1]], **small)
    diff = np.abs(mapped.astype(int) - plain).sum(-1) > 0
    assert diff[:45, 100:].any() and not diff[60:, :80].any()


def test_render_frame_rejects_bad_input(walker):
    with pytest.raises(ValueError, match=r"\(22, 3\)"):
        render_frame(np.zeros((21, 3)))
    with pytest.raises(ValueError, match="NaN"):
        render_frame(np.full((22, 3), np.nan))
    joints = walker(1).joints[0]
    with pytest.raises(ValueError, match="waypoints"):
        render_frame(joints, waypoints=np.zeros((3, 4)))
    with pytest.raises(ValueError, match="obstacles"):
        render_frame(joints, obstacles=[[0.0, 1.0, -0.5]])
