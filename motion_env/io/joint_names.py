"""Joint-name matching: which joint of a source skeleton is which canonical joint.

Covers the Bandai Namco skeleton (``Hips``, ``UpperLeg_L``, ...), the CMU "Daz-friendly" skeleton
(``hip``, ``lThigh``, ``lShldr``, ...) and the common MotionBuilder / Mixamo / 3ds Max biped naming
(``Hips``, ``LeftUpLeg``, ``LeftArm``, ``mixamorig:Hips``, ``Bip01 L Thigh``, ...), case- and
prefix-tolerant; and the package's own names (``left_ankle``, ``left_foot``, ...), which
:func:`motion_env.io.save_bvh` writes, taken as they are.
"""

from __future__ import annotations

import re

from motion_env.motion.skeleton import JOINT_NAMES

__all__ = ["REQUIRED_JOINTS", "has_canonical_names", "map_joint_names"]

# Namespace / rig prefixes stripped before matching ("mixamorig:Hips", "Bip01 L Thigh", "DEF-thigh.L").
_PREFIX = re.compile(r"^(?:mixamorig\d*[:_]?|bip0*1[\s_]*|def[-_]|cc_base_)", re.IGNORECASE)
_SIDE_WORD = re.compile(r"^(left|right)(?=.)", re.IGNORECASE)
_SIDE_LETTER = re.compile(r"^([lLrR])(?=[A-Z_.\-\s])")
_SIDE_SUFFIX = re.compile(r"(?:[_.\-\s](l|r|left|right)|(left|right))$", re.IGNORECASE)

# Base names (lower-case, alphanumeric only, side removed) of each canonical joint, best first.
_CENTER_NAMES = {
    "pelvis": ("hips", "hip", "pelvis", "spinebase"),
    "neck": ("neck", "neck1", "spineshoulder"),
    "head": ("head",),
}
_SIDE_NAMES = {
    "hip": ("upleg", "upperleg", "thigh", "hip"),
    "knee": ("lowerleg", "leg", "shin", "knee", "calf"),
    "ankle": ("foot", "ankle"),
    "foot": ("toebase", "toes", "toe", "toe0", "ball"),
    "collar": ("collar", "clavicle"),
    "shoulder": ("upperarm", "arm", "shldr"),
    "elbow": ("forearm", "lowerarm", "elbow"),
    "wrist": ("hand", "wrist"),
}
REQUIRED_JOINTS = (
    "pelvis", "head", "left_hip", "right_hip", "left_knee", "right_knee", "left_ankle", "right_ankle",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)  # fmt: skip


def _side_and_base(name: str) -> tuple[str, str]:
    """("left" | "right" | "", normalised base name) of a source joint name."""
    name = _PREFIX.sub("", re.split(r"[:|]", name)[-1].strip())
    side = ""
    if m := _SIDE_WORD.match(name):
        side, name = m.group(1).lower(), name[m.end() :]
    elif m := _SIDE_LETTER.match(name):
        side, name = {"l": "left", "r": "right"}[m.group(1).lower()], name[m.end() :]
    elif m := _SIDE_SUFFIX.search(name):
        word = (m.group(1) or m.group(2)).lower()
        side, name = ("left" if word[0] == "l" else "right"), name[: m.start()]
    return side, re.sub(r"[^a-z0-9]", "", name.lower())


def _canonical_names(names: list[str]) -> dict[str, int] | None:
    """The package's own names (``motion_env.io.save_bvh`` writes them), matched as they are.

    They must be matched whole: ``left_foot`` is the canonical toe, where the base-name rules
    below read "foot" as the ankle (as in Mixamo's ``LeftFoot``). None unless every canonical
    joint name is there exactly once.
    """
    if not all(names.count(name) == 1 for name in JOINT_NAMES):
        return None
    return {name: names.index(name) for name in JOINT_NAMES if not name.startswith("spine")}


def has_canonical_names(names: list[str]) -> bool:
    """True when every canonical joint is there under its own name, once (the package's own
    BVH files, written by :func:`motion_env.io.save_bvh`)."""
    return _canonical_names(names) is not None


def map_joint_names(names: list[str]) -> dict[str, int]:
    """Match source joint names to canonical joint names.

    Returns:
        canonical name -> source joint index for every canonical joint found by name (the spine
        joints ``spine1..3`` are never matched by name: they are placed along the spine polyline).
    """
    exact = _canonical_names(names)
    if exact is not None:
        return exact
    keys = [_side_and_base(n) for n in names]
    found: dict[str, int] = {}

    def first(side: str, bases: tuple[str, ...], used: set[int]) -> int | None:
        for base in bases:
            for j, key in enumerate(keys):
                if key == (side, base) and j not in used:
                    return j
        return None

    for canon, bases in _CENTER_NAMES.items():
        j = first("", bases, set())
        if j is not None:
            found[canon] = j
    for side in ("left", "right"):
        used: set[int] = set()
        for part, bases in _SIDE_NAMES.items():
            j = first(side, bases, used)
            if j is not None:
                found[f"{side}_{part}"] = j
                used.add(j)
        # "Shoulder" is the clavicle in Mixamo / Bandai naming and the upper arm where a separate
        # collar or clavicle joint exists: give it to whichever of the two is still missing.
        j = first(side, ("shoulder",), used)
        if j is not None:
            for part in ("shoulder", "collar"):
                if f"{side}_{part}" not in found:
                    found[f"{side}_{part}"] = j
                    break
    return found
