"""Import BVH motion capture onto the canonical 22-joint skeleton at 20 fps.

:func:`load_bvh` reads any ``.bvh`` / ``.bvh.gz`` file and returns a
:class:`~motion_env.motion.types.Motion`:

1. :func:`~motion_env.io.bvh_file.read_bvh` parses the hierarchy (any Euler order per joint, 3- or
   6-channel joints, End Sites, several roots) and the MOTION block.
2. :func:`~motion_env.io.bvh_file.bvh_world_positions` runs forward kinematics on the source
   skeleton, vectorised over frames, in the file's units.
3. Units are told from the skeleton's standing height (leg + pelvis-to-head chain lengths, which do
   not depend on the pose): metres, centimetres or millimetres. Y is up, as BVH files are written.
4. Source joints are matched to the canonical joints by name
   (:func:`~motion_env.io.joint_names.map_joint_names`: Bandai Namco, CMU "Daz-friendly",
   MotionBuilder / Mixamo / 3ds Max biped names, case- and prefix-tolerant). Canonical joints a
   source lacks are filled in:

   - ``spine1``, ``spine2``, ``spine3`` always lie on the source's pelvis-to-neck polyline (every
     source spine joint between them), at the canonical arc-length fractions, so any number of
     source spine joints (zero included) gives the same bone directions as the source's curve;
     without a neck joint, ``neck`` is placed the same way on the pelvis-to-head polyline;
   - a missing collar sits halfway between ``spine3`` and the shoulder;
   - missing toes (``left_foot`` / ``right_foot``) come from the ankle's End Site when it has one
     (the CMU Daz skeleton), else they are extrapolated 20 degrees below the body's forward
     direction (from the hips) in front of the ankle.
5. The CMU Daz conversion's lead-in (a T-pose at frame 0 and a blend from it into the motion over
   the next few frames) is detected and dropped (:func:`_lead_in_frames`); other files keep every
   frame. The clip is resampled to 20 fps (linear interpolation of joint positions).
6. A capture floor tilted by 0.2-5 degrees (the CMU floors rise about 2 cm per metre) is levelled
   from the foot contacts (:func:`_level_floor`), then :func:`motion_env.motion.canonicalize` puts
   the clip on the canonical bone lengths, feet on the floor, pelvis above the origin, facing +Z.

The package's own BVH files (:func:`motion_env.io.save_bvh`; every canonical joint under its own
name) hold motion that is canonical already: the lead-in (step 5) and the levelling (step 6) are
skipped for them, so ``load_bvh(save_bvh(m))`` gives ``canonicalize(m.joints)`` (``m`` itself for
a canonical clip at 20 fps). The levelling is not idempotent: run again on its own output it can
find a new tilt of a few tenths of a degree, as it measures the tilt before the retargeting.

Left and right follow the file's joint names (``_L`` / ``l`` / ``Left``); on the Bandai and CMU
files the canonical left hip ends up at +X when the body faces +Z, and feet on the floor point
the way the body faces (checked in tests/io/test_bvh.py). Not handled: Z-up files (BVH is Y-up by
convention), inch units, frame rates mislabelled in the file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from motion_env import motion as mmath
from motion_env.io.bvh_file import AXES, BvhFile, bvh_world_positions, read_bvh
from motion_env.io.joint_names import REQUIRED_JOINTS, has_canonical_names, map_joint_names
from motion_env.motion.skeleton import BONE_LENGTHS, FOOT_JOINTS, FPS, JOINT_INDEX, NUM_JOINTS
from motion_env.motion.types import Motion


@dataclass
class _Plan:
    """How to build the 22 canonical joints from the source joints."""

    found: dict[str, int]
    spine: list[int]  # source joints from the pelvis up to the neck (or the head when no neck)
    spine_targets: tuple[str, ...]  # canonical joints placed along that polyline
    spine_weights: np.ndarray  # (len(spine_targets), len(spine)) interpolation weights


def _ancestors(parents: np.ndarray, j: int) -> list[int]:
    """[j, parent(j), ..., root]."""
    chain = []
    while j >= 0:
        chain.append(j)
        j = int(parents[j])
    return chain


def _plan(bvh: BvhFile) -> _Plan:
    """Match the joints by name, check the hierarchy agrees, and place the spine joints."""
    found = map_joint_names(bvh.names)
    missing = [name for name in REQUIRED_JOINTS if name not in found]
    if missing:
        raise ValueError(
            f"{bvh.path}: unknown skeleton: cannot find the canonical joints {missing}; "
            f"the file's joints are {bvh.names}"
        )
    # Each limb joint must hang below the previous one of its chain, else the names lied.
    chains = [("pelvis", "neck", "head")]
    for s in ("left", "right"):
        chains += [
            ("pelvis", f"{s}_hip", f"{s}_knee", f"{s}_ankle", f"{s}_foot"),
            ("pelvis", f"{s}_collar", f"{s}_shoulder", f"{s}_elbow", f"{s}_wrist"),
        ]
    for chain in chains:
        present = [c for c in chain if c in found]
        for upper, lower in zip(present[:-1], present[1:], strict=True):
            if found[upper] not in _ancestors(bvh.parents, found[lower])[1:]:
                raise ValueError(
                    f"{bvh.path}: unexpected skeleton: {lower} ({bvh.names[found[lower]]!r}) is not "
                    f"below {upper} ({bvh.names[found[upper]]!r}) in the hierarchy"
                )

    top = found.get("neck", found["head"])
    spine = _ancestors(bvh.parents, top)
    spine = spine[: spine.index(found["pelvis"]) + 1][::-1]  # pelvis ... top
    targets = ("spine1", "spine2", "spine3") + (() if "neck" in found else ("neck",))
    canon_chain = [JOINT_INDEX[n] for n in ("spine1", "spine2", "spine3", "neck", "head")]
    canon_cum = np.cumsum(BONE_LENGTHS[canon_chain])
    total = canon_cum[len(targets)]  # length up to the source's top joint (neck or head)
    fractions = canon_cum[: len(targets)] / total

    seg = np.array([np.linalg.norm(_bone(bvh, j)) for j in spine[1:]])
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    weights = np.zeros((len(targets), len(spine)))
    if cum[-1] <= 0:
        raise ValueError(f"{bvh.path}: the spine from {bvh.names[spine[0]]!r} up has zero length")
    for k, frac in enumerate(fractions):
        d = frac * cum[-1]
        i = min(int(np.searchsorted(cum, d, side="right")) - 1, len(seg) - 1)  # segment holding d
        t = (d - cum[i]) / seg[i] if seg[i] > 0 else 0.0
        weights[k, i], weights[k, i + 1] = 1.0 - t, t
    return _Plan(found, spine, targets, weights)


def _bone(bvh: BvhFile, j: int) -> np.ndarray:
    """Rest translation of joint j from its parent: its position channels at frame 0, else OFFSET."""
    trans = bvh.offsets[j].copy()
    for k, name in enumerate(bvh.channels[j]):
        if name[1:].lower() == "position":
            trans[AXES[name[0].lower()]] = bvh.values[0, bvh.channel_start[j] + k]
    return trans


def _standing_height(bvh: BvhFile, plan: _Plan) -> float:
    """Pose-independent body size in file units: left leg + pelvis-to-head chain lengths."""
    leg = _ancestors(bvh.parents, plan.found["left_ankle"])
    leg = leg[: leg.index(plan.found["left_hip"])]
    trunk = _ancestors(bvh.parents, plan.found["head"])
    trunk = trunk[: trunk.index(plan.found["pelvis"])]
    return float(sum(np.linalg.norm(_bone(bvh, j)) for j in leg + trunk))


def _unit_scale(bvh: BvhFile, plan: _Plan) -> float:
    """Metres per file unit, from the standing height (about 1.3-1.6 m for an adult)."""
    height = _standing_height(bvh, plan)
    if not np.isfinite(height) or height <= 0:
        raise ValueError(f"{bvh.path}: the skeleton has zero size")
    if height < 10.0:
        return 1.0  # metres
    if height < 1000.0:
        return 0.01  # centimetres
    return 0.001  # millimetres


def _canonical_joints(bvh: BvhFile, plan: _Plan, scale: float) -> np.ndarray:
    """(T, 22, 3) canonical joint positions in metres, source frame rate, source world frame."""
    found = plan.found
    pos, ends = bvh_world_positions(bvh, list(found.values()))
    pos *= scale
    out = np.full((bvh.num_frames, NUM_JOINTS, 3), np.nan)
    for name, j in found.items():
        out[:, JOINT_INDEX[name]] = pos[:, j]
    spine_pos = np.einsum("ks,tsc->tkc", plan.spine_weights, pos[:, plan.spine])
    for k, name in enumerate(plan.spine_targets):
        out[:, JOINT_INDEX[name]] = spine_pos[:, k]
    for side in ("left", "right"):
        collar, shoulder = JOINT_INDEX[f"{side}_collar"], JOINT_INDEX[f"{side}_shoulder"]
        if f"{side}_collar" not in found:
            out[:, collar] = 0.5 * (out[:, JOINT_INDEX["spine3"]] + out[:, shoulder])
        if f"{side}_foot" not in found:
            ankle = found[f"{side}_ankle"]
            end = ends.get(ankle)
            if end is not None and np.linalg.norm(bvh.end_sites[ankle]) > 0:
                out[:, JOINT_INDEX[f"{side}_foot"]] = end * scale
            else:
                out[:, JOINT_INDEX[f"{side}_foot"]] = _extrapolated_toe(out, side)
    return out


def _extrapolated_toe(joints: np.ndarray, side: str) -> np.ndarray:
    """(T, 3) toe position for a source without toes or an ankle End Site: in front of the ankle,
    along the body's forward direction from the hips (left cross up), tilted 20 degrees down."""
    across = joints[:, JOINT_INDEX["left_hip"]] - joints[:, JOINT_INDEX["right_hip"]]
    forward = np.cross(across, np.array([0.0, 1.0, 0.0]))
    forward[:, 1] = 0.0
    forward /= np.maximum(np.linalg.norm(forward, axis=-1, keepdims=True), 1e-9)
    tilt = np.deg2rad(20.0)
    length = BONE_LENGTHS[JOINT_INDEX[f"{side}_foot"]]
    direction = np.cos(tilt) * forward + np.sin(tilt) * np.array([0.0, -1.0, 0.0])
    return joints[:, JOINT_INDEX[f"{side}_ankle"]] + length * direction


