"""Tests for motion_env.render (videos, frames, path plots) and `motion-env show`."""

from __future__ import annotations

from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from motion_env import motion as M
from motion_env import skeleton as S
from motion_env.cli import main
from motion_env.motion.types import Motion
from motion_env.render import stick as R

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
SMALL = {"width": 160, "height": 120}


def _walker(frames: int = 12, heading: float = 0.0, speed: float = 1.2, arms_out: bool = False) -> Motion:
    """A rest-pose body gliding along its heading at `speed` m/s (20 fps), feet on the floor."""
    rot = np.zeros((frames, S.NUM_JOINTS, 4))
    rot[..., 0] = 1.0
    rot[:, 0] = M.quat_from_yaw(np.full(frames, heading))
    t = np.arange(frames) / S.FPS
    root = np.stack([np.sin(heading) * speed * t, np.zeros(frames), np.cos(heading) * speed * t], -1)
    joints = M.forward_kinematics(root, rot)
    if arms_out:
        # Arms straight out sideways from the shoulders: the left hand far on the body's left.
        left = M.from_heading_frame(np.array([1.0, 0.0]), heading)
        for shoulder, elbow, wrist, side in ((16, 18, 20, 1.0), (17, 19, 21, -1.0)):
            out = np.array([left[0], 0.0, left[1]]) * side
            joints[:, elbow] = joints[:, shoulder] + 0.26 * out
            joints[:, wrist] = joints[:, shoulder] + 0.53 * out
    joints[..., 1] -= joints[..., 1].min()
    return Motion(joints.astype(np.float32), text="a person glides forward")


def _mask(img: np.ndarray, color: str, tol: float = 40.0) -> np.ndarray:
    """(H, W) pixels within `tol` (RGB distance) of a '#rrggbb' colour."""
    return np.linalg.norm(img.astype(float) - R._hex_rgb(color) * 255, axis=-1) < tol


def test_render_frame_shape_and_left_right_colours():
    motion = _walker(1, arms_out=True)
    img = R.render_frame(motion.joints[0], **SMALL)
    assert img.shape == (120, 160, 3) and img.dtype == np.uint8
    left, right = _mask(img, R.LEFT_COLOR), _mask(img, R.RIGHT_COLOR)
    assert left.sum() > 30 and right.sum() > 30
    assert not _mask(img, R.HIGHLIGHT_COLOR).any()
    # The camera looks at the pelvis: the figure is centred horizontally.
    cols = np.nonzero(left | right)[1]
    assert abs(cols.mean() - 80) < 15


@pytest.mark.parametrize("heading, left_on_screen_right", [(0.0, True), (np.pi, False)])
def test_render_frame_is_not_mirrored(heading, left_on_screen_right):
    # The default camera sees a character facing +Z from its front-left, so its left hand (+X)
    # is on the right of the picture; turned around, it is on the left.
    joints = _walker(1, heading=heading, arms_out=True).joints[0]
    img = R.render_frame(joints, **SMALL)
    left_x = np.nonzero(_mask(img, R.LEFT_COLOR))[1].mean()
    right_x = np.nonzero(_mask(img, R.RIGHT_COLOR))[1].mean()
    assert (left_x > right_x) == left_on_screen_right


def test_render_frame_overlays_and_highlight():
    joints = _walker(1).joints[0]
    plain = R.render_frame(joints, inset=False, **SMALL)
    red = R.render_frame(joints, highlight=True, inset=False, **SMALL)
    assert _mask(red, R.HIGHLIGHT_COLOR).sum() > 200  # skeleton and border
    assert not _mask(red, R.LEFT_COLOR).any()
    with_target = R.render_frame(joints, target=[1.0, 0.5], inset=False, **SMALL)
    assert _mask(with_target, R.TARGET_COLOR).sum() > 10 and not _mask(plain, R.TARGET_COLOR).any()
    with_obstacle = R.render_frame(joints, obstacles=[[0.8, 0.8, 0.3]], inset=False, **SMALL)
    assert np.abs(with_obstacle.astype(int) - plain).sum() > 1000
    # A far waypoint route turns the map on by default; it only occupies the top-right corner.
    mapped = R.render_frame(joints, waypoints=[[0, 5], [5, 10]], path=[[0, 0], [0, 0.1]], **SMALL)
    diff = np.abs(mapped.astype(int) - plain).sum(-1) > 0
    assert diff[:45, 100:].any() and not diff[60:, :80].any()


def test_render_frame_rejects_bad_input():
    with pytest.raises(ValueError, match=r"\(22, 3\)"):
        R.render_frame(np.zeros((21, 3)))
    with pytest.raises(ValueError, match="NaN"):
        R.render_frame(np.full((22, 3), np.nan))
    joints = _walker(1).joints[0]
    with pytest.raises(ValueError, match="waypoints"):
        R.render_frame(joints, waypoints=np.zeros((3, 4)))
    with pytest.raises(ValueError, match="obstacles"):
        R.render_frame(joints, obstacles=[[0.0, 1.0, -0.5]])


