"""The files motion trackers read: mjlab's tracking npz, GMR's pickle, a LAFAN-style CSV.

Keys, shapes, dtypes, joint and body orders and quaternion conventions of each, round trips through
`load_robot_motion`, a known pose (a root turned 90 degrees about +Z) and a known motion (a root
spinning at a constant rate), and the checks that refuse bad clips and foreign files."""

from __future__ import annotations

import pickle
from pathlib import Path

import mujoco
import numpy as np
import pytest

import motion_env
from motion_env.retarget import RobotMotion, load_robot, load_robot_motion
from motion_env.retarget.tracking import body_names

DATA = Path(__file__).resolve().parent / "data"
# mjlab's G1 (its tracking task reads bodies and joints in this order), root first.
G1_BODIES = (
    "pelvis", "left_hip_pitch_link", "left_hip_roll_link", "left_hip_yaw_link", "left_knee_link",
    "left_ankle_pitch_link", "left_ankle_roll_link", "right_hip_pitch_link", "right_hip_roll_link",
    "right_hip_yaw_link", "right_knee_link", "right_ankle_pitch_link", "right_ankle_roll_link",
    "waist_yaw_link", "waist_roll_link", "torso_link", "left_shoulder_pitch_link",
    "left_shoulder_roll_link", "left_shoulder_yaw_link", "left_elbow_link", "left_wrist_roll_link",
    "left_wrist_pitch_link", "left_wrist_yaw_link", "right_shoulder_pitch_link",
    "right_shoulder_roll_link", "right_shoulder_yaw_link", "right_elbow_link", "right_wrist_roll_link",
    "right_wrist_pitch_link", "right_wrist_yaw_link",
)  # fmt: skip
GMR_KEYS = {"fps", "root_pos", "root_rot", "dof_pos", "local_body_pos", "link_body_list"}
H = np.sqrt(0.5)


@pytest.fixture(scope="module")
def g1_clip(waving_clip) -> RobotMotion:
    return motion_env.retarget(waving_clip(frames=12), robot="unitree_g1", fps=50)


def _spinning(robot: str = "unitree_g1", rate: float = 2.0, frames: int = 20, fps: float = 50) -> RobotMotion:
    """The robot in its home pose, root 0.8 m up, turning about +Z at `rate` rad/s from yaw 0."""
    bot = load_robot(robot)
    yaw = rate * np.arange(frames) / fps
    qpos = np.tile(bot.home, (frames, 1))
    qpos[:, :3] = (0.3, -0.2, 0.8)
    qpos[:, 3:7] = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], axis=-1)
    return RobotMotion(qpos, fps, bot.joint_names, robot)


def _turned(robot: str = "unitree_g1") -> RobotMotion:
    """Three frames of the home pose with the root turned +90 degrees about +Z."""
    clip = _spinning(robot, rate=0.0, frames=3)
    clip.qpos[:, 3:7] = (H, 0.0, 0.0, H)
    return clip


def test_mjlab_keys_shapes_dtypes_and_orders(g1_clip: RobotMotion, tmp_path: Path) -> None:
    path = g1_clip.save(tmp_path / "clip.npz", "mjlab")
    bot = load_robot("unitree_g1")
    with np.load(path) as data:  # allow_pickle=False, as mjlab's MotionLoader
        t, nj, nb = g1_clip.num_frames, 29, 30
        shapes = {
            "joint_pos": (t, nj), "joint_vel": (t, nj), "body_pos_w": (t, nb, 3), "body_quat_w": (t, nb, 4),
            "body_lin_vel_w": (t, nb, 3), "body_ang_vel_w": (t, nb, 3),
        }  # fmt: skip
        for key, shape in shapes.items():
            assert data[key].shape == shape and data[key].dtype == np.float32, key
        assert data["fps"].tolist() == [50.0]
        assert tuple(data["joint_names"]) == bot.joint_names == g1_clip.joint_names
        assert tuple(data["body_names"]) == G1_BODIES == body_names(bot)
        np.testing.assert_allclose(data["joint_pos"], g1_clip.dof_pos, atol=1e-6)
        np.testing.assert_allclose(data["body_pos_w"][:, 0], g1_clip.root_pos, atol=1e-6)
        np.testing.assert_allclose(data["body_quat_w"][:, 0], g1_clip.root_rot, atol=1e-6)  # w first
        np.testing.assert_allclose(np.linalg.norm(data["body_quat_w"], axis=-1), 1.0, atol=1e-6)
        # Finite differences at 50 fps, central inside the clip (torch.gradient, as csv_to_npz).
        np.testing.assert_allclose(data["joint_vel"], np.gradient(g1_clip.dof_pos, 0.02, axis=0), atol=1e-4)
        lin = np.gradient(g1_clip.root_pos, 0.02, axis=0)
        np.testing.assert_allclose(data["body_lin_vel_w"][:, 0], lin, atol=1e-4)
    back = load_robot_motion(path)
    np.testing.assert_allclose(back.qpos, g1_clip.qpos, atol=1e-6)
    assert (back.fps, back.robot, back.joint_names) == (50.0, "unitree_g1", g1_clip.joint_names)