def _lead_in_frames(bvh: BvhFile, plan: _Plan, joints: np.ndarray) -> int:
    """How many leading frames are a conversion artefact rather than motion (0 for most files).

    The CMU Daz-friendly conversion puts a rest pose (T-pose) at frame 0 and blends from it into
    the motion over the next few frames (about 8 at 120 fps; some files also keep a wrong root
    position for a few of them). A file has such a lead-in when frame 0 has every body rotation
    near zero and the pose then moves much faster than it does afterwards; the lead-in ends after
    the last such fast step within the first ``_LEAD_IN_SECONDS``.

    joints: (T, 22, 3) canonical joints in metres at the source rate.
    """
    window = max(1, round(_LEAD_IN_SECONDS * bvh.fps))
    if bvh.num_frames < window + 3:
        return 0
    body = {a for j in plan.found.values() for a in _ancestors(bvh.parents, j) if bvh.parents[a] >= 0}
    rot_cols = [
        int(bvh.channel_start[j]) + k
        for j in sorted(body)
        for k, name in enumerate(bvh.channels[j])
        if name[1:].lower() == "rotation"
    ]
    if not rot_cols or np.abs(bvh.values[0, rot_cols]).max() > _REST_MAX_DEG:
        return 0
    after = joints[: window + 1 + round(bvh.fps)]
    speed = np.linalg.norm(np.diff(after, axis=0), axis=-1).max(axis=-1) * bvh.fps  # (n,) m/s
    lead, rest = speed[:window], speed[window:]
    typical = float(np.median(rest)) if rest.size >= 2 else 0.0
    if lead.max() < max(_JUMP_RATIO * typical, _JUMP_MIN_SPEED):
        return 0
    fast = np.flatnonzero(lead > max(_BLEND_RATIO * typical, _BLEND_MIN_SPEED))
    return int(fast[-1]) + 1


