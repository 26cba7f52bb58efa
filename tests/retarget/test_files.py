"""RobotMotion files: CSV and npz round trips, GMR's npz fields."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import motion_env
from motion_env.retarget import RobotMotion, load_robot_motion


@pytest.fixture(scope="module")
def clip(waving_clip) -> RobotMotion:
    return motion_env.retarget(waving_clip(frames=10), robot="booster_t1", fps=30)


def test_csv_round_trip(clip: RobotMotion, tmp_path: Path) -> None:
    with pytest.warns(UserWarning, match="lafan_csv"):  # pointing LAFAN-style tool users there
        path = clip.save(tmp_path / "clip.csv")
    header = [line for line in path.read_text().splitlines() if line.startswith("#")]
    assert any(line == "# columns: " + ",".join(clip.columns) for line in header)
    assert np.loadtxt(path, delimiter=",").shape == clip.qpos.shape  # plain numbers under the header
    back = load_robot_motion(path)
    np.testing.assert_allclose(back.qpos, clip.qpos, atol=1e-6)
    assert (back.fps, back.joint_names, back.robot) == (clip.fps, clip.joint_names, clip.robot)


def test_npz_has_gmr_fields_and_round_trips(clip: RobotMotion, tmp_path: Path) -> None:
    path = clip.save(tmp_path / "clip.npz")
    with np.load(path) as data:
        assert str(data["root_rot_order"]) == "xyzw"
        np.testing.assert_array_equal(data["root_rot"], clip.qpos[:, [4, 5, 6, 3]])  # x, y, z, w
        np.testing.assert_array_equal(data["root_pos"], clip.qpos[:, :3])
        np.testing.assert_array_equal(data["dof_pos"], clip.qpos[:, 7:])
        assert float(data["fps"]) == 30 and tuple(data["joint_names"]) == clip.joint_names
    back = load_robot_motion(path)
    np.testing.assert_array_equal(back.qpos, clip.qpos)
    np.testing.assert_array_equal(back.residuals, clip.residuals)
    assert back.residual_names == clip.residual_names and back.robot == "booster_t1"


def test_bad_files(clip: RobotMotion, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="saved as .csv, .npz or .pkl"):
        clip.save(tmp_path / "clip.txt")
    with pytest.raises(FileNotFoundError, match="no robot motion file"):
        load_robot_motion(tmp_path / "missing.csv")
    (tmp_path / "plain.csv").write_text("1,2,3\n")
    with pytest.raises(ValueError, match="plain.csv: 3 columns per row; a LAFAN-style CSV has"):
        load_robot_motion(tmp_path / "plain.csv")  # no header: read as a LAFAN-style CSV
    (tmp_path / "bad_header.csv").write_text("# robot: g1\n1,2,3\n")
    with pytest.raises(ValueError, match="bad_header.csv: not a robot motion CSV"):
        load_robot_motion(tmp_path / "bad_header.csv")