def test_render_video_mp4_frames_and_highlight(tmp_path):
    motion = _walker(12)
    out = R.render_video(motion, tmp_path / "clip.mp4", highlight_frames=[4, 5], **SMALL)
    frames = iio.imread(out, index=None)
    assert frames.shape == (12, 120, 160, 3)
    flagged = [_mask(f, R.HIGHLIGHT_COLOR, 60).sum() > 200 for f in frames]
    assert flagged == [i in (4, 5) for i in range(12)]
    # The follow camera keeps the walker in the middle although it moves 0.6 m.
    for f in (frames[0], frames[-1]):
        cols = np.nonzero(_mask(f, R.LEFT_COLOR, 60))[1]
        assert abs(cols.mean() - 80) < 20


def test_render_video_gif_with_other_fps(tmp_path):
    motion = _walker(12)
    motion.waypoints = np.array([[0.0, 1.0, 10.0], [1.0, 2.0, np.nan]], np.float32)
    out = R.render_video(motion, tmp_path / "clip.gif", fps=10, obstacles=[[1, 1, 0.2]], **SMALL)
    frames = iio.imread(out, index=None)
    assert frames.shape[:3] == (6, 120, 160)
    assert iio.immeta(out)["duration"] == 100


def test_render_video_fixed_camera_frames_the_whole_route(tmp_path):
    motion = _walker(40, heading=0.5, speed=4.0)  # 8 m: far outside a follow view
    frames = iio.imread(R.render_video(motion, tmp_path / "fixed.mp4", camera="fixed", **SMALL), index=None)
    cols = [np.nonzero(_mask(f, R.LEFT_COLOR, 60))[1] for f in (frames[0], frames[-1])]
    assert all(len(c) > 0 for c in cols)
    assert abs(cols[0].mean() - cols[1].mean()) > 30  # the camera stays put, the walker moves


def test_render_video_rejects_bad_arguments(tmp_path):
    motion = _walker(4)
    with pytest.raises(ValueError, match=r"unknown video type '\.avi'"):
        R.render_video(motion, tmp_path / "clip.avi")
    with pytest.raises(ValueError, match="highlight frame 9"):
        R.render_video(motion, tmp_path / "clip.mp4", highlight_frames=[9])
    with pytest.raises(ValueError, match="camera"):
        R.render_video(motion, tmp_path / "clip.mp4", camera="orbit")
    with pytest.raises(ValueError, match="even"):
        R.render_video(motion, tmp_path / "clip.mp4", width=161, height=120)


def test_plot_path_writes_png(tmp_path):
    a, b = _walker(45), _walker(45, heading=1.0)
    b.text = "a person glides to the left"
    wps = [[0.0, 1.0, 20.0], [1.5, 2.0, 40.0], [0.0, 3.0, np.nan]]
    out = R.plot_path([a, b], tmp_path / "paths.png", waypoints=wps, obstacles=[[1, 1, 0.3]], title="two")
    img = iio.imread(out)
    assert img.ndim == 3 and img.shape[0] > 300 and img.std() > 10
    dense = np.stack([np.zeros(50), np.linspace(0, 2, 50)], -1)  # a waypoint every frame: a line
    assert R.plot_path(a, tmp_path / "dense.png", waypoints=dense).is_file()
    with pytest.raises(ValueError, match=r"\.png"):
        R.plot_path(a, tmp_path / "paths.jpg")
    with pytest.raises(ValueError, match="at least one"):
        R.plot_path([], tmp_path / "none.png")


def test_cli_show_npz(tmp_path, capsys):
    src = _walker(10).save(tmp_path / "walk.npz")
    out, plot = tmp_path / "walk.mp4", tmp_path / "walk.png"
    assert main(["show", str(src), "--out", str(out), "--plot", str(plot)]) == 0
    assert iio.imread(out, index=None).shape[0] == 10
    assert iio.imread(plot).ndim == 3
    assert "wrote" in capsys.readouterr().out
    assert main(["show", str(src), "--out", str(tmp_path / "walk.avi")]) == 2
    assert "unknown video type" in capsys.readouterr().err
    assert main(["show", str(tmp_path / "missing.npz"), "--out", str(out)]) == 2


def test_render_real_clip(tmp_path):
    joints_file = DATA / "humanml3d_sample" / "new_joints" / "012314.npy"
    if not joints_file.is_file():
        pytest.skip(f"HumanML3D reference clip not found at {joints_file} (shared data is not present)")
    motion = Motion(np.load(joints_file), text="a real HumanML3D clip")
    frames = iio.imread(R.render_video(motion, tmp_path / "real.mp4", fps=5, **SMALL), index=None)
    assert frames.shape[0] == 43  # 170 frames at 20 fps = 8.5 s -> 42.5 frames at 5 fps, rounded up
    assert all(_mask(f, R.LEFT_COLOR, 60).sum() > 10 for f in frames)


def test_cli_show_real_bvh(tmp_path):
    bvh = DATA / "bandai" / "dataset-2" / "bvh" / "dataset-2_walk-turn-left_normal_001.bvh.gz"
    if not bvh.is_file():
        pytest.skip(f"Bandai BVH not found at {bvh} (shared data is not present)")
    out = tmp_path / "turn.gif"
    assert main(["show", str(bvh), "--out", str(out), "--fps", "5", "--plot", str(tmp_path / "t.png")]) == 0
    assert iio.imread(out, index=None).shape[0] > 10
