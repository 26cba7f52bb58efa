"""Where each robot frame should be, frame by frame: the human clip scaled onto the robot.

- **Scale.** The robot's legs are shorter than the human's: the root path and the heights are
  scaled by ``leg scale = robot leg / human leg`` (hip, knee, ankle, summed segment lengths in
  both rest poses), so the robot takes the human's steps at its own size. Arms get their own
  scale (robot arm / human arm).
- **Heights** are shifted so that a standing human's ankles are at the height of a standing
  robot's ankles above its soles.
- **Trunk points** (hips, shoulders, neck, ...) keep the robot's own proportions: each is placed
  from the scaled mid-hip point by the robot's rest offset, turned with the human's pelvis (hips)
  or torso (shoulders, neck, head), plus the scaled part of the human's own offset that the turn
  does not explain (a shrug, a bent spine).
- **Limb points** (knee, ankle, elbow, wrist) hang from their limb's root target by the human's
  own limb vector times the limb scale, so a hand or foot sits where the human's is relative to
  the body.
- **Feet**: each ankle target is raised or lowered so that the robot's foot, turned as the human's
  is, touches the floor when the human's does (the two feet are not the same shape).
- **Orientations** are the human segment's rotation away from its rest pose applied to the robot
  frame's rest orientation (:func:`motion_env.retarget.human.rest_relative`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion_env.motion.mass import centre_of_mass
from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.replay.humanoid import rest_positions, to_mujoco
from motion_env.retarget.human import LIMBS, frames, limb_length, rest_relative
from motion_env.retarget.robot import Robot

__all__ = ["Targets", "compute_targets", "foot_clearance", "human_clearance", "limb_scales"]

# Trunk joints and the segment they turn with (the rest are limb joints, see human.LIMBS).
_TRUNK_SEGMENT = {
    "pelvis": "pelvis", "left_hip": "pelvis", "right_hip": "pelvis", "spine1": "pelvis",
    "spine2": "torso", "spine3": "torso", "neck": "torso", "head": "torso", "left_collar": "torso",
    "right_collar": "torso", "left_shoulder": "torso", "right_shoulder": "torso",
}  # fmt: skip
_LIMB_OF = {joint: limb for limb, names in LIMBS.items() for joint in names[1:]}


@dataclass
class Targets:
    """IK targets of a clip, one row per frame.

    Attributes:
        positions: (T, K, 3) world target of each of the robot's K tasks (NaN: no position).
        rotations: (T, K, 3, 3) world target orientation of each task (identity: none).
        root_position, root_rotation: (T, 3), (T, 3, 3) a first guess of the root body's pose.
        com: (T, 3) where the robot's centre of mass belongs: the human's, scaled like the root
            path (its height is not used).
        floor_height: (T,) where the robot's lowest foot point belongs: 0 while the human
            stands, the scaled height of the human's feet above their standing height otherwise.
        leg_scale, arm_scale: robot limb length / human limb length.
    """

    positions: np.ndarray
    rotations: np.ndarray
    root_position: np.ndarray
    root_rotation: np.ndarray
    com: np.ndarray
    floor_height: np.ndarray
    leg_scale: float
    arm_scale: float


def _limb_scale(robot: Robot, joints: np.ndarray, kind: str) -> float:
    """Robot limb length / human limb length, over the joints of that kind of limb the robot maps."""
    ratios = []
    for limb, names in LIMBS.items():
        mapped = tuple(n for n in names if n in robot.rest_points)
        if not limb.endswith(kind) or len(mapped) < 2:
            continue
        points = np.stack([robot.rest_points[n] for n in mapped])
        robot_length = float(np.linalg.norm(np.diff(points, axis=0), axis=-1).sum())
        ratios.append(robot_length / max(limb_length(joints, mapped), 1e-6))
    return float(np.mean(ratios)) if ratios else 0.0


def _ankle_height_offset(robot: Robot, leg_scale: float) -> float:
    """How much higher the robot's ankles stand above its soles than the scaled human's do: added
    to every target height, so that a standing human's ankles are a standing robot's."""
    ankles = [n for n in ("left_ankle", "right_ankle") if n in robot.rest_points]
    if not ankles:
        return 0.0
    robot_height = np.mean([robot.rest_points[n][2] for n in ankles]) - robot.rest_sole
    human_height = rest_positions()[[JOINT_INDEX[n] for n in ankles], 1].mean()
    return float(robot_height - leg_scale * human_height)


def foot_clearance(joints: np.ndarray) -> dict[str, np.ndarray]:
    """Per foot ("left", "right"), (T,) how far it is above where it is when standing (metres).

    joints: (T, 22, 3) in the motion's own axes (Y up). The ankle and the toe are each measured
    from their height in the canonical rest pose and the lower counts, so a flat-footed stance,
    a raised heel and a raised toe all read about 0.
    """
    rest = rest_positions()
    out = {}
    for side in ("left", "right"):
        idx = [JOINT_INDEX[f"{side}_ankle"], JOINT_INDEX[f"{side}_foot"]]
        out[side] = (joints[:, idx, 1] - rest[idx, 1]).min(axis=1)
    return out


def human_clearance(joints: np.ndarray) -> np.ndarray:
    """(T,) how far the human's lower foot is above where it is when standing (metres);
    :func:`foot_clearance` of the lower foot."""
    clearance = foot_clearance(joints)
    return np.minimum(clearance["left"], clearance["right"])


def _plant_feet(
    robot: Robot, points: dict[str, np.ndarray], turn: dict[str, np.ndarray], heights: dict[str, np.ndarray]
) -> None:
    """Move each ankle target up or down, in place, so that the robot's foot, turned as the
    target says, has its lowest point at `heights[side]` (T,).

    The human's foot and the robot's are not the same shape: a heel raised by the same angle puts
    the robot's toe lower or higher than the human's. The legs absorb that, not the whole body.
    """
    for side, geoms in robot.feet.items():
        ankle = f"{side}_ankle"
        if ankle not in points:
            continue
        rest_xpos, rest_xmat = robot.rest_feet[side]  # (G, 3), (G, 9)
        foot_turn = turn[f"{side}_foot"]  # (T, 3, 3)
        offsets = rest_xpos - robot.rest_points[ankle]  # (G, 3) from the ankle, rest pose
        xpos = points[ankle][:, None] + np.einsum("tij,gj->tgi", foot_turn, offsets)
        xmat = np.einsum("tij,gjk->tgik", foot_turn, rest_xmat.reshape(-1, 3, 3)).reshape(*xpos.shape[:2], 9)
        points[ankle][:, 2] += heights[side] - geoms.lowest(xpos, xmat).min(axis=1)


def limb_scales(robot: Robot, joints: np.ndarray) -> tuple[float, float]:
    """(leg scale, arm scale) of `robot` for a human clip (T, 22, 3), motion axes: robot limb length
    / the human's median limb length over the frames."""
    joints = to_mujoco(joints).astype(np.float64)
    return _limb_scale(robot, joints, "leg"), _limb_scale(robot, joints, "arm")


