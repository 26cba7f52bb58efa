"""Tests for motion_env.io (BVH): parsing, kinematics, joint matching and bad inputs (real mocap:
test_bvh_real_data.py)."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from motion_env import motion as M
from motion_env import skeleton as S
from motion_env.io.bvh import load_bvh
from motion_env.io.bvh_file import bvh_world_positions, read_bvh
from motion_env.io.joint_names import map_joint_names

# --- synthetic BVH files ---------------------------------------------------------------------------

# A small humanoid in centimetres, Y up, facing +Z (its left is +X), arms out (T-pose) at rest.
# role -> (parent role, offset). Roles are the MotionBuilder names; NAMINGS renames them.
_SKELETON: dict[str, tuple[str | None, tuple[float, float, float]]] = {
    "Hips": (None, (0.0, 95.0, 0.0)),
    "Spine": ("Hips", (0.0, 10.0, 0.0)),
    "Chest": ("Spine", (0.0, 15.0, 0.0)),
    "Neck": ("Chest", (0.0, 20.0, 0.0)),
    "Head": ("Neck", (0.0, 10.0, 0.0)),
    "LeftShoulder": ("Chest", (3.0, 15.0, 0.0)),
    "LeftArm": ("LeftShoulder", (12.0, 0.0, 0.0)),
    "LeftForeArm": ("LeftArm", (26.0, 0.0, 0.0)),
    "LeftHand": ("LeftForeArm", (25.0, 0.0, 0.0)),
    "RightShoulder": ("Chest", (-3.0, 15.0, 0.0)),
    "RightArm": ("RightShoulder", (-12.0, 0.0, 0.0)),
    "RightForeArm": ("RightArm", (-26.0, 0.0, 0.0)),
    "RightHand": ("RightForeArm", (-25.0, 0.0, 0.0)),
    "LeftUpLeg": ("Hips", (9.0, -5.0, 0.0)),
    "LeftLeg": ("LeftUpLeg", (0.0, -42.0, 0.0)),
    "LeftFoot": ("LeftLeg", (0.0, -42.0, 0.0)),
    "LeftToeBase": ("LeftFoot", (0.0, -5.0, 12.0)),
    "RightUpLeg": ("Hips", (-9.0, -5.0, 0.0)),
    "RightLeg": ("RightUpLeg", (0.0, -42.0, 0.0)),
    "RightFoot": ("RightLeg", (0.0, -42.0, 0.0)),
    "RightToeBase": ("RightFoot", (0.0, -5.0, 12.0)),
}
_END_SITES = {"Head": (0.0, 10.0, 0.0), "LeftHand": (8.0, 0.0, 0.0), "RightHand": (-8.0, 0.0, 0.0)}
_END_SITES |= {"LeftToeBase": (0.0, 0.0, 5.0), "RightToeBase": (0.0, 0.0, 5.0)}


def _both_sides(template: str, **parts: str) -> dict[str, str]:
    """role -> name for the left and right roles of a naming: `parts` maps a role's part ("UpLeg")
    to the naming's ("Thigh"), put into `template` with the side as {S} ("L", "R") or {s} ("l", "r")."""
    return {
        f"{side}{part}": template.format(part=theirs, S=side[0], s=side[0].lower())
        for side in ("Left", "Right")
        for part, theirs in parts.items()
    }


_BANDAI_NAMES = {"Chest": "Chest"} | _both_sides(
    "{part}_{S}", Shoulder="Shoulder", Arm="UpperArm", ForeArm="LowerArm", Hand="Hand",
    UpLeg="UpperLeg", Leg="LowerLeg", Foot="Foot", ToeBase="Toes",
)  # fmt: skip
_DAZ_NAMES = {"Hips": "hip", "Spine": "abdomen", "Chest": "chest", "Neck": "neck", "Head": "head"}
_DAZ_NAMES |= _both_sides(
    "{s}{part}", Shoulder="Collar", Arm="Shldr", ForeArm="ForeArm", Hand="Hand",
    UpLeg="Thigh", Leg="Shin", Foot="Foot", ToeBase="Toe",
)  # fmt: skip
_MIXAMO_NAMES = {role: f"mixamorig:{role}" for role in _SKELETON} | {"Chest": "mixamorig:Spine1"}
_BIPED_NAMES = {"Hips": "Bip01 Pelvis", "Spine": "Bip01 Spine", "Chest": "Bip01 Spine1"}
_BIPED_NAMES |= {"Neck": "Bip01 Neck", "Head": "Bip01 Head"} | _both_sides(
    "Bip01 {S} {part}", Shoulder="Clavicle", Arm="UpperArm", ForeArm="Forearm", Hand="Hand",
    UpLeg="Thigh", Leg="Calf", Foot="Foot", ToeBase="Toe0",
)  # fmt: skip
NAMINGS = {"motionbuilder": {}, "bandai": _BANDAI_NAMES, "daz": _DAZ_NAMES, "mixamo": _MIXAMO_NAMES}
NAMINGS["biped"] = _BIPED_NAMES


