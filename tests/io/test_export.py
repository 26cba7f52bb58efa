"""Tests for motion export: the BVH writer (motion_env.io.bvh_write), the humanoid reference
(motion_env.replay.export) and `motion-env export`."""

from __future__ import annotations

import gzip
from pathlib import Path

import mujoco
import numpy as np
import pytest

from motion_env import motion as M
from motion_env.cli import main
from motion_env.io import load_bvh, save_bvh
from motion_env.io.bvh_file import bvh_world_positions, read_bvh
from motion_env.io.bvh_write import EULER_ORDER, HELPER_JOINTS, bvh_layout
from motion_env.io.joint_names import map_joint_names
from motion_env.motion.skeleton import BONE_LENGTHS, JOINT_INDEX, JOINT_NAMES, PARENTS, RAW_OFFSETS
from motion_env.motion.types import Motion
from motion_env.replay.export import FIELDS, save_humanoid_npz

MM = 1e-3
# Real takes: a Bandai walk, and CMU takes whose floor load_bvh levels, or whose levelled output
# a second levelling would tilt again (02_08, 05_02): the package's own files are not levelled.
REAL_TAKES = (
    "bandai/dataset-2/bvh/dataset-2_walk-turn-right_normal_004.bvh.gz",
    "bandai/dataset-1/bvh/dataset-1_dash_proud_001.bvh.gz",
    "cmu/bvh/02_08.bvh.gz",
    "cmu/bvh/05_02.bvh.gz",
)


def _posed(dirs: np.ndarray, pelvis: np.ndarray) -> np.ndarray:
    """Joints (T, 22, 3) on the canonical bone lengths from bone directions (T, 22, 3)."""
    joints = np.zeros(dirs.shape)
    joints[:, 0] = pelvis
    for j in range(1, len(JOINT_NAMES)):
        joints[:, j] = joints[:, PARENTS[j]] + dirs[:, j] * BONE_LENGTHS[j]
    return joints


