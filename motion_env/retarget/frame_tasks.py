"""Every tracked frame of a robot, and its centre of mass, as one least-squares task of the IK.

mink's :class:`mink.FrameTask` is one task per frame: each step it builds the frame's SE(3) pose,
its 6 x nv body Jacobian and the SE(3) logarithm in Python, whatever the frame's costs, and that
was half the retargeter's time. :class:`FrameTargets` stacks the rows that have a cost and
computes them with MuJoCo's own Jacobians in one pass:

- a position: ``p - p*`` in the world (metres), Jacobian ``mj_jacSite`` / ``mj_jacBody``'s
  translational part (world-aligned);
- an orientation: the rotation vector ``e`` of ``R R*^T`` (world axes, radians), Jacobian the
  inverse left Jacobian of SO(3) at ``e`` times the rotational part;
- the centre of mass, horizontally: ``c - c*`` (x, y), Jacobian ``mj_jacSubtreeCom`` of the root.

Each row is weighted by its cost, as mink weights a task's rows; the solver adds its damping.
"""

from __future__ import annotations

import mujoco
import numpy as np
from mink import Configuration
from mink.tasks import BaseTask, Objective
from scipy.spatial.transform import Rotation

from motion_env.retarget.robot import Robot

__all__ = ["FrameTargets", "inverse_left_jacobian", "rotation_vectors"]


def rotation_vectors(rotations: np.ndarray) -> np.ndarray:
    """(K, 3) rotation vectors of rotation matrices (K, 3, 3), angles in [0, pi].

    The same as ``quat_to_axis_angle(quat_from_matrix(m))`` (:mod:`motion_env.motion.rotations`),
    which takes 4.7 times as long for the 10 matrices of an IK step (180 us against 38): the IK
    calls this every iteration of every frame.
    """
    trace = np.einsum("kii->k", rotations)
    angle = np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0))
    skew = np.stack(
        [
            rotations[:, 2, 1] - rotations[:, 1, 2],
            rotations[:, 0, 2] - rotations[:, 2, 0],
            rotations[:, 1, 0] - rotations[:, 0, 1],
        ],
        axis=-1,
    )
    sin = np.sin(angle)
    small = sin < 1e-6
    out = np.where(small, 0.5 + angle**2 / 12.0, angle / (2.0 * np.where(small, 1.0, sin)))[:, None] * skew
    flipped = np.flatnonzero(small & (angle > 1.0))  # near pi the skew part says nothing
    if flipped.size:
        out[flipped] = Rotation.from_matrix(rotations[flipped]).as_rotvec()
    return out


def inverse_left_jacobian(vectors: np.ndarray) -> np.ndarray:
    """(K, 3, 3) inverse left Jacobians of SO(3) at rotation vectors (K, 3): how a world angular
    velocity w changes the rotation vector of ``R R*^T`` (``de = J^-1 w``)."""
    angle = np.linalg.norm(vectors, axis=-1)
    skew = np.zeros((len(vectors), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -vectors[:, 2], vectors[:, 1], -vectors[:, 0]
    skew -= skew.transpose(0, 2, 1)
    small = angle < 1e-4
    safe = np.where(small, 1.0, np.minimum(angle, np.pi - 1e-6))
    coef = np.where(small, 1.0 / 12.0, 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    return np.eye(3) - 0.5 * skew + coef[:, None, None] * (skew @ skew)


class FrameTargets(BaseTask):
    """The positions and orientations of a robot's tracked frames (and optionally the horizontal
    place of its centre of mass) as one weighted least-squares task of :func:`mink.solve_ik`."""

    def __init__(self, robot: Robot, com_cost: float = 0.0) -> None:
        model = robot.model
        self.model, self.root = model, robot.root
        self.positions = [k for k, t in enumerate(robot.tasks) if t.position_cost > 0]
        self.orientations = [k for k, t in enumerate(robot.tasks) if t.orientation_cost > 0]
        wanted = sorted(set(self.positions) | set(self.orientations))
        # (task, id, is a site) of each frame with a cost; jac[k] holds its (6, nv) Jacobian.
        self._frames = [(k, robot.frame_id(robot.tasks[k]), robot.tasks[k].type == "site") for k in wanted]
        self._slot = {k: i for i, k in enumerate(wanted)}
        self._jac = np.zeros((len(wanted), 6, model.nv))
        self._com_jac = np.zeros((3, model.nv))
        self.com_cost = float(com_cost)
        cost = [np.repeat([robot.tasks[k].position_cost for k in self.positions], 3)]
        cost.append(np.repeat([robot.tasks[k].orientation_cost for k in self.orientations], 3))
        if self.com_cost > 0:
            cost.append(np.full(2, self.com_cost))
        self.cost = np.concatenate(cost)
        self.target_positions = np.zeros((len(self.positions), 3))
        self.target_rotations = np.broadcast_to(np.eye(3), (len(self.orientations), 3, 3)).copy()
        self.target_com = np.zeros(2)

    def set_targets(
        self, positions: np.ndarray, rotations: np.ndarray, com: np.ndarray | None = None
    ) -> None:
        """Targets of one frame: positions (K, 3) and rotations (K, 3, 3) of all the robot's tasks
        (those without a cost are ignored), and the centre of mass (3,) (its height is ignored)."""
        self.target_positions = positions[self.positions]
        self.target_rotations = rotations[self.orientations]
        if com is not None:
            self.target_com = np.asarray(com, dtype=np.float64)[:2]

    def _error_and_jacobian(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray]:
        model, data, jac = self.model, configuration.data, self._jac
        for i, (_, frame, site) in enumerate(self._frames):
            (mujoco.mj_jacSite if site else mujoco.mj_jacBody)(model, data, jac[i, :3], jac[i, 3:], frame)
        rows = [jac[[self._slot[k] for k in self.positions], :3].reshape(-1, model.nv)]
        pos = np.array([self._place(data, k) for k in self.positions]).reshape(-1, 3)
        errors = [(pos - self.target_positions).ravel()]
        if self.orientations:
            current = np.array([self._turn(data, k) for k in self.orientations])
            vectors = rotation_vectors(current @ self.target_rotations.transpose(0, 2, 1))
            angular = jac[[self._slot[k] for k in self.orientations], 3:]
            rows.append((inverse_left_jacobian(vectors) @ angular).reshape(-1, model.nv))
            errors.append(vectors.ravel())
        if self.com_cost > 0:
            mujoco.mj_jacSubtreeCom(model, data, self._com_jac, self.root)
            rows.append(self._com_jac[:2])
            errors.append(data.subtree_com[self.root, :2] - self.target_com)
        return np.concatenate(errors), np.concatenate(rows)

    def _place(self, data: mujoco.MjData, k: int) -> np.ndarray:
        _, frame, site = self._frames[self._slot[k]]
        return (data.site_xpos if site else data.xpos)[frame]

    def _turn(self, data: mujoco.MjData, k: int) -> np.ndarray:
        _, frame, site = self._frames[self._slot[k]]
        return (data.site_xmat if site else data.xmat)[frame].reshape(3, 3)

    def compute_qp_residual(self, configuration: Configuration) -> tuple[np.ndarray, np.ndarray, float]:
        error, jacobian = self._error_and_jacobian(configuration)
        return self.cost[:, None] * jacobian, -self.cost * error, 0.0

    def compute_qp_objective(self, configuration: Configuration) -> Objective:
        weighted_jacobian, weighted_error, _ = self.compute_qp_residual(configuration)
        return Objective(weighted_jacobian.T @ weighted_jacobian, -weighted_error @ weighted_jacobian)