_LEAD_IN_SECONDS = 0.1  # longest lead-in looked for
_REST_MAX_DEG = 20.0  # body rotations of a rest-pose frame 0 stay below this (CMU subject 8: 10.6)
_JUMP_RATIO, _JUMP_MIN_SPEED = 3.0, 1.0  # a lead-in moves this much faster than the motion, m/s
_BLEND_RATIO, _BLEND_MIN_SPEED = 2.0, 0.2  # steps faster than this still belong to the blend


def _level_floor(joints: np.ndarray, fps: float) -> tuple[np.ndarray, float]:
    """Undo a slightly tilted capture floor (the CMU floors rise by about 2 cm per metre walked).

    Contacts are the lowest foot joint of each frame while it moves slower than 0.2 m/s; a plane
    is fitted to them (least squares, refitted without outliers) along the horizontal directions
    in which they spread over at least 0.25 m (std). The clip is rotated so that plane is level
    when its tilt is between 0.2 and 5 degrees and the contacts lie within 1.5 cm (std) of it;
    otherwise (flat already, stairs, jumps, too few contacts) it is left alone.

    joints: (T, 22, 3) metres, Y up. Returns the levelled joints and the tilt removed (degrees).
    """
    feet = joints[:, list(FOOT_JOINTS)]  # (T, 4, 3)
    lowest = feet[..., 1].argmin(axis=1)
    frames = np.arange(len(joints))
    pts = feet[frames, lowest]  # (T, 3)
    if len(joints) < 3:
        return joints, 0.0
    speed = np.linalg.norm(np.gradient(feet, axis=0), axis=-1)[frames, lowest] * fps
    pts = pts[speed < _CONTACT_SPEED]
    if len(pts) < 10:
        return joints, 0.0
    centre = pts[:, [0, 2]].mean(axis=0)
    xz = pts[:, [0, 2]] - centre
    var, axes = np.linalg.eigh(np.cov(xz.T))
    axes = axes[:, var > _FLOOR_MIN_SPREAD**2]  # (2, k) directions the contacts cover
    if axes.shape[1] == 0:
        return joints, 0.0
    design = np.concatenate([np.ones((len(pts), 1)), xz @ axes], axis=1)
    keep = np.ones(len(pts), dtype=bool)
    for _ in range(2):
        coef = np.linalg.lstsq(design[keep], pts[keep, 1], rcond=None)[0]
        resid = pts[:, 1] - design @ coef
        keep = np.abs(resid) < max(3.0 * np.std(resid[keep]), 0.01)
    grad = axes @ coef[1:]  # d(height) / d(x, z)
    tilt = float(np.degrees(np.arctan(np.linalg.norm(grad))))
    if not (_FLOOR_MIN_TILT <= tilt <= _FLOOR_MAX_TILT) or np.std(resid[keep]) > _FLOOR_MAX_RESID:
        return joints, 0.0
    normal = np.array([-grad[0], 1.0, -grad[1]]) / np.sqrt(1.0 + grad @ grad)
    axis = np.cross(normal, [0.0, 1.0, 0.0])
    rot = Rotation.from_rotvec(axis / np.linalg.norm(axis) * np.radians(tilt)).as_matrix()
    pivot = np.array([centre[0], coef[0], centre[1]])
    return (joints - pivot) @ rot.T + pivot, tilt


