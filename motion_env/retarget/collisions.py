"""Which of a robot's geoms the IK keeps apart: each arm from the trunk, the thighs and the other
arm; the two shins (and feet) from each other.

A human's hands pass close in front of the body (arms crossed, hands on the belly, a wave across
the chest) and hang close beside the thighs; scaled onto a robot with a thicker torso and wider
hips, the same targets put the forearm into the torso and the hand into the hip. A run's feet
pass close by each other, and a robot's feet are wider than a human's. The IK (:mod:`.ik`) keeps
these pairs of geom groups apart with mink's :class:`mink.CollisionAvoidanceLimit`, as
constraints like the joint ranges.

The groups come from the mapping table and the body tree, so any robot gets them:

- an **arm** is the subtree hanging from the trunk that holds the body of the table's elbow
  frame (for the G1, ``left_shoulder_pitch_link`` and everything below it);
- a **leg** likewise for the knee; its **shin** is the subtree of the knee frame's body, its
  **thigh** the rest (hip links, thigh);
- the **trunk** is every other body (pelvis, waist, torso, head).

Only collision geoms count (contype or conaffinity set), as MuJoCo collides them.
"""

from __future__ import annotations

import mujoco

from motion_env.retarget.floor import collision_geoms
from motion_env.retarget.robot import Robot, subtree

__all__ = ["limb_roots", "self_collision_pairs"]


def _frame_body(robot: Robot, human: str) -> int | None:
    task = robot.table.point(human)
    if task is None:
        return None
    i = mujoco.mj_name2id(
        robot.model, mujoco.mjtObj.mjOBJ_BODY if task.type == "body" else mujoco.mjtObj.mjOBJ_SITE, task.frame
    )
    return i if task.type == "body" else int(robot.model.site_bodyid[i])


def _ancestors(model: mujoco.MjModel, body: int) -> list[int]:
    out = [body]
    while out[-1] > 0:
        out.append(int(model.body_parentid[out[-1]]))
    return out


def limb_roots(robot: Robot, joint: str) -> dict[str, int]:
    """Side -> the body each limb hangs from the trunk by, for the limb of human `joint`
    (``"elbow"``: arms, ``"knee"``: legs); sides the table does not map are left out."""
    model = robot.model
    bodies = {side: _frame_body(robot, f"{side}_{joint}") for side in ("left", "right")}
    bodies = {side: b for side, b in bodies.items() if b is not None}
    if not bodies:
        return {}
    if len(bodies) == 1:  # one limb: it hangs from the robot's root
        common = robot.root
    else:
        up = set(_ancestors(model, bodies["right"]))
        common = next(b for b in _ancestors(model, bodies["left"]) if b in up)
    roots = {}
    for side, body in bodies.items():
        chain = _ancestors(model, body)
        k = chain.index(common)
        if k > 0:
            roots[side] = chain[k - 1]
    return roots


def self_collision_pairs(robot: Robot) -> list[tuple[list[int], list[int]]]:
    """Pairs of geom groups (geom ids) to keep apart: each arm and the trunk, each arm and the
    upper legs (hips and thighs, where hanging hands are), the two arms, the two lower legs (from
    the knee frame's body down, where a run's feet pass). Fewer pairs, less work per IK step: a
    hand does not reach a foot in a clip a robot should follow."""
    model = robot.model
    arms = {side: subtree(model, [b]) for side, b in limb_roots(robot, "elbow").items()}
    legs = {side: subtree(model, [b]) for side, b in limb_roots(robot, "knee").items()}
    shins = {side: subtree(model, [b]) for side in legs if (b := _frame_body(robot, f"{side}_knee"))}
    limbs = set().union(*arms.values(), *legs.values())
    trunk = [b for b in subtree(model, [robot.root]) if b not in limbs]
    thighs = [b for side, bodies in legs.items() for b in bodies if b not in shins.get(side, [])]

    def geoms(bodies: list[int]) -> list[int]:
        return [int(g) for g in collision_geoms(model, bodies) if model.geom_bodyid[g] in bodies]

    arm_geoms = {side: geoms(bodies) for side, bodies in arms.items()}
    pairs = [(arm, other) for arm in arm_geoms.values() for other in (geoms(trunk), geoms(thighs))]
    for sides in (arm_geoms, {side: geoms(bodies) for side, bodies in shins.items()}):
        if len(sides) == 2:
            pairs.append((sides["left"], sides["right"]))
    return [(a, b) for a, b in pairs if a and b]
