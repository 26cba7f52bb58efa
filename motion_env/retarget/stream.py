"""Robot qpos while a motion streams: a causal, frame-by-frame retargeter.

>>> from motion_env.retarget import StreamRetargeter
>>> rt = StreamRetargeter("unitree_g1", batch=1)
>>> qpos = rt.step(joints)        # joints (B, 22, 3) of the frame just emitted -> (B, nq)

Every frame uses that frame and the past only, so an RL agent or a tracker gets the robot's
reference motion as the human's is generated (the environments' ``robot=`` option). Per frame,
the stages of :func:`motion_env.retarget.retarget` that need no future frames:

1. the frame scaled onto the robot as IK targets (:func:`.ik_goals.compute_targets`, with the limb
   scales measured on the character's first frame);
2. the IK (:class:`.ik.FrameSolver`), warm-started from the character's previous frame (the
   first frame from the home pose);
3. the joint speed capped against the previous frame (:func:`.limits.limit_speed`), every joint
   clipped into its soft range (:func:`.limits.clip_to_limits`);
4. the root height from the lowest foot geom (:mod:`.floor`), as in the whole-clip retargeter.

There is no Gaussian low-pass (it would need future frames): a streamed clip is a little less
smooth than :func:`~motion_env.retarget.retarget` of the same frames.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from motion_env.motion.skeleton import FPS
from motion_env.motion.validation import check_joints
from motion_env.retarget.api import check_rate
from motion_env.retarget.ik import FrameSolver, IKSettings
from motion_env.retarget.ik_goals import compute_targets, limb_scales
from motion_env.retarget.limits import SOFT_LIMIT, check_soft_limit, clip_to_limits, limit_speed
from motion_env.retarget.robot import Robot, load_robot

__all__ = ["StreamRetargeter"]


class StreamRetargeter:
    """Retarget B characters' frames onto a robot as they come, at the stream's 20 fps.

    Args:
        robot: a known robot name, a mapping table (.json) or a humanoid MJCF (.xml), as for
            :func:`motion_env.retarget.retarget`.
        batch: the number of characters B.
        max_joint_speed: fastest a joint may turn, rad/s (or m/s for a slide joint).
        soft_limit: share of each joint's range, about its centre, that the frames stay inside.
        ik: the solver's settings.

    Attributes:
        robot: the :class:`~motion_env.retarget.robot.Robot` (``robot.model`` is its MuJoCo model).
        qpos: (B, nq) the last frame returned (the home pose before the first one).
    """

    fps = float(FPS)

    def __init__(
        self,
        robot: str | os.PathLike = "unitree_g1",
        batch: int = 1,
        *,
        max_joint_speed: float = 15.0,
        soft_limit: float = SOFT_LIMIT,
        ik: IKSettings | None = None,
    ) -> None:
        if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
            raise ValueError(f"batch must be a positive int, got {batch!r}")
        self.robot: Robot = load_robot(robot)
        self.max_step = check_rate(max_joint_speed, "max_joint_speed") / self.fps
        self._limits = self.robot.soft_model(check_soft_limit(soft_limit))
        self._solvers = [FrameSolver(self.robot, ik or IKSettings(), soft_limit) for _ in range(int(batch))]
        self._scales: list[tuple[float, float] | None] = [None] * int(batch)
        self.qpos = np.tile(self.robot.home, (int(batch), 1))

    @property
    def batch(self) -> int:
        return len(self._solvers)

    @property
    def nq(self) -> int:
        return int(self.robot.model.nq)

    def reset(self, index: int | None = None) -> None:
        """Start character `index` (default: all) over: its next frame is a first frame."""
        for i in range(self.batch) if index is None else [int(index)]:
            self._solvers[i].reset()
            self._scales[i] = None
            self.qpos[i] = self.robot.home

    def step(self, joints: np.ndarray, rows: Sequence[int] | np.ndarray | None = None) -> np.ndarray:
        """The robot's qpos (B, nq) float64 for the human frames `joints` (B, 22, 3), motion axes
        (Y up), each character's next frame; with `rows`, `joints` holds only those characters'
        frames (len(rows), 22, 3) and the others keep their pose."""
        joints = check_joints(np.asarray(joints, dtype=np.float64), "joints")
        rows = np.arange(self.batch) if rows is None else np.asarray(rows, np.int64).reshape(-1)
        if joints.ndim != 3 or joints.shape[0] != len(rows):
            raise ValueError(f"joints must be ({len(rows)}, 22, 3), got {joints.shape}")
        bot, model = self.robot, self.robot.model
        for n, b in enumerate(rows):
            solver = self._solvers[b]
            frame = joints[n : n + 1]
            first = self._scales[b] is None
            if first:
                self._scales[b] = limb_scales(bot, frame)
            targets = compute_targets(bot, frame, self._scales[b])
            q = solver.solve(targets)
            if not first:
                q = limit_speed(model, np.stack([self.qpos[b], q]), self.max_step)[1]
            clip_to_limits(self._limits, q)
            pose = bot.kinematics(q[None])
            lift = max(float(targets.floor_height[0] - pose.foot_lowest[0]), float(-pose.lowest[0]))
            q[bot.root_qpos + 2] += lift
            self.qpos[b] = q
        return self.qpos.copy()
