"""How good a retargeted clip is: the numbers ``scripts/evaluate_retarget.py`` reports.

:func:`measure` compares a robot clip with the human clip it came from:

| key | what | target |
|---|---|---|
| ``range_violations`` | (frame, joint) entries outside the joint's range | 0 |
| ``soft_range_violations`` | entries outside the soft range (:data:`.limits.SOFT_LIMIT` of it) | 0 |
| ``penetration_cm`` | deepest any collision geom goes below the floor | <= 1.5 |
| ``self_collision_cm`` | deepest two of the robot's own geoms go into each other (an arm into the torso) | |
| ``self_collision_share`` | share of frames where two of the robot's geoms overlap by more than 5 mm | |
| ``stand_float_cm`` | highest the robot's lowest point gets while the human stands | <= 4 |
| ``max_jump_rad`` | largest change of one joint between frames (at the clip's rate) | <= 0.35 at 50 fps |
| ``hand_corr``, ``foot_corr`` | correlation of wrist / ankle heights with the human's | >= 0.8, >= 0.6 |
| ``distance_ratio`` | horizontal path of the robot's root / the human's pelvis | 0.5 to 1.1 |
| ``hand_residual_cm``, ``foot_residual_cm`` | mean distance of wrists / ankles from their targets | |

"While the human stands": frames where the human's lowest foot joint is within
:data:`STAND_CLEARANCE` of its standing height. A correlation is None when the human's heights
hardly move (a standing clip's feet), the distance ratio when the human travels less than
:data:`MIN_TRAVEL`.
"""

from __future__ import annotations

import mujoco
import numpy as np

from motion_env.motion.kinematics import resample
from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.motion.types import Motion
from motion_env.retarget.ik_goals import human_clearance
from motion_env.retarget.limits import SOFT_LIMIT, range_violations
from motion_env.retarget.result import RobotMotion
from motion_env.retarget.robot import Robot, load_robot

__all__ = ["MIN_TRAVEL", "STAND_CLEARANCE", "QUALITY_BOUNDS", "measure", "self_contact_depth"]

STAND_CLEARANCE = 0.025  # metres
MIN_TRAVEL = 0.5  # metres
MIN_HEIGHT_STD = 0.01  # metres: below this a height "does not move" and has no correlation
# The bounds each number should meet: (low, high), None for no bound.
QUALITY_BOUNDS: dict[str, tuple[float | None, float | None]] = {
    "range_violations": (None, 0),
    "soft_range_violations": (None, 0),
    "penetration_cm": (None, 1.5),
    "stand_float_cm": (None, 4.0),
    "max_jump_rad": (None, 0.35),
    "hand_corr": (0.8, None),
    "foot_corr": (0.6, None),
    "distance_ratio": (0.5, 1.1),
}


def _corr(a: np.ndarray, b: np.ndarray) -> float | None:
    if b.std() < MIN_HEIGHT_STD or a.std() < 1e-9:
        return None
    return float(np.corrcoef(a, b)[0, 1])


def _mean_corr(values: list[float | None]) -> float | None:
    kept = [v for v in values if v is not None]
    return float(np.mean(kept)) if kept else None


def _path_length(xy: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=-1).sum())


def self_contact_depth(robot: Robot, qpos: np.ndarray) -> np.ndarray:
    """(T,) how deep two of the robot's own geoms go into each other, per frame of qpos (T, nq)
    (metres, 0 if none): MuJoCo's collision detection, which leaves out parent and child."""
    model, data = robot.model, mujoco.MjData(robot.model)
    out = np.zeros(len(qpos))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_fwdPosition(model, data)
        contacts = data.contact[: data.ncon]
        own = (model.geom_bodyid[contacts.geom[:, 0]] > 0) & (model.geom_bodyid[contacts.geom[:, 1]] > 0)
        if own.any():
            out[t] = max(0.0, float(-contacts.dist[own].min()))
    return out


def measure(
    robot_motion: RobotMotion, motion: Motion, soft_limit: float = SOFT_LIMIT
) -> dict[str, float | int | None]:
    """The numbers of the module docstring for `robot_motion`, retargeted from `motion` (the soft
    range: `soft_limit` of each joint's range about its centre)."""
    robot = load_robot(robot_motion.robot)
    qpos = robot_motion.qpos
    pose = robot.kinematics(qpos)
    human = resample(motion.joints.astype(np.float64), motion.fps, robot_motion.fps)[: len(qpos)]
    standing = human_clearance(human) < STAND_CLEARANCE

    def robot_height(joint: str) -> np.ndarray | None:
        k = next((k for k, t in enumerate(robot.tasks) if t.human == joint), None)
        return None if k is None else pose.frame_positions[:, k, 2]

    def corr(joints: tuple[str, str]) -> float | None:
        values = []
        for joint in joints:
            height = robot_height(joint)
            if height is not None:
                values.append(_corr(height, human[:, JOINT_INDEX[joint], 1]))
        return _mean_corr(values)

    def residual(joints: tuple[str, str]) -> float | None:
        if robot_motion.residuals is None:
            return None
        cols = [k for k, n in enumerate(robot_motion.residual_names) if n in joints]
        return float(100 * robot_motion.residuals[:, cols].mean()) if cols else None

    human_path = _path_length(human[:, 0, [0, 2]])
    self_depth = self_contact_depth(robot, qpos)
    jumps = np.abs(np.diff(robot_motion.dof_pos, axis=0))
    return {
        "frames": int(len(qpos)),
        "range_violations": range_violations(robot.model, qpos),
        "soft_range_violations": range_violations(robot.soft_model(soft_limit), qpos),
        "penetration_cm": float(100 * max(0.0, -pose.lowest.min())),
        "self_collision_cm": float(100 * self_depth.max()),
        "self_collision_share": float((self_depth > 0.005).mean()),
        "stand_float_cm": float(100 * pose.lowest[standing].max()) if standing.any() else None,
        "stand_share": float(standing.mean()),
        "max_jump_rad": float(jumps.max()) if jumps.size else 0.0,
        "hand_corr": corr(("left_wrist", "right_wrist")),
        "foot_corr": corr(("left_ankle", "right_ankle")),
        "distance_ratio": _path_length(qpos[:, :2]) / human_path if human_path >= MIN_TRAVEL else None,
        "hand_residual_cm": residual(("left_wrist", "right_wrist")),
        "foot_residual_cm": residual(("left_ankle", "right_ankle")),
    }