def test_mjlab_resamples_to_50_fps(waving_clip, tmp_path: Path) -> None:
    clip = motion_env.retarget(waving_clip(frames=10), robot="booster_t1", fps=20)  # 10 frames, 0.45 s
    with np.load(clip.save(tmp_path / "t1.npz", "mjlab")) as data:
        assert data["joint_pos"].shape == (23, 23) and data["fps"].tolist() == [50.0]
        assert data["body_names"][0] == "Trunk" and data["body_pos_w"].shape[1] == 24
        # Frames 0, 5, 10, 20 at 50 fps are frames 0, 2, 4, 8 at 20 fps.
        np.testing.assert_allclose(data["joint_pos"][[0, 5, 10, 20]], clip.dof_pos[[0, 2, 4, 8]], atol=1e-6)


def test_known_pose_quaternion_orders(tmp_path: Path) -> None:
    """A root turned +90 degrees about +Z: (w, x, y, z) = (0.707, 0, 0, 0.707) in qpos and mjlab,
    (x, y, z, w) = (0, 0, 0.707, 0.707) in GMR's pickle and the LAFAN-style CSV."""
    clip = _turned()
    with np.load(clip.save(tmp_path / "a.npz", "mjlab")) as data:
        np.testing.assert_allclose(data["body_quat_w"][0, 0], (H, 0, 0, H), atol=1e-6)
        # The left hip is to the robot's left (+y); turned 90 degrees left, it is behind (-x).
        rel = data["body_pos_w"][0, 1] - data["body_pos_w"][0, 0]
        assert rel[0] < -0.05 and abs(rel[1]) < 0.02
    with (clip.save(tmp_path / "a.pkl")).open("rb") as f:
        gmr = pickle.load(f)
    np.testing.assert_allclose(gmr["root_rot"][0], (0, 0, H, H), atol=1e-9)
    row = np.loadtxt(clip.save(tmp_path / "a.csv", "lafan_csv"), delimiter=",")[0]
    np.testing.assert_allclose(row[3:7], (0, 0, H, H), atol=1e-6)
    with np.load(clip.save(tmp_path / "b.npz")) as data:
        assert str(data["root_rot_order"]) == "xyzw"
        np.testing.assert_allclose(data["root_rot"][0], (0, 0, H, H), atol=1e-9)


def test_spinning_root_gives_body_origin_velocities(tmp_path: Path) -> None:
    """Every body turns at the root's rate; each body's origin (not its centre of mass) moves at
    omega x (origin - root)."""
    clip = _spinning(rate=2.0)
    with np.load(clip.save(tmp_path / "spin.npz", "mjlab")) as data:
        spin = np.broadcast_to((0, 0, 2.0), (20, 30, 3))
        np.testing.assert_allclose(data["body_ang_vel_w"], spin, atol=1e-4)
        rel = data["body_pos_w"] - data["body_pos_w"][:, :1]
        expected = np.cross(np.array([0.0, 0.0, 2.0]), rel)
        np.testing.assert_allclose(data["body_lin_vel_w"], expected, atol=1e-4)
        np.testing.assert_allclose(data["joint_vel"], 0.0, atol=1e-6)


def test_gmr_pickle_keys_and_round_trip(g1_clip: RobotMotion, tmp_path: Path) -> None:
    path = g1_clip.save(tmp_path / "clip.pkl")  # .pkl means gmr
    with path.open("rb") as f:
        data = pickle.load(f)
    assert GMR_KEYS <= set(data) and data["fps"] == 50 and isinstance(data["fps"], int)
    assert data["root_pos"].shape == (g1_clip.num_frames, 3) and data["dof_pos"].shape[1] == 29
    np.testing.assert_array_equal(data["root_rot"], g1_clip.qpos[:, [4, 5, 6, 3]])  # x, y, z, w
    assert data["local_body_pos"].shape == (g1_clip.num_frames, 30, 3)
    assert tuple(data["link_body_list"]) == G1_BODIES and tuple(data["joint_names"]) == g1_clip.joint_names
    np.testing.assert_allclose(data["local_body_pos"][:, 0], 0.0, atol=1e-6)  # the root at the origin
    back = load_robot_motion(path)
    np.testing.assert_array_equal(back.qpos, g1_clip.qpos)
    assert (back.fps, back.robot) == (50.0, "unitree_g1")


