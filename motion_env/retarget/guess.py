"""A mapping table guessed from body names, for an MJCF that comes without one.

Bodies are sorted into sides (``left``/``l`` or ``right``/``r`` as a word of the name) and parts
(hip, knee, ankle; shoulder, elbow, wrist) by the words of their names. Of several bodies of one
part (a hip with pitch, roll and yaw links) the one nearest the root is taken: its origin is the
joint. The foot is the last body below the ankle. The pelvis is the body both hips hang from, the
torso the one both shoulders hang from.

Nothing is guessed silently: :func:`guess_table` warns with the whole mapping (``motion-env
retarget --show-mapping`` prints it), and names each chain it did not find. Legs are required (no
legs: ValueError); an arm without a shoulder and an elbow is not tracked, a hand without a wrist
is not (the arm is), each with a warning that names it.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import mujoco

from motion_env.retarget.table import RobotTable, Task

__all__ = ["PART_PATTERNS", "guess_table"]

# Words that name each part, tried on the lower-cased body name.
PART_PATTERNS: dict[str, str] = {
    "hip": r"hip|thigh|upper_?leg|up_?leg",
    "knee": r"knee|shin|shank|calf|lower_?leg|low_?leg",
    "ankle": r"ankle|foot",
    "shoulder": r"shoulder|upper_?arm|up_?arm",
    "elbow": r"elbow|forearm|fore_?arm|lower_?arm|low_?arm",
    "wrist": r"wrist|hand",
}
_SIDES = {"left": r"(^|[^a-z])(l|left)([^a-z]|$)|left", "right": r"(^|[^a-z])(r|right)([^a-z]|$)|right"}
# Costs of a guessed table: the same weights as the shipped tables.
_COSTS = {"hip": 5.0, "knee": 1.0, "ankle": 10.0, "shoulder": 1.0, "elbow": 1.0, "wrist": 5.0}
_ORIENTATION_COSTS = {"pelvis": 2.0, "torso": 1.0, "foot": 2.0}


def _depth(model: mujoco.MjModel, body: int) -> int:
    depth = 0
    while body > 0:
        body, depth = model.body_parentid[body], depth + 1
    return depth


def _ancestors(model: mujoco.MjModel, body: int) -> list[int]:
    """`body` and its ancestors up to the world, nearest first."""
    out = [body]
    while out[-1] > 0:
        out.append(int(model.body_parentid[out[-1]]))
    return out


def _common_ancestor(model: mujoco.MjModel, a: int, b: int) -> int:
    up = set(_ancestors(model, b))
    return next(x for x in _ancestors(model, a) if x in up)


def _find(model: mujoco.MjModel, names: list[str], side: str, part: str, below: int | None) -> int | None:
    """The body of `part` on `side` nearest the root (under `below` when given), or None."""
    found = [
        b
        for b, name in enumerate(names)
        if b > 0
        and re.search(_SIDES[side], name)
        and re.search(PART_PATTERNS[part], name)
        and (below is None or below in _ancestors(model, b))
    ]
    return min(found, key=lambda b: (_depth(model, b), b)) if found else None


def _root(model: mujoco.MjModel, path: Path) -> int:
    free = [j for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    if len(free) != 1:
        raise ValueError(
            f"{path}: a humanoid to retarget onto needs exactly one free joint (its floating root); "
            f"this model has {len(free)}"
        )
    return int(model.jnt_bodyid[free[0]])


def _limbs(model: mujoco.MjModel, path: Path) -> tuple[dict[str, int], list[str]]:
    """(human joint -> body of both legs and of the arms found, the chains not found), or
    ValueError "no legs found"."""
    names = [
        (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "").lower() for b in range(model.nbody)
    ]
    bodies: dict[str, int] = {}
    missing: list[str] = []
    for side in _SIDES:
        hip = _find(model, names, side, "hip", None)
        knee = _find(model, names, side, "knee", hip) if hip is not None else None
        ankle = _find(model, names, side, "ankle", knee) if knee is not None else None
        if ankle is None:
            raise ValueError(
                f"no legs found in {path}: no {side} hip, knee and ankle bodies (body names with "
                f"'{side}' or '{side[0]}' and {PART_PATTERNS['hip']!r}, {PART_PATTERNS['knee']!r}, "
                f"{PART_PATTERNS['ankle']!r}, one below the other); write a mapping table for it "
                f"(see motion_env/retarget/table.py)"
            )
        bodies.update({f"{side}_hip": hip, f"{side}_knee": knee, f"{side}_ankle": ankle})
        shoulder = _find(model, names, side, "shoulder", None)
        elbow = _find(model, names, side, "elbow", shoulder) if shoulder is not None else None
        wrist = _find(model, names, side, "wrist", elbow) if elbow is not None else None
        if elbow is None:
            missing.append(
                f"no {side} arm (a body named like {PART_PATTERNS['shoulder']!r} with one like "
                f"{PART_PATTERNS['elbow']!r} below it): the {side} arm is not tracked"
            )
            continue
        bodies.update({f"{side}_shoulder": shoulder, f"{side}_elbow": elbow})
        if wrist is None:
            missing.append(
                f"no {side} hand (a body named like {PART_PATTERNS['wrist']!r} below the {side} elbow): "
                f"the {side} hand is not tracked, the arm is"
            )
        else:
            bodies[f"{side}_wrist"] = wrist
    return bodies, missing


def guess_table(model: mujoco.MjModel, path: Path) -> RobotTable:
    """A :class:`RobotTable` for `model` from its body names, or ValueError "no legs found"."""
    bodies, missing = _limbs(model, path)
    root = _root(model, path)

    def name(b: int) -> str:
        return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b)

    tasks = [
        Task(frame=name(b), human=joint, position_cost=_COSTS[joint.split("_", 1)[1]])
        for joint, b in bodies.items()
    ]
    pelvis = _common_ancestor(model, bodies["left_hip"], bodies["right_hip"])
    tasks.append(
        Task(frame=name(pelvis), orientation="pelvis", orientation_cost=_ORIENTATION_COSTS["pelvis"])
    )
    if "left_shoulder" in bodies and "right_shoulder" in bodies:
        torso = _common_ancestor(model, bodies["left_shoulder"], bodies["right_shoulder"])
        if torso != pelvis:
            tasks.append(
                Task(frame=name(torso), orientation="torso", orientation_cost=_ORIENTATION_COSTS["torso"])
            )
    feet = {}
    for side in _SIDES:
        foot = bodies[f"{side}_ankle"]
        while children := [b for b in range(model.nbody) if model.body_parentid[b] == foot and b != foot]:
            foot = children[0]
        feet[side] = name(foot)
        tasks.append(
            Task(frame=name(foot), orientation=f"{side}_foot", orientation_cost=_ORIENTATION_COSTS["foot"])
        )
    home = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, 0) if model.nkey else None
    table = RobotTable(
        robot=path.stem,
        model=path,
        root=name(root),
        feet=feet,
        tasks=tuple(tasks),
        home=home,
        source=f"{path} (mapping guessed from body names)",
    )
    for message in missing:
        warnings.warn(f"{path}: {message}", UserWarning, stacklevel=2)
    mapped = [f"{t.human or t.orientation + ' orientation'} -> {t.frame}" for t in table.tasks]
    warnings.warn(
        f"{path} has no mapping table; guessed from its body names: {', '.join(mapped)} "
        "(motion-env retarget --show-mapping prints it; a table changes it, see "
        "motion_env/retarget/table.py)",
        UserWarning,
        stacklevel=2,
    )
    return table