def _walk_angles(t: np.ndarray, yaw_deg: float = 0.0) -> dict[str, dict[str, np.ndarray]]:
    """role -> {axis: degrees (T,)}: legs swing at 1 Hz, arms hang down, the body yawed by yaw_deg."""
    swing = 25.0 * np.sin(2 * np.pi * t)
    ones = np.ones_like(t)
    return {
        "Hips": {"Y": yaw_deg * ones},
        "LeftUpLeg": {"X": -swing},
        "RightUpLeg": {"X": swing},
        "LeftLeg": {"X": 15.0 + 15.0 * np.cos(2 * np.pi * t)},
        "RightLeg": {"X": 15.0 - 15.0 * np.cos(2 * np.pi * t)},
        "LeftArm": {"Z": -80.0 * ones, "X": 0.5 * swing},
        "RightArm": {"Z": 80.0 * ones, "X": -0.5 * swing},
    }


def _bvh_text(
    fps: float = 30.0,
    seconds: float = 2.0,
    names: dict[str, str] | None = None,
    order: str = "ZXY",
    unit: float = 1.0,
    yaw_deg: float = 0.0,
    speed_cm: float = 120.0,
    angles: dict[str, dict[str, np.ndarray]] | None = None,
    omit: tuple[str, ...] = (),
    end_sites: dict[str, tuple[float, float, float]] | None = None,
) -> str:
    """A BVH of the synthetic humanoid walking forward (along its yaw) at speed_cm per second.

    names renames roles; unit scales every length (1 = centimetres, 0.01 = metres); omit drops
    roles (their children hang from the grandparent with summed offsets); end_sites adds End
    Sites to childless roles. angles are intrinsic "ZXY" Euler angles, written in `order`.
    """
    names = names or {}
    ends = _END_SITES | (end_sites or {})
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    angles = _walk_angles(t, yaw_deg) if angles is None else angles
    if order != "ZXY":
        angles = {role: _reorder(axes, len(t), order) for role, axes in angles.items()}
    roles = [r for r in _SKELETON if r not in omit]
    children: dict[str | None, list[str]] = {}
    offsets: dict[str, np.ndarray] = {}
    for role in roles:
        parent, off = _SKELETON[role]
        off = np.array(off)
        while parent in omit:
            parent, up = _SKELETON[parent]
            off = off + np.array(up)
        children.setdefault(parent, []).append(role)
        offsets[role] = off * unit
    lines, columns = ["HIERARCHY"], []

    def emit(role: str, depth: int) -> None:
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {names.get(role, role)}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v:g}' for v in offsets[role])}")
        rot = [f"{a}rotation" for a in order]
        chans = ["Xposition", "Yposition", "Zposition", *rot] if depth == 0 else rot
        lines.append(f"{pad}  CHANNELS {len(chans)} {' '.join(chans)}")
        for chan in chans:
            columns.append((role, chan))
        for child in children.get(role, []):
            emit(child, depth + 1)
        if role in ends and not children.get(role):
            offset = " ".join(map(str, ends[role]))
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET {offset}", pad + "  }"])
        lines.append(pad + "}")

    emit(children[None][0], 0)
    yaw = np.deg2rad(yaw_deg)
    root = np.stack([np.sin(yaw) * speed_cm * t, 95.0 + 0 * t, np.cos(yaw) * speed_cm * t], axis=-1) * unit
    values = np.zeros((len(t), len(columns)))
    for k, (role, chan) in enumerate(columns):
        if chan.endswith("position"):
            values[:, k] = root[:, "XYZ".index(chan[0])]
        else:
            values[:, k] = angles.get(role, {}).get(chan[0], 0.0)
    lines += ["MOTION", f"Frames: {len(t)}", f"Frame Time: {1.0 / fps:.8f}"]
    lines += [" ".join(f"{v:.6f}" for v in row) for row in values]
    return "\n".join(lines) + "\n"


