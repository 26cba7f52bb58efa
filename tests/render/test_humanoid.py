"""Tests of motion_env.render.humanoid: the replay video and the env's humanoid frames (MuJoCo)."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from motion_env.motion.types import Motion
from motion_env.render.humanoid import HumanoidView, problem_frames, render_humanoid_video
from motion_env.replay import corruptions, evaluate_detailed
from motion_env.replay.humanoid import rest_positions


def _floating_clip() -> Motion:
    """The humanoid's rest pose held for 1.5 s, raised off the floor for 0.5 s from frame 10."""
    rest = rest_positions().astype(np.float32)
    return corruptions.raised(Motion(np.repeat(rest[None], 30, axis=0)), seconds=0.5, start=10)


def _offscreen(make):
    try:
        return make()
    except RuntimeError as exc:  # no offscreen OpenGL here
        pytest.skip(str(exc))


def test_problem_frames_lists_failing_checks_per_frame():
    report = {"checks": {"floating": {"frames": [[2, 3]]}, "speed": {"frames": [[3, 9]]}}}
    assert problem_frames(report, 5) == [[], [], ["floating"], ["floating", "speed"], ["speed"]]


def test_render_humanoid_video_marks_problem_frames(tmp_path):
    measurements, report = evaluate_detailed(_floating_clip())
    assert "floating" in report["failed"]
    out = _offscreen(lambda: render_humanoid_video(measurements, report, tmp_path / "replay.mp4", 320, 180))
    frames = iio.imread(out, index=None)
    assert frames.shape == (30, 180, 320, 3)
    red = [(f[..., 0].astype(int) - f[..., 1] > 120).sum() for f in frames]
    assert red[15] > red[2]  # the humanoid turns red while it floats
    gif = render_humanoid_video(measurements, report, tmp_path / "replay.gif", 160, 90)
    assert iio.imread(gif, index=None).shape[:3] == (30, 90, 160)
    with pytest.raises(ValueError, match="unknown video type"):
        render_humanoid_video(measurements, report, tmp_path / "replay.avi")


def test_render_humanoid_video_of_a_clip_too_short_to_judge(tmp_path, monkeypatch):
    import motion_env.render.humanoid as module

    texts = []
    draw = module._text_image
    monkeypatch.setattr(module, "_text_image", lambda text, *a: (texts.append(text), draw(text, *a))[1])
    rest = rest_positions().astype(np.float32)
    measurements, report = evaluate_detailed(Motion(np.repeat(rest[None], 4, axis=0)))
    assert report["judged"] is False
    out = _offscreen(lambda: render_humanoid_video(measurements, report, tmp_path / "short.gif", 160, 90))
    assert iio.imread(out, index=None).shape[0] == 4
    assert texts and all(t.endswith("too short to judge") for t in texts)


def test_humanoid_view_draws_the_pose_and_the_scene():
    view = _offscreen(lambda: HumanoidView(128, 96))
    try:
        joints = rest_positions()
        plain = view.draw(joints)
        assert plain.shape == (96, 128, 3) and plain.dtype == np.uint8
        busy = view.draw(
            joints,
            trail=np.zeros((8, 2)),
            target=np.array([1.0, 1.0]),
            waypoints=np.array([[0.0, 1.0], [1.0, 2.0]]),
            obstacles=np.array([[-1.0, 1.0, 0.3]]),
        )
        assert np.abs(busy.astype(int) - plain).sum() > 1000
    finally:
        view.close()