def _hard_poses() -> Motion:
    """Random bone directions, plus poses at gimbal lock and with bones opposite their rest."""
    rng = np.random.default_rng(0)
    dirs = rng.normal(size=(24, 22, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    dirs[:4] = RAW_OFFSETS
    j = JOINT_INDEX
    dirs[0, [j["left_knee"], j["right_knee"]]] = [0.0, 0.0, 1.0]  # thighs forward: ZXY gimbal lock
    dirs[1, j["left_ankle"]] = [0.0, 1.0, 0.0]  # shin folded back along the thigh
    dirs[2, j["left_hip"]] = [-1.0, 0.0, 0.0]  # hip bone opposite its rest direction
    dirs[3, j["spine1"]] = [0.0, -1.0, 0.0]
    return Motion(_posed(dirs, rng.normal(size=(24, 3))), fps=30.0)


def _file_joints(path: Path) -> np.ndarray:
    """(T, 22, 3) metres: the canonical joints of a written file, by its own forward kinematics."""
    bvh = read_bvh(path)
    pos, _ = bvh_world_positions(bvh)
    return pos[:, [bvh.names.index(n) for n in JOINT_NAMES]] / 100.0


def _max_error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(np.asarray(a, float) - np.asarray(b, float), axis=-1).max())


# --- BVH ------------------------------------------------------------------------------------------


def test_header_layout(tmp_path: Path) -> None:
    motion = _hard_poses()
    bvh = read_bvh(save_bvh(motion, tmp_path / "clip.bvh"))
    layout = bvh_layout()
    assert bvh.names == [j.name for j in layout] and len(bvh.names) == 26
    assert set(JOINT_NAMES) | set(HELPER_JOINTS) == set(bvh.names)
    assert bvh.names[0] == "pelvis" and bvh.parents[0] == -1
    rot = tuple(f"{a}rotation" for a in EULER_ORDER)
    assert bvh.channels[0] == ("Xposition", "Yposition", "Zposition", *rot)
    assert all(c == rot for c in bvh.channels[1:]) and EULER_ORDER == "ZXY"
    assert bvh.values.shape == (motion.num_frames, 6 + 3 * 25)
    assert bvh.fps == 30.0
    # Offsets in centimetres along the rest directions; End Sites where the chains end.
    for name in JOINT_NAMES[1:]:
        k, j = bvh.names.index(name), JOINT_INDEX[name]
        np.testing.assert_allclose(bvh.offsets[k], RAW_OFFSETS[j] * BONE_LENGTHS[j] * 100, atol=1e-5)
    for name, (at, child) in HELPER_JOINTS.items():
        k = bvh.names.index(name)
        assert bvh.names[bvh.parents[k]] == at and not bvh.offsets[k].any()
        assert bvh.names[bvh.parents[bvh.names.index(child)]] == name
    leaves = {bvh.names[k] for k in bvh.end_sites}
    assert leaves == {"head", "left_wrist", "right_wrist", "left_foot", "right_foot"}
    # The importer reads the package's names as they are (left_foot is the toe, not the ankle).
    assert map_joint_names(bvh.names) == {
        n: bvh.names.index(n) for n in JOINT_NAMES if not n.startswith("spine")
    }


def test_file_reproduces_the_joints(tmp_path: Path) -> None:
    motion = _hard_poses()
    path = save_bvh(motion, tmp_path / "clip.bvh")
    assert _max_error(_file_joints(path), motion.joints) < 0.01 * MM


def test_round_trip_of_a_generated_clip(tmp_path: Path, random_generator) -> None:
    motion = random_generator.generate("a person walks", np.array([[1.0, 2.0]]), num_frames=32, seed=3)
    path = motion.save_bvh(tmp_path / "walk.bvh")
    assert path == tmp_path / "walk.bvh"
    assert _max_error(_file_joints(path), motion.joints) < 0.01 * MM  # world placement kept
    # load_bvh puts any clip at the origin facing +Z (canonicalize), and nothing else.
    back = load_bvh(path)
    assert back.fps == 20 and back.meta["units"] == "cm" and back.meta["dropped_frames"] == "0"
    assert _max_error(back.joints, M.canonicalize(motion.joints)) < MM


@pytest.mark.parametrize("take", REAL_TAKES)
def test_round_trip_of_real_takes_within_1mm(tmp_path: Path, require_data, take: str) -> None:
    motion = load_bvh(require_data(take))
    back = load_bvh(save_bvh(motion, tmp_path / "take.bvh.gz"))
    assert back.num_frames == motion.num_frames
    assert _max_error(back.joints, motion.joints) < MM


def test_gz_suffix_compresses(tmp_path: Path) -> None:
    motion = _hard_poses()
    plain, packed = save_bvh(motion, tmp_path / "a.bvh"), save_bvh(motion, tmp_path / "a.BVH.gz")
    assert packed.read_bytes()[:2] == b"\x1f\x8b" and packed.stat().st_size < plain.stat().st_size
    assert gzip.decompress(packed.read_bytes()).decode() == plain.read_text()
    assert plain.read_text().startswith("HIERARCHY\nROOT pelvis")


def test_bad_inputs_name_the_file(tmp_path: Path) -> None:
    motion = _hard_poses()
    with pytest.raises(ValueError, match=r"clip\.txt.*\.bvh or \.bvh\.gz"):
        save_bvh(motion, tmp_path / "clip.txt")
    (tmp_path / "afile").write_text("")
    with pytest.raises(OSError, match=r"afile/clip\.bvh: cannot write"):
        save_bvh(motion, tmp_path / "afile" / "clip.bvh")
    motion.joints[5, 3] = np.nan  # Motion checks its joints when made, not after
    with pytest.raises(ValueError, match=r"NaN.*frames \[5\]"):
        motion.save_bvh(tmp_path / "clip.bvh")
    assert not (tmp_path / "clip.bvh").exists()


# --- humanoid reference ---------------------------------------------------------------------------


def test_humanoid_npz_fields(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    still = np.repeat(M.canonicalize(_posed(RAW_OFFSETS[None], np.array([[0.0, 0.9, 0.0]])))[:1], 30, 0)
    joints = still + rng.normal(scale=1e-4, size=still.shape)  # standing, a little noise
    joints[15:, :, 2] += 0.1 * np.arange(15)[:, None]  # then glides forward at 2 m/s
    path = save_humanoid_npz(Motion(joints, fps=20, text="stands"), tmp_path / "ref.npz")
    with np.load(path) as data:
        assert set(data.files) == set(FIELDS)
        d = {k: data[k] for k in data.files}
    n, k = 30, 16
    assert d["fps"] == 20 and d["qpos"].shape == (n, 7 + 4 * k)
    assert d["root_pos"].shape == (n, 3) and d["root_quat_wxyz"].shape == (n, 4)
    assert d["joint_quat_wxyz"].shape == (n, k, 4) and len(d["joint_names"]) == k
    np.testing.assert_allclose(d["root_pos"], d["qpos"][:, :3], atol=1e-6)
    np.testing.assert_allclose(d["root_quat_wxyz"], d["qpos"][:, 3:7], atol=1e-6)
    np.testing.assert_allclose(d["joint_quat_wxyz"].reshape(n, -1), d["qpos"][:, 7:], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(d["joint_quat_wxyz"], axis=-1), 1.0, atol=1e-5)
    assert d["root_pos"][0, 2] == pytest.approx(joints[0, 0, 1], abs=1e-5)  # MuJoCo: z up
    assert list(d["contact_names"]) == ["left_ankle", "left_foot", "right_ankle", "right_foot"]
    contacts = d["foot_contacts"]
    assert contacts.dtype == bool and contacts.shape == (n, 4)
    assert contacts[:15].all() and not contacts[15:].any()
    assert d["joint_positions"].shape == (n, 22, 3) and d["fit_error"].max() < 0.01
    # The body in the file takes the qpos as it is.
    model = mujoco.MjModel.from_xml_string(str(d["humanoid_xml"]))
    assert model.nq == d["qpos"].shape[1]
    assert "stands" in str(d["meta"])


def test_humanoid_npz_of_a_real_take(tmp_path: Path, require_data) -> None:
    motion = load_bvh(require_data(REAL_TAKES[0]))
    with np.load(save_humanoid_npz(motion, tmp_path / "walk.npz")) as data:
        assert data["qpos"].shape[0] == motion.num_frames
        assert data["fit_error"].max() < 0.01
        assert 0.2 < data["foot_contacts"].mean() < 0.9  # walking: each foot down part of the time


def test_humanoid_npz_bad_inputs(tmp_path: Path) -> None:
    motion = _hard_poses()
    with pytest.raises(ValueError, match=r"ref\.bvh.*\.npz"):
        save_humanoid_npz(motion, tmp_path / "ref.bvh")
    with pytest.raises(ValueError, match="mass"):
        save_humanoid_npz(motion, tmp_path / "ref.npz", mass=0)
    motion.joints[2] = np.nan
    with pytest.raises(ValueError, match=r"frames \[2\]"):
        save_humanoid_npz(motion, tmp_path / "ref.npz")


# --- motion-env export ----------------------------------------------------------------------------


def test_cli_export(tmp_path: Path, capsys) -> None:
    src = _hard_poses().save(tmp_path / "clip.npz")
    bvh, ref = tmp_path / "out" / "clip.bvh.gz", tmp_path / "clip_ref.npz"
    args = ["export", str(src), "--bvh", str(bvh), "--humanoid-npz", str(ref)]
    assert main(args) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 2 and lines[0].startswith(f"wrote {bvh}") and lines[1].startswith(f"wrote {ref}")
    assert read_bvh(bvh).num_frames == 24 and np.load(ref)["qpos"].shape[0] == 24
    # Outputs are not replaced without --overwrite; a BVH reads back in as a motion file.
    assert main(args) == 2
    assert "exists" in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0
    assert main(["export", str(bvh), "--bvh", str(tmp_path / "again.bvh")]) == 0
    # User errors: one line, exit code 2.
    for bad in (
        ["export", str(src)],
        ["export", str(src), "--bvh", str(tmp_path / "x.fbx")],
        ["export", str(src), "--humanoid-npz", str(tmp_path / "x.json")],
        ["export", str(tmp_path / "missing.npz"), "--bvh", str(tmp_path / "m.bvh")],
    ):
        capsys.readouterr()
        assert main(bad) == 2
        err = capsys.readouterr().err
        assert err.startswith("motion-env export: error:") and err.count("\n") == 1