def test_gmr_pickle_that_runs_code_is_refused(tmp_path: Path) -> None:
    class Evil:
        def __reduce__(self):
            return (print, ("this should not run",))

    path = tmp_path / "evil.pkl"
    path.write_bytes(pickle.dumps({"fps": 30, "root_pos": Evil()}))
    with pytest.raises(ValueError, match=r"evil.pkl: not a GMR motion pickle.*refused .*builtins.print"):
        load_robot_motion(path)


def test_lafan_csv_layout_and_round_trip(g1_clip: RobotMotion, tmp_path: Path) -> None:
    path = g1_clip.save(tmp_path / "clip.csv", "lafan_csv")  # 30 fps by default
    text = path.read_text()
    assert not text.startswith("#")
    rows = np.loadtxt(path, delimiter=",")
    frames = int((g1_clip.num_frames - 1) * 30 / 50) + 1
    assert rows.shape == (frames, 7 + 29)
    np.testing.assert_allclose(rows[0, :3], g1_clip.root_pos[0], atol=1e-6)
    np.testing.assert_allclose(rows[0, 3:7], g1_clip.root_rot[0, [1, 2, 3, 0]], atol=1e-6)
    back = load_robot_motion(path, robot="unitree_g1")  # 30 fps unless told
    assert back.fps == 30 and back.joint_names == g1_clip.joint_names and back.num_frames == frames
    np.testing.assert_allclose(back.qpos[0], g1_clip.qpos[0], atol=1e-5)
    same_rate = g1_clip.save(tmp_path / "clip50.csv", "lafan_csv", fps=50)
    np.testing.assert_allclose(load_robot_motion(same_rate, fps=50).qpos, g1_clip.qpos, atol=1e-5)


def test_foreign_lafan_csv_errors_name_file_and_column(g1_clip: RobotMotion, tmp_path: Path) -> None:
    rows = np.loadtxt(g1_clip.save(tmp_path / "ok.csv", "lafan_csv", fps=50), delimiter=",")
    short = tmp_path / "short.csv"
    np.savetxt(short, rows[:, :-2], delimiter=",")
    with pytest.raises(ValueError, match=r"short.csv: 27 joints in columns 8-34, but robot 'unitree_g1'"):
        load_robot_motion(short, robot="unitree_g1")
    wxyz = tmp_path / "wxyz.csv"  # the quaternion written w first: the robot would stand on its head
    np.savetxt(wxyz, np.concatenate([rows[:, :3], rows[:, [6, 3, 4, 5]], rows[:, 7:]], axis=1), delimiter=",")
    with pytest.raises(ValueError, match=r"wxyz.csv: columns 4-7 .*unknown quaternion order"):
        load_robot_motion(wxyz, robot="unitree_g1")
    scaled = tmp_path / "scaled.csv"
    rows[3, 3:7] *= 2
    np.savetxt(scaled, rows, delimiter=",")
    with pytest.raises(ValueError, match=r"scaled.csv: columns 4-7 \(the root quaternion\), row 4: norm 2"):
        load_robot_motion(scaled)
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("0,0,0.8,0,0,0,1,0.1\n0,0,0.8,0,0,0,1\n")
    with pytest.raises(ValueError, match="ragged.csv: not a CSV of numbers"):
        load_robot_motion(ragged)


