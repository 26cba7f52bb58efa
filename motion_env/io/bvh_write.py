"""BVH files out: :func:`save_bvh` writes a motion on the canonical skeleton with local rotations.

The file (``docs/conventions.md``, "Export"):

- HIERARCHY: the 22 canonical joints under their own names (:data:`skeleton.JOINT_NAMES`), in
  centimetres, Y up, the rest pose facing +Z with every bone along :data:`skeleton.RAW_OFFSETS`
  at its :data:`skeleton.BONE_LENGTHS` length. The pelvis and spine3 have three children each,
  and a clip's hips, spine1, neck and collars do not keep fixed angles around them (the skeleton
  fixes bone lengths, not those angles; a generated clip moves them freely), so one rotation
  cannot place all three children. Four zero-length helper joints carry the other children's
  rotations: ``left_pelvis`` / ``right_pelvis`` (pelvis -> hip) and ``left_chest`` /
  ``right_chest`` (spine3 -> collar), as CMU's ``LHipJoint``. The pelvis's own rotation aims
  spine1 and spine3's aims the neck. Leaf joints (toes, head, wrists) end in an End Site that
  continues their bone a few centimetres (:data:`END_SITE_LENGTHS`, cosmetic).
- Channels: the ROOT (pelvis) ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``,
  every other joint ``Zrotation Xrotation Yrotation`` (:data:`EULER_ORDER` = "ZXY", intrinsic:
  R = Rz @ Rx @ Ry, degrees, the order of the Bandai Namco files).
- MOTION: one line per frame of the motion, ``Frame Time`` = 1 / fps (no resampling).

Rotations: the root position is the pelvis; the root rotation is the heading yaw of
:func:`motion.inverse_kinematics` (:func:`motion.heading_from_joints`) turned so that the pelvis
-> spine1 bone points where it does; every other joint takes the shortest-arc rotation of its
bone from the rest direction, seen from its parent (so no twist is made up, and a limb's local
rotation is small when it is near its rest direction); leaf joints keep their parent's rotation.
The clip is first put on the canonical bone lengths (:func:`motion.kinematics.rescale_bones`, as
:func:`motion_env.load_bvh` does), so the file reproduces the joints within micrometres, where
they are. ``load_bvh`` reads it back as ``canonicalize(joints)`` (at the origin, facing +Z): a
clip it returned comes back within 0.002 mm.
"""

from __future__ import annotations

import gzip
import io
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from motion_env.motion.kinematics import heading_from_joints, rescale_bones
from motion_env.motion.rotations import qbetween, qinv, qmul, qrot, quat_from_yaw
from motion_env.motion.skeleton import (
    BONE_LENGTHS,
    JOINT_INDEX,
    JOINT_NAMES,
    NUM_JOINTS,
    PARENTS,
    RAW_OFFSETS,
)
from motion_env.motion.validation import check_joints

__all__ = [
    "BVH_UNITS",
    "END_SITE_LENGTHS",
    "EULER_ORDER",
    "HELPER_JOINTS",
    "BvhJoint",
    "bvh_layout",
    "bvh_text",
    "save_bvh",
]

EULER_ORDER = "ZXY"
"""Euler order of every rotation channel: intrinsic, R = Rz @ Rx @ Ry, in degrees."""
BVH_UNITS = 100.0
"""File units per metre: the file is in centimetres."""
HELPER_JOINTS: dict[str, tuple[str, str]] = {
    "left_pelvis": ("pelvis", "left_hip"),
    "right_pelvis": ("pelvis", "right_hip"),
    "left_chest": ("spine3", "left_collar"),
    "right_chest": ("spine3", "right_collar"),
}
"""Zero-length helper joints: name -> (the canonical joint they sit at, the child they aim)."""
END_SITE_LENGTHS: dict[str, float] = {
    "left_foot": 0.05, "right_foot": 0.05, "head": 0.1, "left_wrist": 0.08, "right_wrist": 0.08,
}  # fmt: skip
"""Length (m) of the End Site after each leaf joint, along its bone's rest direction (cosmetic)."""

_ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", *(f"{a}rotation" for a in EULER_ORDER))
_JOINT_CHANNELS = tuple(f"{a}rotation" for a in EULER_ORDER)
_CHILDREN = tuple(tuple(c for c in range(NUM_JOINTS) if PARENTS[c] == j) for j in range(NUM_JOINTS))
_AIM = {JOINT_INDEX["pelvis"]: JOINT_INDEX["spine1"], JOINT_INDEX["spine3"]: JOINT_INDEX["neck"]}
_HELPER_OF = {JOINT_INDEX[child]: name for name, (_, child) in HELPER_JOINTS.items()}
_SUFFIXES = (".bvh", ".bvh.gz")


@dataclass(frozen=True)
class BvhJoint:
    """One joint of the written hierarchy.

    Attributes:
        name: the joint's name in the file.
        parent: index of its parent in :func:`bvh_layout` (-1 for the ROOT).
        at: the canonical joint it sits at.
        aim: the canonical joint its rotation points its bone at (None for a leaf).
        offset: (3,) rest offset from its parent, metres.
    """

    name: str
    parent: int
    at: int
    aim: int | None
    offset: np.ndarray


