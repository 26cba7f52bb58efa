"""`motion-env retarget` and examples/retarget_to_robot.py (random model, tiny settings)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from motion_env.args import parse_dataclass
from motion_env.cli import main
from motion_env.retarget import load_robot_motion

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "retarget_to_robot.py"


def test_cli_writes_csv_npz_and_refuses_to_overwrite(tmp_path: Path, waving_clip, capsys) -> None:
    src = waving_clip(frames=10).save(tmp_path / "wave.npz")
    out = tmp_path / "wave_g1.csv"
    assert main(["retarget", str(src), "--robot", "unitree_g1", "--out", str(out), "--fps", "30"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"wrote {out} (unitree_g1, 14 frames at 30 fps")
    clip = load_robot_motion(out)
    assert clip.qpos.shape == (14, 36) and clip.fps == 30 and clip.robot == "unitree_g1"

    assert main(["retarget", str(src), "--out", str(out)]) == 2
    assert "exists: nothing was written (pass --overwrite" in capsys.readouterr().err
    assert main(["retarget", str(src), "--out", str(out), "--overwrite", "--robot", "booster_t1"]) == 0
    assert load_robot_motion(out).qpos.shape[1] == 30

    npz = tmp_path / "wave_t1.npz"
    assert main(["retarget", str(src), "--robot", "booster_t1", "--out", str(npz)]) == 0
    with np.load(npz) as data:
        assert str(data["root_rot_order"]) == "xyzw" and data["dof_pos"].shape == (23, 23)


@pytest.mark.parametrize(
    ("flags", "message"),
    [
        (["--out", "x.txt"], "--out x.txt: must end in .csv or .npz"),
        (["--out", "x.csv", "--robot", "nao"], "unknown robot 'nao': the known robots are"),
        (["--out", "x.csv", "--fps", "0"], "--fps must be a positive number"),
        (["--out", "x.csv", "--video", "x.avi"], "--video x.avi: must end in .mp4 or .gif"),
    ],
)
def test_cli_user_errors(
    flags: list[str], message: str, tmp_path: Path, waving_clip, capsys, monkeypatch
) -> None:
    monkeypatch.chdir(tmp_path)
    src = waving_clip(frames=4).save(tmp_path / "wave.npz")
    assert main(["retarget", str(src), *flags]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "x.csv").exists()


def test_cli_formats_for_trackers(tmp_path: Path, waving_clip, capsys) -> None:
    src = waving_clip(frames=10).save(tmp_path / "wave.npz")
    out = tmp_path / "wave_g1.npz"
    assert main(["retarget", str(src), "--format", "mjlab", "--out", str(out)]) == 0
    assert "(unitree_g1, 23 frames at 50 fps, format mjlab" in capsys.readouterr().out
    with np.load(out) as data:
        assert data["body_quat_w"].shape == (23, 30, 4) and data["joint_pos"].dtype == np.float32
    lafan = tmp_path / "wave_g1.csv"
    assert main(["retarget", str(src), "--format", "lafan_csv", "--out", str(lafan)]) == 0
    assert "14 frames at 30 fps, format lafan_csv" in capsys.readouterr().out  # 30 fps by default
    assert np.loadtxt(lafan, delimiter=",").shape == (14, 36)
    pkl = tmp_path / "wave_t1.pkl"
    assert main(["retarget", str(src), "--robot", "booster_t1", "--out", str(pkl), "--soft-limit", ".8"]) == 0
    assert load_robot_motion(pkl).robot == "booster_t1"
    assert main(["retarget", str(src), "--format", "gmr", "--out", str(tmp_path / "x.csv")]) == 2
    assert "--out " in capsys.readouterr().err
    assert main(["retarget", str(src), "--out", str(tmp_path / "y.csv"), "--soft-limit", "2"]) == 2
    assert "--soft-limit must be in (0, 1]" in capsys.readouterr().err


def test_cli_show_mapping(capsys) -> None:
    assert main(["retarget", "--robot", "booster_t1", "--show-mapping"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("robot booster_t1: ") and "<- left_wrist position (cost 5)" in out
    assert main(["retarget", "--robot", "booster_t1"]) == 2
    assert "--out is required" in capsys.readouterr().err


def test_cli_refuses_a_pickled_motion_clearly(tmp_path: Path, capsys) -> None:
    """A motion .npz whose joints are an object array (clips of different lengths in one file)."""
    joints = np.empty(2, dtype=object)
    joints[0], joints[1] = np.zeros((3, 22, 3)), np.zeros((4, 22, 3))
    np.savez(tmp_path / "ragged.npz", joints=joints)
    assert main(["retarget", str(tmp_path / "ragged.npz"), "--out", str(tmp_path / "r.csv")]) == 2
    err = capsys.readouterr().err
    assert "ragged.npz: 'joints' is a pickled object array" in err and "allow_pickle" not in err


def test_cli_video(tmp_path: Path, waving_clip, capsys) -> None:
    src = waving_clip(frames=6).save(tmp_path / "wave.npz")
    video = tmp_path / "wave.gif"
    code = main(
        ["retarget", str(src), "--out", str(tmp_path / "w.csv"), "--video", str(video), "--fps", "10"]
    )
    if code == 2 and not video.exists():
        pytest.skip("offscreen OpenGL rendering is unavailable here (MUJOCO_GL=egl or osmesa)")
    assert code == 0 and video.stat().st_size > 0
    assert capsys.readouterr().out.count("wrote ") == 2


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:the project's robot CSV")  # the example writes it on purpose
def test_example_runs(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("example_retarget_to_robot", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    flags = ["--random-model", "--video", "gif", "--width", "96", "--height", "64", "--frames", "12"]
    result = module.main(parse_dataclass(module.Args, [*flags, "--out", str(tmp_path)]))
    assert set(result["robots"]) == {"unitree_g1", "booster_t1"}
    for robot, numbers in result["robots"].items():
        assert numbers["range_violations"] == 0 and numbers["penetration_cm"] <= 1.5
        assert load_robot_motion(tmp_path / f"{robot}.csv").num_frames == numbers["frames"]
        assert (tmp_path / f"{robot}.gif").stat().st_size > 0
    assert json.loads((tmp_path / "result.json").read_text())["args"]["random_model"] is True


@pytest.mark.filterwarnings("ignore::UserWarning")  # the guessed mapping is said: tested elsewhere
def test_video_of_an_mjcf_without_a_floor(tmp_path: Path, waving_clip) -> None:
    """The G1's body XML has no floor and no light: the video adds them."""
    import motion_env
    from motion_env.retarget.robot import ROBOTS_DIR
    from motion_env.retarget.video import render_robot_video

    result = motion_env.retarget(waving_clip(frames=6), robot=ROBOTS_DIR / "unitree_g1" / "g1.xml", fps=10)
    try:
        video = render_robot_video(result, tmp_path / "g1.mp4", width=64, height=48)
    except RuntimeError:
        pytest.skip("offscreen OpenGL rendering is unavailable here (MUJOCO_GL=egl or osmesa)")
    import imageio.v2 as imageio

    frames = imageio.mimread(video)
    assert len(frames) == result.num_frames and frames[0].shape == (48, 64, 3)