def test_exports_validate_before_writing(g1_clip: RobotMotion, tmp_path: Path) -> None:
    bad = RobotMotion(g1_clip.qpos.copy(), 50, g1_clip.joint_names, "unitree_g1")
    bad.qpos[4, 10] = np.nan
    for fmt, name in (("mjlab", "n.npz"), ("gmr", "n.pkl"), ("lafan_csv", "n.csv"), ("npz", "m.npz")):
        with pytest.raises(ValueError, match=rf"{name}: qpos has a non-finite value at index \(4, 10\)"):
            bad.save(tmp_path / name, fmt)
        assert not (tmp_path / name).exists()
    unnormed = RobotMotion(g1_clip.qpos.copy(), 50, g1_clip.joint_names, "unitree_g1")
    unnormed.qpos[2, 3:7] = (1, 1, 0, 0)
    with pytest.raises(ValueError, match=r"u.pkl: the root quaternion .* index \(2,\) is not a unit"):
        unnormed.save(tmp_path / "u.pkl")
    other = RobotMotion(g1_clip.qpos[:, :-1], 50, g1_clip.joint_names[:-1], "unitree_g1")
    with pytest.raises(ValueError, match=r"o.npz: the clip has 28 joints but robot 'unitree_g1' has 29"):
        other.save(tmp_path / "o.npz", "mjlab")
    renamed = RobotMotion(g1_clip.qpos, 50, ("hip", *g1_clip.joint_names[1:]), "unitree_g1")
    with pytest.raises(ValueError, match=r"r.pkl: the clip's joint 0 is 'hip', robot 'unitree_g1''s is"):
        renamed.save(tmp_path / "r.pkl")
    with pytest.raises(ValueError, match=r"x.csv: format 'mjlab' is written to a .npz file"):
        g1_clip.save(tmp_path / "x.csv", "mjlab")
    with pytest.raises(ValueError, match="unknown robot motion format 'bvh'"):
        g1_clip.save(tmp_path / "x.bvh", "bvh")
    anonymous = RobotMotion(g1_clip.qpos, 50, g1_clip.joint_names, "")
    with pytest.raises(ValueError, match=r"a.npz: the mjlab format needs the robot's model"):
        anonymous.save(tmp_path / "a.npz", "mjlab")


def test_mjlab_npz_from_another_tool(g1_clip: RobotMotion, tmp_path: Path) -> None:
    """mjlab's own csv_to_npz writes no names: the robot names the joints, the root is body 0."""
    with np.load(g1_clip.save(tmp_path / "ours.npz", "mjlab")) as data:
        plain = {k: data[k] for k in ("fps", "joint_pos", "joint_vel", "body_pos_w", "body_quat_w")}
    np.savez(tmp_path / "theirs.npz", **plain)
    back = load_robot_motion(tmp_path / "theirs.npz", robot="unitree_g1")
    assert back.joint_names == g1_clip.joint_names
    np.testing.assert_allclose(back.qpos, g1_clip.qpos, atol=1e-6)
    with pytest.raises(ValueError, match=r"theirs.npz: 29 joints in joint_pos, but robot 'booster_t1'"):
        load_robot_motion(tmp_path / "theirs.npz", robot="booster_t1")
    np.savez(tmp_path / "other.npz", poses=np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"other.npz: neither a robot motion npz .* keys are \['poses'\]"):
        load_robot_motion(tmp_path / "other.npz")


def test_matches_mjlab_csv_to_npz(tmp_path: Path) -> None:
    """mjlab's own csv_to_npz (mjlab 1.6.0, CPU) on our lafan_csv export of a G1 clip agrees with
    our mjlab export of the same clip (data/README.md): positions and quaternions to 1e-6,
    velocities to 1e-4, over the frames both compute alike (all but mjlab's last)."""
    clip = load_robot_motion(DATA / "g1_clip_lafan.csv", robot="unitree_g1", fps=50)
    with np.load(clip.save(tmp_path / "ours.npz", "mjlab")) as data:
        ours = {key: data[key] for key in data.files}
    with np.load(DATA / "mjlab_csv_to_npz_g1.npz") as theirs:
        frames = theirs["joint_pos"].shape[0] - 1
        assert theirs["body_pos_w"].shape[1:] == ours["body_pos_w"].shape[1:] == (30, 3)
        for key in ("joint_pos", "body_pos_w", "body_quat_w"):
            np.testing.assert_allclose(ours[key][:frames], theirs[key][:frames], atol=1e-6, err_msg=key)
        for key in ("joint_vel", "body_lin_vel_w", "body_ang_vel_w"):
            np.testing.assert_allclose(ours[key][:frames], theirs[key][:frames], atol=1e-4, err_msg=key)


def test_t1_bodies_are_its_model_bodies_root_first() -> None:
    bot = load_robot("booster_t1")
    names = body_names(bot)
    assert names[0] == "Trunk" and len(names) == bot.model.nbody - 1
    assert all(mujoco.mj_name2id(bot.model, mujoco.mjtObj.mjOBJ_BODY, n) > 0 for n in names)