def bvh_layout() -> list[BvhJoint]:
    """The written hierarchy in file order (depth first, parents before children): 26 joints."""
    out: list[BvhJoint] = []

    def visit(j: int, parent: int, offset: np.ndarray) -> None:
        kids = _CHILDREN[j]
        aim = _AIM.get(j, kids[0]) if kids else None
        me = len(out)
        out.append(BvhJoint(JOINT_NAMES[j], parent, j, aim, offset))
        for c in kids:
            bone = RAW_OFFSETS[c].astype(np.float64) * float(BONE_LENGTHS[c])
            if c == aim:
                visit(c, me, bone)
            else:  # a helper at j that aims c
                out.append(BvhJoint(_HELPER_OF[c], me, j, c, np.zeros(3)))
                visit(c, len(out) - 1, bone)

    visit(JOINT_INDEX["pelvis"], -1, np.zeros(3))
    return out


def _world_rotations(joints: np.ndarray, layout: list[BvhJoint]) -> np.ndarray:
    """(T, J, 4) world rotation (w, x, y, z) of every joint of `layout` for joints (T, 22, 3)."""
    n = joints.shape[0]
    yaw = quat_from_yaw(heading_from_joints(joints))  # the root rotation of inverse_kinematics
    world = np.zeros((n, len(layout), 4))
    for b, joint in enumerate(layout):
        parent = yaw if joint.parent < 0 else world[:, joint.parent]
        if joint.aim is None:
            world[:, b] = parent
            continue
        rest = np.broadcast_to(RAW_OFFSETS[joint.aim].astype(np.float64), (n, 3))
        seen = qrot(qinv(parent), joints[:, joint.aim] - joints[:, joint.at])  # in the parent's frame
        short = np.linalg.norm(seen, axis=-1) < 1e-9  # a zero-length bone keeps its rest direction
        seen[short] = rest[short]
        world[:, b] = qmul(parent, qbetween(rest, seen))
    return world


def _channel_values(joints: np.ndarray, layout: list[BvhJoint]) -> np.ndarray:
    """(T, 6 + 3 (J - 1)) channel values: root position (cm), then ZXY Euler angles per joint."""
    world = _world_rotations(joints, layout)
    parents = [max(j.parent, 0) for j in layout]
    local = qmul(qinv(world[:, parents]), world)
    local[:, 0] = world[:, 0]
    with warnings.catch_warnings():  # at gimbal lock the angles still give the same rotation
        warnings.filterwarnings("ignore", message="Gimbal lock", category=UserWarning)
        euler = Rotation.from_quat(local.reshape(-1, 4)[:, [1, 2, 3, 0]]).as_euler(EULER_ORDER, degrees=True)
    euler = euler.reshape(len(joints), len(layout) * 3)
    return np.concatenate([joints[:, 0] * BVH_UNITS, euler], axis=1)


def _fmt(v: np.ndarray) -> str:
    return " ".join(f"{x * BVH_UNITS:.6f}" for x in v)


def _hierarchy(layout: list[BvhJoint]) -> str:
    lines = ["HIERARCHY"]
    kids: dict[int, list[int]] = {}
    for b, joint in enumerate(layout):
        kids.setdefault(joint.parent, []).append(b)

    def write(b: int, depth: int) -> None:
        joint, pad = layout[b], "\t" * depth
        channels = _ROOT_CHANNELS if joint.parent < 0 else _JOINT_CHANNELS
        lines.append(f"{pad}{'ROOT' if joint.parent < 0 else 'JOINT'} {joint.name}")
        lines.append(pad + "{")
        lines.append(f"{pad}\tOFFSET {_fmt(joint.offset)}")
        lines.append(f"{pad}\tCHANNELS {len(channels)} {' '.join(channels)}")
        for c in kids.get(b, []):
            write(c, depth + 1)
        if joint.aim is None:
            end = RAW_OFFSETS[joint.at].astype(np.float64) * END_SITE_LENGTHS[joint.name]
            lines.extend([f"{pad}\tEnd Site", pad + "\t{", f"{pad}\t\tOFFSET {_fmt(end)}", pad + "\t}"])
        lines.append(pad + "}")

    write(0, 0)
    return "\n".join(lines) + "\n"


def bvh_text(motion: Any) -> str:
    """The BVH file of `motion` (a :class:`~motion_env.motion.types.Motion`) as a string."""
    joints = check_joints(getattr(motion, "joints", None), "motion.joints")
    fps = float(getattr(motion, "fps", 0.0))
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"motion.fps must be a positive number, got {getattr(motion, 'fps', None)!r}")
    joints = rescale_bones(joints)  # canonical bone lengths; the identity for a canonical clip
    layout = bvh_layout()
    values = _channel_values(joints, layout)
    buf = io.StringIO()
    buf.write(_hierarchy(layout))
    buf.write(f"MOTION\nFrames: {len(values)}\nFrame Time: {1.0 / fps:.10g}\n")
    np.savetxt(buf, values, fmt="%.6f")
    return buf.getvalue()


def save_bvh(motion: Any, path: str | Path) -> Path:
    """Write `motion` as a BVH file (format in the module docstring); replaces an existing file.

    Args:
        motion: a :class:`~motion_env.motion.types.Motion` (any fps; the file keeps it).
        path: ``.bvh``, or ``.bvh.gz`` for a gzip-compressed file. Missing folders are made.

    Returns:
        the path written.

    Raises:
        ValueError: another suffix, or a motion with NaN / infinite joints or a bad fps.
        OSError: the file cannot be written (the message names it).
    """
    path = Path(path)
    name = path.name.lower()
    if not name.endswith(_SUFFIXES):
        raise ValueError(f"{path}: a BVH file name must end in .bvh or .bvh.gz")
    text = bvh_text(motion)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if name.endswith(".gz"):
            with gzip.open(path, "wt", encoding="ascii") as fh:
                fh.write(text)
        else:
            path.write_text(text, encoding="ascii")
    except OSError as exc:
        raise OSError(f"{path}: cannot write the BVH file ({exc.strerror or exc})") from exc
    return path