def _reorder(axes: dict[str, np.ndarray], frames: int, order: str) -> dict[str, np.ndarray]:
    """Intrinsic "ZXY" angles -> the same rotations as intrinsic angles in `order`."""
    zxy = np.stack([np.broadcast_to(axes.get(a, 0.0), (frames,)) for a in "ZXY"], axis=-1)
    out = Rotation.from_euler("ZXY", zxy, degrees=True).as_euler(order, degrees=True)
    return {a: out[:, k] for k, a in enumerate(order)}


def _write(tmp_path: Path, text: str, name: str = "clip.bvh") -> Path:
    path = tmp_path / name
    if name.endswith(".gz"):
        with gzip.open(path, "wt") as fh:
            fh.write(text)
    else:
        path.write_text(text)
    return path


# --- parsing and kinematics ------------------------------------------------------------------------


def _rot(axis: str, deg: float) -> np.ndarray:
    """Elementary rotation matrix, written out by hand (independent of scipy)."""
    c, s = np.cos(np.deg2rad(deg)), np.sin(np.deg2rad(deg))
    return {
        "X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
        "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
        "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]),
    }[axis]


@pytest.mark.parametrize("order", ["ZXY", "XYZ", "YZX", "ZYX", "YXZ"])
def test_rotation_channels_compose_in_file_order(tmp_path: Path, order: str):
    # Root: 6 channels in order "ZXY" for every file; child: 3 channels in `order`.
    root_angles = {"Z": 30.0, "X": -20.0, "Y": 50.0}
    child_angles = {"X": 10.0, "Y": -35.0, "Z": 70.0}
    text = f"""HIERARCHY
ROOT Base
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Arm
  {{
    OFFSET 1 2 3
    CHANNELS 3 {" ".join(f"{a}rotation" for a in order)}
    End Site
    {{
      OFFSET 0 0 4
    }}
  }}
}}
MOTION
Frames: 1
Frame Time: 0.05
5 6 7 30 -20 50 {" ".join(str(child_angles[a]) for a in order)}
"""
    bvh = read_bvh(_write(tmp_path, text))
    assert bvh.names == ["Base", "Arm"] and bvh.parents.tolist() == [-1, 0]
    assert bvh.channels[1] == tuple(f"{a}rotation" for a in order)
    pos, ends = bvh_world_positions(bvh)
    r_root = _rot("Z", root_angles["Z"]) @ _rot("X", root_angles["X"]) @ _rot("Y", root_angles["Y"])
    r_child = np.eye(3)
    for axis in order:  # "ZXY" -> Rz @ Rx @ Ry: intrinsic rotations in channel order
        r_child = r_child @ _rot(axis, child_angles[axis])
    arm = np.array([5.0, 6.0, 7.0]) + r_root @ [1.0, 2.0, 3.0]
    np.testing.assert_allclose(pos[0, 0], [5.0, 6.0, 7.0])
    np.testing.assert_allclose(pos[0, 1], arm, atol=1e-9)
    np.testing.assert_allclose(ends[1][0], arm + r_root @ r_child @ [0.0, 0.0, 4.0], atol=1e-9)


def test_position_channels_replace_offsets_and_three_channel_root_keeps_its_offset(tmp_path: Path):
    text = """HIERARCHY
ROOT A
{
  OFFSET 1 2 3
  CHANNELS 3 Yrotation Xrotation Zrotation
  JOINT B
  {
    OFFSET 100 100 100
    CHANNELS 6 Xposition Yposition Zposition Xrotation Yrotation Zrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
0 0 0 0 0 0 0 0 0
90 0 0 4 5 6 0 0 0
"""
    bvh = read_bvh(_write(tmp_path, text))
    assert bvh.fps == pytest.approx(30.0, rel=1e-5) and bvh.num_frames == 2
    pos, ends = bvh_world_positions(bvh)
    np.testing.assert_allclose(pos[:, 0], [[1, 2, 3], [1, 2, 3]])  # no position channels: OFFSET
    np.testing.assert_allclose(pos[0, 1], [1, 2, 3])  # channels (0, 0, 0) replace OFFSET (100, ...)
    np.testing.assert_allclose(pos[1, 1], np.array([1, 2, 3]) + _rot("Y", 90) @ [4, 5, 6], atol=1e-9)
    np.testing.assert_allclose(ends[1][1], pos[1, 1] + [0, 1, 0], atol=1e-9)


