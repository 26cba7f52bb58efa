"""Tests of motion_env.render.frames (render_frame) and the stick-figure renderer behind it."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.render import render_frame
from motion_env.render.drawing import HIGHLIGHT_COLOR, LEFT_COLOR, RIGHT_COLOR, TARGET_COLOR


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


def test_render_frame_names_bad_arguments(walker):
    joints = walker(1).joints[0]
    with pytest.raises(ValueError, match="^width must be an int of at least 64 pixels, got 10"):
        render_frame(joints, width=10, height=120)
    with pytest.raises(ValueError, match="^height must be an int of at least 64 pixels, got 120.5"):
        render_frame(joints, width=160, height=120.5)
    with pytest.raises(ValueError, match="center"):
        render_frame(joints, center=[np.nan, 0.0], width=160, height=120)
    with pytest.raises(ValueError, match="target"):
        render_frame(joints, target=[np.inf, 0.0], width=160, height=120)
    with pytest.raises(ValueError, match="path"):
        render_frame(joints, path=[[0.0, 0.0], [np.nan, 1.0]], width=160, height=120)
    with pytest.raises(ValueError, match="waypoints have infinite or negative times"):
        render_frame(joints, waypoints=[[0.0, 1.0, np.inf]], width=160, height=120)
    with pytest.raises(TypeError, match="camera"):
        render_frame(joints, camera="front", width=160, height=120)


def test_timed_waypoints_are_labelled_in_frames_then_seconds(walker, small):
    from motion_env.render.drawing import waypoint_time
    from motion_env.render.skeleton import SkeletonRenderer

    assert waypoint_time(40, 20) == "f40 (2.0 s)" and waypoint_time(40.5, 20) == "f40.5 (2.0 s)"
    renderer = SkeletonRenderer(**small)
    renderer.draw(walker(1).joints[0], waypoints=[[0.0, 1.0, 40.0], [1.0, 2.0, np.nan]], fps=20.0)
    labels = [t.get_text() for t in renderer.figure.axes[0].texts if t.get_visible() and t.get_text()]
    assert "1: f40 (2.0 s)" in labels and "2" in labels
    assert not any("t=" in label or "s@" in label or "@" in label for label in labels)
