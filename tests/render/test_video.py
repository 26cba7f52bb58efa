"""Tests of motion_env.render.video: the one video writer and the stick-figure video."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from motion_env.motion.types import Motion
from motion_env.render import render_video
from motion_env.render.drawing import HIGHLIGHT_COLOR, LEFT_COLOR
from motion_env.render.video import VideoWriter, check_video_path


def test_render_video_mp4_frames_and_highlight(tmp_path, walker, mask, small):
    motion = walker(12)
    out = render_video(motion, tmp_path / "clip.mp4", highlight_frames=[4, 5], **small)
    frames = iio.imread(out, index=None)
    assert frames.shape == (12, 120, 160, 3)
    flagged = [mask(f, HIGHLIGHT_COLOR, 60).sum() > 200 for f in frames]
    assert flagged == [i in (4, 5) for i in range(12)]
    # The follow camera keeps the walker in the middle although it moves 0.6 m.
    for f in (frames[0], frames[-1]):
        cols = np.nonzero(mask(f, LEFT_COLOR, 60))[1]
        assert abs(cols.mean() - 80) < 20


def test_render_video_gif_with_other_fps(tmp_path, walker, small):
    motion = walker(12)
    motion.waypoints = np.array([[0.0, 1.0, 10.0], [1.0, 2.0, np.nan]], np.float32)
    out = render_video(motion, tmp_path / "clip.gif", fps=10, obstacles=[[1, 1, 0.2]], **small)
    frames = iio.imread(out, index=None)
    assert frames.shape[:3] == (6, 120, 160)
    assert iio.immeta(out)["duration"] == 100


def test_render_video_fixed_camera_frames_the_whole_route(tmp_path, walker, mask, small):
    motion = walker(40, heading=0.5, speed=4.0)  # 8 m: far outside a follow view
    frames = iio.imread(render_video(motion, tmp_path / "fixed.mp4", camera="fixed", **small), index=None)
    cols = [np.nonzero(mask(f, LEFT_COLOR, 60))[1] for f in (frames[0], frames[-1])]
    assert all(len(c) > 0 for c in cols)
    assert abs(cols[0].mean() - cols[1].mean()) > 30  # the camera stays put, the walker moves


def test_render_video_rejects_bad_arguments(tmp_path, walker):
    motion = walker(4)
    with pytest.raises(ValueError, match=r"unknown video type '\.avi'"):
        render_video(motion, tmp_path / "clip.avi")
    with pytest.raises(ValueError, match="highlight frame 9"):
        render_video(motion, tmp_path / "clip.mp4", highlight_frames=[9])
    with pytest.raises(ValueError, match="camera"):
        render_video(motion, tmp_path / "clip.mp4", camera="orbit")
    with pytest.raises(ValueError, match="even"):
        render_video(motion, tmp_path / "clip.mp4", width=161, height=120)
    with pytest.raises(ValueError, match="fps"):
        render_video(motion, tmp_path / "clip.mp4", fps=0)
    assert not list(tmp_path.iterdir())  # nothing written


def test_video_writer_checks_and_abort(tmp_path):
    assert check_video_path(tmp_path / "a.GIF").suffix == ".GIF"
    check_video_path(tmp_path / "a.gif", 161, 121)  # a GIF has no even-size rule
    with pytest.raises(ValueError, match="even"):
        check_video_path(tmp_path / "a.mp4", 160, 121)
    with pytest.raises(ValueError, match="unknown video type"):
        VideoWriter(tmp_path / "a.webm", 20)
    with pytest.raises(ValueError, match="fps"):
        VideoWriter(tmp_path / "a.gif", float("nan"))
    frame = np.zeros((16, 16, 3), np.uint8)
    for suffix in (".mp4", ".gif"):
        path = tmp_path / "sub" / f"v{suffix}"
        writer = VideoWriter(path, 20)  # makes the folder
        writer.append(frame)
        writer.abort()
        assert not path.exists()
    writer = VideoWriter(tmp_path / "ok.gif", 20)
    for value in (0, 255):
        writer.append(np.full((16, 16, 3), value, np.uint8))
    writer.close()
    frames = iio.imread(tmp_path / "ok.gif", index=None)
    assert frames.shape[0] == 2 and iio.immeta(tmp_path / "ok.gif")["duration"] == 50


def test_render_real_clip(tmp_path, humanml3d_sample, mask, small):
    joints, _ = humanml3d_sample
    motion = Motion(joints, text="a real HumanML3D clip")
    frames = iio.imread(render_video(motion, tmp_path / "real.mp4", fps=5, **small), index=None)
    assert frames.shape[0] == 43  # 170 frames at 20 fps = 8.5 s -> 42.5 frames at 5 fps, rounded up
    assert all(mask(f, LEFT_COLOR, 60).sum() > 10 for f in frames)


def test_render_video_names_bad_input(tmp_path, walker):
    motion = walker(6)
    motion.joints[3, 4, 1] = np.nan  # a Motion checks its joints when made; its array can change
    with pytest.raises(ValueError, match=r"motion\.joints has NaN or infinite values at frames \[3\]"):
        render_video(motion, tmp_path / "clip.gif")
    motion = walker(6)
    motion.fps = 0.0
    with pytest.raises(ValueError, match=r"motion\.fps must be a positive finite number"):
        render_video(motion, tmp_path / "clip.gif")
    motion = walker(6)
    sizes = [
        ({"width": 160.5, "height": 120}, "width"),
        ({"width": 160, "height": 0}, "height"),
        ({"width": 32, "height": 120}, "width"),
        ({"width": 160, "height": True}, "height"),
    ]
    for size, name in sizes:
        with pytest.raises(ValueError, match=rf"^{name} must be an int of at least 64 pixels"):
            render_video(motion, tmp_path / "clip.gif", **size)
    with pytest.raises(ValueError, match="even frame size: height is 121"):
        render_video(motion, tmp_path / "clip.mp4", width=160, height=121)
    with pytest.raises(ValueError, match=r"waypoints have infinite or negative times .* rows \[1\]"):
        render_video(motion, tmp_path / "clip.gif", waypoints=[[0, 1, 5], [1, 1, -3]])
    with pytest.raises(TypeError, match="motion_env.Motion"):
        render_video(motion.joints, tmp_path / "clip.gif")
    assert not list(tmp_path.iterdir())  # nothing written


def test_video_size_check_names_the_argument(tmp_path):
    with pytest.raises(ValueError, match="^width must be an int of at least 1 pixels"):
        check_video_path(tmp_path / "a.mp4", 0, 120)
    with pytest.raises(ValueError, match="even frame size: width is 161"):
        check_video_path(tmp_path / "a.mp4", 161, 120)