def test_joint_names_with_spaces_and_gzip_by_content(tmp_path: Path):
    text = _bvh_text(names=_BIPED_NAMES)
    path = tmp_path / "biped.bvh"  # gzip-compressed but without the .gz suffix
    path.write_bytes(gzip.compress(text.encode()))
    bvh = read_bvh(path)
    assert "Bip01 L Thigh" in bvh.names
    assert read_bvh(_write(tmp_path, text, "biped.bvh.gz")).values.shape == bvh.values.shape


def test_joint_name_matching_covers_the_three_conventions_and_prefixes():
    cases = {
        "left_hip": ["UpperLeg_L", "lThigh", "LeftUpLeg", "mixamorig:LeftUpLeg", "Bip01 L Thigh", "thigh.L"],
        "right_knee": ["LowerLeg_R", "rShin", "RightLeg", "mixamorig1:RightLeg", "Bip01 R Calf"],
        "left_collar": ["lCollar", "Bip01 L Clavicle", "LeftClavicle"],
        "right_shoulder": ["UpperArm_R", "rShldr", "RightArm", "Bip01 R UpperArm"],
        "left_elbow": ["LowerArm_L", "lForeArm", "LeftForeArm", "Bip01 L Forearm"],
        "right_wrist": ["Hand_R", "rHand", "RightHand", "RIGHTHAND"],
        "left_ankle": ["Foot_L", "lFoot", "LeftFoot"],
        "right_foot": ["Toes_R", "RightToeBase", "Bip01 R Toe0"],
        "pelvis": ["Hips", "hip", "mixamorig:Hips", "Bip01 Pelvis"],
        "neck": ["Neck", "neck"],
        "head": ["Head", "head"],
    }
    for canon, names in cases.items():
        for name in names:
            found = map_joint_names(["joint_Root", name, "leftEye", "rButtock"])
            assert found.get(canon) == 1, (canon, name, found)
    # A "Shoulder" joint is the collar next to an upper-arm joint and the shoulder next to a collar.
    assert map_joint_names(["LeftShoulder", "LeftArm"]) == {"left_collar": 0, "left_shoulder": 1}
    assert map_joint_names(["Shoulder_R", "UpperArm_R"]) == {"right_collar": 0, "right_shoulder": 1}
    assert map_joint_names(["L_Collar", "L_Shoulder"]) == {"left_collar": 0, "left_shoulder": 1}


# --- the whole import on synthetic files -----------------------------------------------------------


def test_all_namings_give_the_same_motion(tmp_path: Path):
    reference = None
    for naming, names in NAMINGS.items():
        motion = load_bvh(_write(tmp_path, _bvh_text(names=names), f"{naming}.bvh"))
        assert motion.fps == S.FPS and motion.joints.shape == (41, S.NUM_JOINTS, 3), naming
        assert motion.meta["source"] == str(tmp_path / f"{naming}.bvh")
        assert motion.meta["units"] == "cm" and motion.meta["dropped_frames"] == "0"
        if reference is None:
            reference = motion.joints
        np.testing.assert_allclose(motion.joints, reference, atol=1e-5, err_msg=naming)
    # On the canonical skeleton, on the floor, facing +Z with its left hip at +X, walking +Z.
    j = reference
    np.testing.assert_allclose(M.bone_lengths(j)[:, 1:], np.tile(S.BONE_LENGTHS[1:], (41, 1)), atol=1e-5)
    assert abs(M.heading_from_joints(j[0])) < 1e-5
    assert j[0, S.JOINT_INDEX["left_hip"], 0] > 0.05 > -0.05 > j[0, S.JOINT_INDEX["right_hip"], 0]
    assert np.percentile(j[:, list(S.FOOT_JOINTS), 1].min(axis=1), 3) == pytest.approx(0.0, abs=1e-6)
    np.testing.assert_allclose(j[0, 0, [0, 2]], 0.0, atol=1e-6)
    assert j[-1, 0, 2] > 1.5 and abs(j[-1, 0, 0]) < 0.05


