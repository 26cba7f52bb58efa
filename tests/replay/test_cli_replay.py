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


def test_strict_exits_1_unless_plausible(tmp_path: Path, standing_clip, capsys) -> None:
    still = standing_clip(1.5).save(tmp_path / "still.npz")
    # longer than a jump's flight (retarget.flight.MAX_FLIGHT): a shorter lift is retargeted as a jump
    raised = corruptions.raised(standing_clip(1.5), seconds=1.0, start=10).save(tmp_path / "raised.npz")
    short = standing_clip(0.5).save(tmp_path / "short.npz")
    assert main(["replay", str(still), "--strict"]) == 0
    assert "verdict: PLAUSIBLE" in capsys.readouterr().out
    assert main(["replay", str(raised)]) == 0  # without --strict the verdict is only reported
    assert main(["replay", str(raised), "--strict"]) == 1
    captured = capsys.readouterr()
    assert "NOT PLAUSIBLE" in captured.out
    assert captured.err.strip().splitlines()[-1] == "motion-env replay: NOT PLAUSIBLE (--strict): exit code 1"
    assert main(["replay", str(short), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["plausible"] is None  # too short to judge
    assert main(["replay", str(short), "--strict"]) == 1
    captured = capsys.readouterr()
    assert "too short" in captured.out and "too short to judge (--strict)" in captured.err


def test_refuses_to_replace_a_video(tmp_path: Path, standing_clip, capsys) -> None:
    path = standing_clip(1.0).save(tmp_path / "clip.npz")
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"keep")
    assert main(["replay", str(path), "--video", str(video)]) == 2
    err = capsys.readouterr().err
    assert (
        err.strip()
        == f"motion-env replay: error: {video} exists: nothing was written (pass --overwrite to replace it)"
    )
    assert video.read_bytes() == b"keep"


def test_robot_replay_judges_the_retargeted_clip(tmp_path: Path, standing_clip, capsys) -> None:
    pytest.importorskip("mink", reason="the optional 'robots' extra (mink) is not installed")
    still = standing_clip(1.5).save(tmp_path / "still.npz")
    # longer than a jump's flight (retarget.flight.MAX_FLIGHT): a shorter lift is retargeted as a jump
    raised = corruptions.raised(standing_clip(1.5), seconds=1.0, start=10).save(tmp_path / "raised.npz")
    assert main(["replay", str(still), "--robot", "unitree_g1", "--strict"]) == 0
    out = capsys.readouterr().out
    assert "verdict: PLAUSIBLE" in out and "joint_limits" in out and "self_collision" in out
    assert main(["replay", str(raised), "--robot", "unitree_g1", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["plausible"] is False and "floating" in result["failed"]
    assert result["fps"] == 50 and "self_collision" in result["checks"]  # the robot's checks
    assert main(["replay", str(raised), "--robot", "unitree_g1", "--strict"]) == 1
    assert "NOT PLAUSIBLE (--strict)" in capsys.readouterr().err
    # The humanoid's own flags do not apply; an unknown robot fails in one line.
    assert main(["replay", str(still), "--robot", "unitree_g1", "--mass", "60"]) == 2
    assert "do not apply with --robot" in capsys.readouterr().err
    assert main(["replay", str(still), "--robot", "no_such_robot"]) == 2
    assert "unknown robot" in capsys.readouterr().err