def compute_targets(robot: Robot, joints: np.ndarray, scales: tuple[float, float] | None = None) -> Targets:
    """IK targets for `robot` from a human clip.

    joints: (T, 22, 3) world joint positions in the motion's axes (Y up, facing +Z).
    scales: (leg scale, arm scale), default :func:`limb_scales` of the clip. With the scales
    given, each frame's targets depend on that frame alone, so a stream can compute them one
    frame at a time (:class:`motion_env.retarget.stream.StreamRetargeter`).
    """
    clearance = foot_clearance(joints)
    joints = to_mujoco(joints).astype(np.float64)  # (T, 22, 3): x forward, y left, z up
    turn = rest_relative(frames(joints))  # segment -> (T, 3, 3)
    if scales is None:
        leg_scale = _limb_scale(robot, joints, "leg")
        arm_scale = _limb_scale(robot, joints, "arm")
    else:
        leg_scale, arm_scale = float(scales[0]), float(scales[1])
    num_frames = joints.shape[0]

    def human(name: str) -> np.ndarray:
        return joints[:, JOINT_INDEX[name]]

    human_rest = to_mujoco(rest_positions())
    human_mid = 0.5 * (human("left_hip") + human("right_hip"))  # (T, 3)
    human_rest_mid = 0.5 * (human_rest[JOINT_INDEX["left_hip"]] + human_rest[JOINT_INDEX["right_hip"]])
    rest_mid = 0.5 * (robot.rest_points["left_hip"] + robot.rest_points["right_hip"])
    mid = leg_scale * human_mid  # the robot's mid-hip point
    mid[:, 2] += _ankle_height_offset(robot, leg_scale)
    points: dict[str, np.ndarray] = {}
    for name in robot.rest_points:  # trunk points first: limbs hang from them
        if name in _TRUNK_SEGMENT:
            segment = turn[_TRUNK_SEGMENT[name]]
            # What the segment's turn does not explain (a shrug of the shoulders, a bent spine)
            # moves the robot's point too, scaled.
            rigid = human_mid + segment @ (human_rest[JOINT_INDEX[name]] - human_rest_mid)
            points[name] = (
                mid + segment @ (robot.rest_points[name] - rest_mid) + leg_scale * (human(name) - rigid)
            )
    for name in robot.rest_points:
        if name in _LIMB_OF:
            root = LIMBS[_LIMB_OF[name]][0]
            scale = leg_scale if _LIMB_OF[name].endswith("leg") else arm_scale
            points[name] = points[root] + scale * (human(name) - human(root))
    heights = {side: leg_scale * np.maximum(c, 0.0) for side, c in clearance.items()}
    _plant_feet(robot, points, turn, heights)

    positions = np.full((num_frames, len(robot.tasks), 3), np.nan)
    rotations = np.broadcast_to(np.eye(3), (num_frames, len(robot.tasks), 3, 3)).copy()
    for k, task in enumerate(robot.tasks):
        if task.human is not None:
            positions[:, k] = points[task.human]
        if task.orientation is not None:
            rotations[:, k] = turn[task.orientation] @ robot.rest_rotations[k]
    return Targets(
        positions=positions,
        rotations=rotations,
        root_position=mid + turn["pelvis"] @ (robot.rest_root - rest_mid),
        root_rotation=turn["pelvis"],
        com=leg_scale * centre_of_mass(joints),
        floor_height=np.minimum(heights["left"], heights["right"]),
        leg_scale=leg_scale,
        arm_scale=arm_scale,
    )