_CONTACT_SPEED = 0.2  # m/s
_FLOOR_MIN_SPREAD = 0.25  # m
_FLOOR_MIN_TILT, _FLOOR_MAX_TILT = 0.2, 5.0  # degrees
_FLOOR_MAX_RESID = 0.015  # m


def load_bvh(path: str | Path) -> Motion:
    """Load a BVH file onto the canonical skeleton: 20 fps, metres, canonicalized.

    Args:
        path: a ``.bvh`` or ``.bvh.gz`` file.

    Returns:
        a :class:`Motion` with joints (T, 22, 3) float32 on the canonical bone lengths, feet on the
        floor, pelvis above the origin and facing +Z at frame 0; ``fps`` = 20; ``meta["source"]`` =
        the path, plus ``source_fps``, ``units``, ``dropped_frames`` (source frames of a
        conversion lead-in removed from the start) and ``floor_tilt_deg`` (the tilt levelled).

    Raises:
        FileNotFoundError: no such file.
        ValueError: not a BVH file, truncated, NaN values, or a skeleton whose joints cannot be
            matched to the canonical ones (the message lists what is missing and the file's joints).
    """
    bvh = read_bvh(path)
    plan = _plan(bvh)
    scale = _unit_scale(bvh, plan)
    joints = _canonical_joints(bvh, plan, scale)
    # The package's own files (save_bvh) hold canonical motion, not a capture: no conversion
    # lead-in, no tilted floor; so load_bvh(save_bvh(m)) is canonicalize(m).
    own = has_canonical_names(bvh.names)
    lead_in = 0 if own else _lead_in_frames(bvh, plan, joints)
    joints = joints[lead_in:]
    joints = mmath.resample(joints, bvh.fps, FPS)
    joints, tilt = (joints, 0.0) if own else _level_floor(joints, FPS)
    joints = mmath.canonicalize(joints)
    meta = {
        "source": str(bvh.path),
        "source_fps": f"{bvh.fps:.6g}",
        "units": {1.0: "m", 0.01: "cm", 0.001: "mm"}[scale],
        "dropped_frames": str(lead_in),
        "floor_tilt_deg": f"{tilt:.2f}",
    }
    return Motion(joints=joints.astype(np.float32), fps=FPS, meta=meta)


__all__ = ["BvhFile", "bvh_world_positions", "load_bvh", "map_joint_names", "read_bvh"]
