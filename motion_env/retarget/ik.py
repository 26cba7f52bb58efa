"""Differential inverse kinematics over a clip (mink on MuJoCo), warm-started frame to frame.

Each frame starts from the previous frame's solution, moved by the change of the root target, and
takes a few damped QP steps (:func:`mink.solve_ik`, solver daqp) over

- the tracked robot frames, their positions and orientations (costs from the table), and the
  horizontal place of the centre of mass (:attr:`IKSettings.com_cost`), all one stacked task
  (:class:`.frame_tasks.FrameTargets`),
- a posture task pulling every joint lightly towards the home pose (it settles the joints no
  target reaches: wrists, head, the arm's twist),

under the joints' soft ranges as hard constraints (:class:`mink.ConfigurationLimit` on the model
whose ranges are shrunk to `soft_limit` of themselves, :func:`.limits.soft_limited`), and with
the arms kept off the trunk, the thighs and each other and the shins off each other
(:class:`mink.CollisionAvoidanceLimit` over :func:`.collisions.self_collision_pairs`). The
first frame starts from the home pose (inside the soft ranges) at the root target and takes more
steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion_env.args import install_line
from motion_env.motion.rotations import quat_from_matrix
from motion_env.motion.validation import CheckedConfig, NonNegativeFloat, PositiveFloat, PositiveInt
from motion_env.retarget.collisions import self_collision_pairs
from motion_env.retarget.ik_goals import Targets
from motion_env.retarget.limits import SOFT_LIMIT, clip_to_limits
from motion_env.retarget.robot import Robot

__all__ = ["FrameSolver", "IKSettings", "solve_clip"]


@dataclass(frozen=True)
class IKSettings(CheckedConfig):
    """How hard the solver works per frame."""

    iterations: PositiveInt = 4  # QP steps per frame (warm-started)
    first_iterations: PositiveInt = 60  # QP steps on the first frame (from the home pose)
    tolerance: PositiveFloat = 1e-3  # stop a frame early when a step moves the joints less (rad)
    damping: PositiveFloat = 1.0  # Levenberg-Marquardt damping of every step (smaller steps, smoother)
    avoid_self_collision: bool = True  # keep arms off the trunk, thighs, each other; shins apart
    collision_margin: PositiveFloat = 0.01  # metres the IK keeps between those geoms
    # Weight of the centre of mass's horizontal place: the human's, scaled (0: not tracked). The
    # robots' masses are not spread as a human's: the T1's legs and trunk, moving as the human's,
    # swing its centre of mass 3 times as hard as the human's in a run, more than a foot on the
    # floor can push (the robot replay's root torque). 20 holds it; see docs/robots.md.
    com_cost: NonNegativeFloat = 20.0


def _mink():
    try:
        import mink
    except ImportError as exc:
        raise ImportError(f"retargeting needs the optional mink package: {install_line('robots')}") from exc
    return mink


class FrameSolver:
    """The IK of one robot, one frame at a time, each frame warm-started from the previous one.

    :func:`solve_clip` runs it over a clip; :class:`motion_env.retarget.stream.StreamRetargeter`
    runs one per character of a stream. :meth:`reset` makes the next frame a first frame again.
    """

    def __init__(
        self, robot: Robot, settings: IKSettings = IKSettings(), soft_limit: float = SOFT_LIMIT
    ) -> None:
        mink = _mink()
        self._mink, self.robot, self.settings = mink, robot, settings
        model = robot.soft_model(soft_limit)  # the same kinematics, the soft joint ranges
        self._home = clip_to_limits(model, robot.home.copy())
        self.configuration = mink.Configuration(model)
        from motion_env.retarget.frame_tasks import FrameTargets  # needs mink

        self.targets = FrameTargets(robot, settings.com_cost)
        posture = mink.PostureTask(model, cost=robot.table.posture_cost)
        posture.set_target(self._home)
        self.limits = [mink.ConfigurationLimit(model)]
        self._joint_limits = list(self.limits)
        pairs = self_collision_pairs(robot) if settings.avoid_self_collision else []
        if pairs:
            margin = settings.collision_margin
            self.limits.append(
                mink.CollisionAvoidanceLimit(
                    model,
                    pairs,
                    minimum_distance_from_collisions=margin,
                    collision_detection_distance=3 * margin,
                )
            )
        self.all_tasks = [self.targets, posture] if robot.table.posture_cost > 0 else [self.targets]
        self.reset()

    def reset(self) -> None:
        """Start over: the next frame starts from the home pose and takes ``first_iterations``."""
        self._q: np.ndarray | None = None
        self._root_target: np.ndarray | None = None

    def solve(self, targets: Targets, t: int = 0) -> np.ndarray:
        """(nq,) the solution of frame `t` of `targets` (a copy), warm-started from the last one."""
        mink, robot, settings = self._mink, self.robot, self.settings
        root = robot.root_qpos
        first = self._q is None
        if first:
            q = self._home.copy()
            q[root : root + 3] = targets.root_position[t]
            q[root + 3 : root + 7] = quat_from_matrix(targets.root_rotation[t])
        else:
            q = self._q
            q[root : root + 3] += targets.root_position[t] - self._root_target
        configuration = self.configuration
        configuration.update(q)
        self.targets.set_targets(targets.positions[t], targets.rotations[t], targets.com[t])
        dt = 1.0  # steps are displacements: no time scale
        for _ in range(settings.first_iterations if first else settings.iterations):
            try:
                step = mink.solve_ik(
                    configuration,
                    self.all_tasks,
                    dt,
                    solver="daqp",
                    damping=settings.damping,
                    limits=self.limits,
                )
            except mink.NoSolutionFound:  # the collision constraints cannot all hold: joint ranges only
                step = mink.solve_ik(
                    configuration,
                    self.all_tasks,
                    dt,
                    "daqp",
                    damping=settings.damping,
                    limits=self._joint_limits,
                )
            configuration.integrate_inplace(step, dt)
            if np.abs(step).max() < settings.tolerance:
                break
        self._q = configuration.q.copy()
        self._root_target = np.array(targets.root_position[t], dtype=np.float64)
        return self._q.copy()


def solve_clip(
    robot: Robot, targets: Targets, settings: IKSettings = IKSettings(), soft_limit: float = SOFT_LIMIT
) -> np.ndarray:
    """Joint positions that put the robot's frames on the targets, (T, nq) MuJoCo qpos, every joint
    inside `soft_limit` of its range."""
    solver = FrameSolver(robot, settings, soft_limit)
    num_frames = targets.positions.shape[0]
    out = np.empty((num_frames, robot.model.nq))
    for t in range(num_frames):
        out[t] = solver.solve(targets, t)
    return out