def test_spine_joints_lie_on_the_source_spine_and_toes_follow_the_end_site(tmp_path: Path):
    # No Chest, no toes: spine joints sit on the straight Hips-Spine-Neck line; the foot tip comes
    # from the ankle's End Site (moved here from the toes), like the CMU Daz skeleton.
    tips = {"LeftFoot": (0.0, -5.0, 17.0), "RightFoot": (0.0, -5.0, 17.0)}
    text = _bvh_text(omit=("Chest", "LeftToeBase", "RightToeBase"), end_sites=tips)
    motion = load_bvh(_write(tmp_path, text))
    j = motion.joints.astype(np.float64)
    up = np.array([0.0, 1.0, 0.0])
    for name in ("spine1", "spine2", "spine3", "neck"):
        bone = j[:, S.JOINT_INDEX[name]] - j[:, S.PARENTS[S.JOINT_INDEX[name]]]
        direction = bone / np.linalg.norm(bone, axis=-1, keepdims=True)
        np.testing.assert_allclose(direction, np.broadcast_to(up, bone.shape), atol=1e-5)
    # At frame 0 the legs hang straight but the knees bend (about X) by 30 (left) and 0 (right) deg.
    for ankle, toe, knee_deg in ((7, 10, 30.0), (8, 11, 0.0)):
        d = j[0, toe] - j[0, ankle]
        tip = _rot("X", knee_deg) @ np.array([0.0, -5.0, 17.0])
        np.testing.assert_allclose(d / np.linalg.norm(d), tip / np.linalg.norm(tip), atol=1e-4)


def test_missing_toes_and_collars_are_filled_in(tmp_path: Path):
    omit = ("LeftToeBase", "RightToeBase", "LeftShoulder", "RightShoulder", "Neck")
    j = load_bvh(_write(tmp_path, _bvh_text(omit=omit))).joints
    for ankle, toe in ((7, 10), (8, 11)):  # extrapolated ahead of the ankle (+Z), a bit down
        d = j[:, toe] - j[:, ankle]
        assert (d[:, 2] > 0.1).all() and (d[:, 1] < 0).all()
    # Collars halfway between spine3 and the shoulder: both bones point the same way.
    for collar in (13, 14):
        a = j[:, collar] - j[:, 9]
        b = j[:, S.JOINT_NAMES.index(S.JOINT_NAMES[collar].replace("collar", "shoulder"))] - j[:, collar]
        cos = (a * b).sum(-1) / np.linalg.norm(a, axis=-1) / np.linalg.norm(b, axis=-1)
        assert (cos > 0.999).all()


def test_frame_rates_units_rotation_orders_and_heading_do_not_change_the_motion(tmp_path: Path):
    base = load_bvh(_write(tmp_path, _bvh_text(fps=120.0, seconds=3.0), "base.bvh")).joints
    variants = {
        "60fps": dict(fps=60.0, seconds=3.0),
        "30fps": dict(fps=30.0, seconds=3.0),
        "25fps": dict(fps=25.0, seconds=3.0),
        "metres": dict(fps=120.0, seconds=3.0, unit=0.01),
        "XYZ": dict(fps=120.0, seconds=3.0, order="XYZ"),
        "yawed": dict(fps=120.0, seconds=3.0, yaw_deg=-60.0),
    }
    for name, kwargs in variants.items():
        motion = load_bvh(_write(tmp_path, _bvh_text(**kwargs), f"{name}.bvh"))
        assert motion.num_frames == 61, name
        # Exact where 20 fps samples land on source frames; linear interpolation otherwise.
        tol = 2e-2 if name in ("30fps", "25fps") else 1e-4
        np.testing.assert_allclose(motion.joints, base, atol=tol, err_msg=name)
    assert load_bvh(_write(tmp_path, _bvh_text(unit=0.01), "m.bvh")).meta["units"] == "m"


def test_conversion_t_pose_lead_in_is_dropped_but_real_frames_are_kept(tmp_path: Path):
    fps, seconds = 120.0, 2.0
    t = np.arange(int(seconds * fps) + 1) / fps
    angles = _walk_angles(t)
    for axes in angles.values():  # frame 0 is the rest pose the CMU Daz conversion puts first
        for axis in axes:
            axes[axis] = axes[axis].copy()
            axes[axis][0] = 0.0
    motion = load_bvh(_write(tmp_path, _bvh_text(fps=fps, seconds=seconds, angles=angles), "tpose.bvh"))
    assert motion.meta["dropped_frames"] == "1"
    # A motion that really starts in the rest pose and leaves it smoothly keeps every frame.
    ramp = np.minimum(t / 0.5, 1.0)
    smooth = {role: {a: v * ramp for a, v in axes.items()} for role, axes in _walk_angles(t).items()}
    motion = load_bvh(_write(tmp_path, _bvh_text(fps=fps, seconds=seconds, angles=smooth), "smooth.bvh"))
    assert motion.meta["dropped_frames"] == "0"
    walk = load_bvh(_write(tmp_path, _bvh_text(fps=fps, seconds=seconds), "walk.bvh"))
    assert walk.meta["dropped_frames"] == "0"


