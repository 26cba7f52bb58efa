"""`retarget`: a human clip -> a robot clip (MuJoCo qpos), checked at the boundary.

The stages, each in its own module:

1. resample the clip to the robot's rate (:func:`motion_env.motion.kinematics.resample`);
2. scale it onto the robot and turn it into IK targets (:mod:`.ik_goals`);
3. solve the IK frame by frame, warm-started, the joints' soft ranges as constraints, the centre
   of mass placed horizontally where the human's is, scaled (:mod:`.ik`);
4. low-pass the result (:mod:`.smoothing`), cap the joint speed and clip every joint into its
   soft range (:mod:`.limits`): the returned clip never leaves it (90 % of each joint's range
   about its centre by default, as mjlab's robots use);
5. set each frame's root height from the lowest foot geom (:mod:`.floor`): the feet stand on the
   floor while the human's do and lift as high as the human's (scaled) when they leave it, and
   no geom goes below the floor; in a flight (both of the human's feet in the air) the centre of
   mass falls freely (:mod:`.flight`);
6. measure how far each tracked frame ended from its target (the residuals).
"""

from __future__ import annotations

import os
from numbers import Real

import numpy as np

from motion_env.motion.kinematics import resample
from motion_env.motion.skeleton import FPS
from motion_env.motion.types import Motion
from motion_env.motion.validation import check_joints
from motion_env.retarget.flight import AIR_CLEARANCE, ballistic_lift
from motion_env.retarget.ik import IKSettings, solve_clip
from motion_env.retarget.ik_goals import compute_targets
from motion_env.retarget.limits import SOFT_LIMIT, check_soft_limit, clip_to_limits, limit_speed
from motion_env.retarget.result import RobotMotion
from motion_env.retarget.robot import load_robot
from motion_env.retarget.smoothing import smooth_qpos

__all__ = ["MAX_FPS", "check_rate", "retarget"]

MAX_FPS = 1000.0


def check_rate(value: object, name: str, upper: float | None = None) -> float:
    """A positive finite number (a frame rate, a speed), at most `upper`; else ValueError naming `name`."""
    if isinstance(value, bool) or not isinstance(value, Real) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive number, got {value!r}")
    if upper is not None and value > upper:
        raise ValueError(f"{name} must be at most {upper:g}, got {value!r}")
    return float(value)


def _check_motion(motion: Motion | np.ndarray) -> tuple[np.ndarray, float]:
    """(joints (T, 22, 3) float64, fps) of a Motion or a joints array (20 fps), or an error."""
    if isinstance(motion, Motion):
        joints, fps = motion.joints, motion.fps
    elif isinstance(motion, (np.ndarray, list, tuple)):
        joints, fps = np.asarray(motion, dtype=np.float64), float(FPS)
    else:
        raise TypeError(
            f"motion must be a motion_env.Motion or a (T, 22, 3) joints array, got {type(motion)}"
        )
    joints = check_joints(joints, "motion")  # shape, NaN and infinite values
    if joints.shape[0] < 2:
        raise ValueError(f"motion has {joints.shape[0]} frame; retargeting needs a clip of at least 2 frames")
    return joints, fps


def retarget(
    motion: Motion | np.ndarray,
    robot: str | os.PathLike = "unitree_g1",
    fps: float = 50.0,
    *,
    max_joint_speed: float = 15.0,
    smoothing: float = 0.03,
    soft_limit: float = SOFT_LIMIT,
    ik: IKSettings | None = None,
) -> RobotMotion:
    """Retarget a human clip onto a humanoid robot.

    Args:
        motion: a :class:`~motion_env.Motion`, or a (T, 22, 3) joints array at 20 fps.
        robot: a known robot (:func:`motion_env.retarget.known_robots`: ``"unitree_g1"``,
            ``"booster_t1"``), a mapping table (.json), or the path of any humanoid MJCF (.xml;
            the mapping is guessed from its body names).
        fps: frame rate of the result (the clip is resampled).
        max_joint_speed: fastest a joint may turn, rad/s (or m/s for a slide joint).
        smoothing: standard deviation of the Gaussian low-pass over the result, seconds (0: none).
        soft_limit: share of each joint's range, about its centre, that the clip stays inside
            (1: the whole range).
        ik: the solver's settings (iterations, damping); the defaults suit both shipped robots.

    Returns:
        A :class:`~motion_env.retarget.result.RobotMotion`: qpos (T', nq) at `fps` in MuJoCo's
        layout (root position, root quaternion w, x, y, z, then the joints in model order) and the
        per-frame residuals of the tracked frames.

    Raises:
        ValueError: a motion with NaN or infinite values, fewer than 2 frames, a rate that is not
            a positive number, an unknown robot name (the message lists the known ones), a model
            that is not a humanoid ("no legs found").
        TypeError: a motion that is neither a Motion nor an array.
        FileNotFoundError: a robot path that does not exist.
    """
    joints, src_fps = _check_motion(motion)
    fps = check_rate(fps, "fps", MAX_FPS)
    max_step = check_rate(max_joint_speed, "max_joint_speed") / fps
    if isinstance(smoothing, bool) or not isinstance(smoothing, Real) or not 0 <= smoothing < np.inf:
        raise ValueError(f"smoothing must be a number of seconds >= 0, got {smoothing!r}")
    soft_limit = check_soft_limit(soft_limit)
    if not isinstance(robot, (str, os.PathLike)):
        raise TypeError(f"robot must be a robot name or a path, got {type(robot)}")
    bot = load_robot(robot)
    model = bot.model

    joints = resample(joints, src_fps, fps) if fps != src_fps else joints
    targets = compute_targets(bot, joints)
    qpos = solve_clip(bot, targets, ik or IKSettings(), soft_limit)
    qpos = smooth_qpos(model, qpos, smoothing * fps)
    limit_speed(model, qpos, max_step)
    clip_to_limits(bot.soft_model(soft_limit), qpos)

    pose = bot.kinematics(qpos)
    # Raise or lower each frame so that the feet are where the human's are, but no geom is
    # below the floor (a knee or a hand on the ground wins over the feet).
    lift = np.maximum(targets.floor_height - pose.foot_lowest, -pose.lowest)
    # In a flight (both of the human's feet off the floor) the centre of mass falls freely.
    in_air = targets.floor_height >= AIR_CLEARANCE
    lift += ballistic_lift(pose.com[:, 2] + lift, in_air, fps)
    lift = np.maximum(lift, -pose.lowest)
    qpos[:, bot.root_qpos + 2] += lift
    frame_positions = pose.frame_positions + lift[:, None, None] * np.array([0.0, 0.0, 1.0])
    tracked = [k for k, task in enumerate(bot.tasks) if task.position_cost > 0]
    residuals = np.linalg.norm(frame_positions[:, tracked] - targets.positions[:, tracked], axis=-1)
    return RobotMotion(
        qpos=qpos,
        fps=fps,
        joint_names=bot.joint_names,
        robot=bot.key,
        residuals=residuals,
        residual_names=tuple(bot.tasks[k].human for k in tracked),
    )
