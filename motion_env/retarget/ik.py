"""Differential inverse kinematics over a clip (mink on MuJoCo), warm-started frame to frame.

Each frame starts from the previous frame's solution, moved by the change of the root target, and
takes a few damped QP steps (:func:`mink.solve_ik`, solver daqp) over

- one frame task per tracked robot frame (position and orientation costs from the table),
- a posture task pulling every joint lightly towards the home pose (it settles the joints no
  target reaches: wrists, head, the arm's twist),

under the joint ranges as hard constraints (:class:`mink.ConfigurationLimit`). The first frame
starts from the home pose at the root target and takes more steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion_env.motion.rotations import quat_from_matrix
from motion_env.retarget.robot import Robot
from motion_env.retarget.targets import Targets

__all__ = ["IKSettings", "solve_clip"]


@dataclass(frozen=True)
class IKSettings:
    """How hard the solver works per frame."""

    iterations: int = 4  # QP steps per frame (warm-started)
    first_iterations: int = 60  # QP steps on the first frame (from the home pose)
    tolerance: float = 1e-3  # stop a frame early when a step moves the joints less than this (rad)
    damping: float = 1.0  # Levenberg-Marquardt damping of every step (smaller steps, smoother)

    def __post_init__(self) -> None:
        for name in ("iterations", "first_iterations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"IKSettings.{name} must be a positive int, got {value!r}")
        for name in ("tolerance", "damping"):
            if not getattr(self, name) > 0:
                raise ValueError(f"IKSettings.{name} must be > 0, got {getattr(self, name)!r}")


def solve_clip(robot: Robot, targets: Targets, settings: IKSettings = IKSettings()) -> np.ndarray:
    """Joint positions that put the robot's frames on the targets, (T, nq) MuJoCo qpos."""
    try:
        import mink
    except ImportError as exc:
        raise ImportError(
            'retargeting needs the optional mink package: pip install -c constraints.txt "motion-env[robots]"'
        ) from exc

    model = robot.model
    configuration = mink.Configuration(model)
    tasks = [
        mink.FrameTask(t.frame, t.type, position_cost=t.position_cost, orientation_cost=t.orientation_cost)
        for t in robot.tasks
    ]
    posture = mink.PostureTask(model, cost=robot.table.posture_cost)
    posture.set_target(robot.home)
    limits = [mink.ConfigurationLimit(model)]
    all_tasks = [*tasks, posture] if robot.table.posture_cost > 0 else tasks

    num_frames = targets.positions.shape[0]
    # SE3 targets as (w, x, y, z, x, y, z); a task with no position keeps 0 (its cost is 0).
    poses = np.concatenate([quat_from_matrix(targets.rotations), np.nan_to_num(targets.positions)], axis=-1)
    root = robot.root_qpos
    q = robot.home.copy()
    q[root : root + 3] = targets.root_position[0]
    q[root + 3 : root + 7] = quat_from_matrix(targets.root_rotation[0])
    out = np.empty((num_frames, model.nq))
    dt = 1.0  # steps are displacements: no time scale
    for t in range(num_frames):
        if t > 0:
            q[root : root + 3] += targets.root_position[t] - targets.root_position[t - 1]
        configuration.update(q)
        for task, pose in zip(tasks, poses[t]):
            task.set_target(mink.SE3(pose))
        for _ in range(settings.first_iterations if t == 0 else settings.iterations):
            step = mink.solve_ik(
                configuration, all_tasks, dt, solver="daqp", damping=settings.damping, limits=limits
            )
            configuration.integrate_inplace(step, dt)
            if np.abs(step).max() < settings.tolerance:
                break
        q = configuration.q.copy()
        out[t] = q
    return out