# --- bad inputs ------------------------------------------------------------------------------------


def test_missing_file(tmp_path: Path):
    with pytest.raises(FileNotFoundError, match="nope.bvh"):
        load_bvh(tmp_path / "nope.bvh")


def _assert_bad(path: Path, *fragments: str) -> None:
    with pytest.raises(ValueError) as info:
        load_bvh(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, message


def test_truncated_and_overlong_motion_blocks(tmp_path: Path):
    text = _bvh_text(seconds=1.0)  # 31 frames
    lines = text.rstrip("\n").split("\n")
    cut = _write(tmp_path, "\n".join(lines[:-3]) + "\n", "cut.bvh")
    _assert_bad(cut, "truncated", "Frames: 31", "28 whole frames")
    half = "\n".join(lines[:-1] + [" ".join(lines[-1].split()[:10])])
    _assert_bad(_write(tmp_path, half, "half.bvh"), "truncated")
    _assert_bad(_write(tmp_path, text + lines[-1] + "\n", "long.bvh"), "longer than its header")
    _assert_bad(_write(tmp_path, text.split("MOTION")[0], "nomotion.bvh"), "no MOTION")
    cut_gz = _write(tmp_path, text, "cut.bvh.gz")
    cut_gz.write_bytes(cut_gz.read_bytes()[:200])
    _assert_bad(cut_gz, "gzip")


def test_nan_and_non_numeric_channels(tmp_path: Path):
    lines = _bvh_text(seconds=1.0).split("\n")
    row = lines.index("MOTION") + 3 + 4  # frame 4
    values = lines[row].split()
    values[7] = "nan"  # the second joint's second channel
    bad = lines[:row] + [" ".join(values)] + lines[row + 1 :]
    _assert_bad(_write(tmp_path, "\n".join(bad), "nan.bvh"), "NaN", "frame 4", "'Spine'", "'Xrotation'")
    values[7] = "1.2.3"
    bad = lines[:row] + [" ".join(values)] + lines[row + 1 :]
    _assert_bad(_write(tmp_path, "\n".join(bad), "junk.bvh"), "non-numeric value '1.2.3'", "frame 4")


def test_unknown_skeleton_lists_missing_joints_and_file_joints(tmp_path: Path):
    names = {role: f"bone{k:02d}" for k, role in enumerate(_SKELETON)} | {"Hips": "Hips", "Head": "Head"}
    path = _write(tmp_path, _bvh_text(names=names), "odd.bvh")
    _assert_bad(path, "unknown skeleton", "left_hip", "right_wrist", "bone05", "'Hips'")
    # Left and right limbs swapped between the hierarchy's branches: caught, not silently mirrored.
    swapped = _bvh_text().replace("LeftLeg", "TMP").replace("RightLeg", "LeftLeg").replace("TMP", "RightLeg")
    _assert_bad(_write(tmp_path, swapped, "swapped.bvh"), "is not below")


def test_non_bvh_content(tmp_path: Path):
    _assert_bad(_write(tmp_path, "hello, world\n1 2 3\n", "hello.bvh"), "not a BVH file")
    (tmp_path / "binary.bvh").write_bytes(bytes(range(256)) * 4)
    _assert_bad(tmp_path / "binary.bvh", "not a BVH file")
    (tmp_path / "fake.bvh.gz").write_text("HIERARCHY but not gzip")
    _assert_bad(tmp_path / "fake.bvh.gz", "gzip")
    broken = _bvh_text(seconds=0.5).replace("CHANNELS 3", "CHANNELS 3 Wrotation", 1)
    _assert_bad(_write(tmp_path, broken, "chan.bvh"), "malformed BVH hierarchy")
    unbalanced = _bvh_text(seconds=0.5).replace("}\nMOTION", "MOTION")
    _assert_bad(_write(tmp_path, unbalanced, "brace.bvh"), "missing '}'")
