"""Tests of `motion-env replay` (the report as text or JSON, and the MuJoCo video)."""

from __future__ import annotations

import io
import json
from contextlib import redirect_stdout
from pathlib import Path

import pytest

from motion_env.cli import main
from motion_env.replay import corruptions


def test_cli_json_and_video(tmp_path: Path, standing_clip) -> None:
    clip = corruptions.raised(standing_clip(1.5), seconds=0.5, start=10)
    path = clip.save(tmp_path / "clip.npz")
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["replay", str(path), "--json"]) == 0
    result = json.loads(out.getvalue())
    assert result["plausible"] is False and "floating" in result["failed"]

    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["replay", str(path)]) == 0
    assert "NOT PLAUSIBLE" in out.getvalue()

    video = tmp_path / "clip.mp4"
    out = io.StringIO()
    with redirect_stdout(out):
        code = main(["replay", str(path), "--json", "--video", str(video)])
    if code == 2 and not video.exists():
        pytest.skip("offscreen OpenGL rendering is unavailable here (MUJOCO_GL=egl or osmesa)")
    assert code == 0
    assert json.loads(out.getvalue())["video"] == str(video)
    import imageio.v2 as imageio

    frames = imageio.mimread(video)
    assert len(frames) == clip.num_frames
    red = frames[15][..., 0].astype(int) - frames[15][..., 1]
    assert (red > 120).sum() > (frames[2][..., 0].astype(int) - frames[2][..., 1] > 120).sum()


def test_cli_reports_a_bad_file(tmp_path: Path, capsys) -> None:
    assert main(["replay", str(tmp_path / "missing.npz")]) == 2
    # A wrong video type fails at once, before the file is even read.
    assert main(["replay", str(tmp_path / "missing.npz"), "--video", str(tmp_path / "v.avi")]) == 2
    assert "unknown video type" in capsys.readouterr().err
