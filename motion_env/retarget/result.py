"""`RobotMotion`: a clip of robot joint positions (MuJoCo qpos).

The qpos layout is MuJoCo's: the free root (position x, y, z in metres, then the orientation
quaternion **w, x, y, z**), then every other joint in the model's order (for the two shipped
robots, the hinge joints, in radians). MuJoCo's world is Z up and the robot faces +X at zero yaw.

:meth:`RobotMotion.save` writes it in the project's CSV or npz, or in the files motion trackers
read (mjlab's tracking npz, GMR's pickle, a LAFAN-style CSV); :func:`load_robot_motion` reads
them all back. The formats and their quaternion orders: :mod:`motion_env.retarget.files`, which
reads and writes plain arrays (this module imports it, not the other way round).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion_env.retarget.files import ROOT_COLUMNS, ClipArrays, read_robot_motion, write_robot_motion

__all__ = ["ROOT_COLUMNS", "RobotMotion", "load_robot_motion"]


@dataclass
class RobotMotion(ClipArrays):
    """A robot clip: the fields of a :class:`~motion_env.retarget.files.ClipArrays`, checked.

    Attributes:
        qpos: (T, nq) MuJoCo qpos per frame: root position, root quaternion (w, x, y, z), joints.
        fps: frames per second.
        joint_names: names of the qpos columns after the root (nq - 7): the joint's name for a
            hinge or slide joint, ``<name>_qw``, ``_qx``, ``_qy``, ``_qz`` for a ball joint.
        robot: the robot: a known name (``"unitree_g1"``) or the path of its MJCF or table.
        residuals: (T, K) distance in metres from each tracked robot frame to its target after
            retargeting (None for a clip read from a CSV).
        residual_names: the K human joints those frames follow (``"left_wrist"``, ...).
    """

    def __post_init__(self) -> None:
        self.qpos = np.asarray(self.qpos, dtype=np.float64)
        if self.qpos.ndim != 2 or self.qpos.shape[1] < 7:
            raise ValueError(f"RobotMotion.qpos must have shape (T, nq) with nq >= 7, got {self.qpos.shape}")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"RobotMotion.fps must be a positive number, got {self.fps!r}")
        self.fps = float(self.fps)
        self.joint_names = tuple(str(n) for n in self.joint_names)
        if len(self.joint_names) != self.qpos.shape[1] - 7:
            raise ValueError(
                f"RobotMotion.joint_names has {len(self.joint_names)} names for {self.qpos.shape[1] - 7} "
                "qpos columns after the root"
            )
        self.residual_names = tuple(str(n) for n in self.residual_names)
        if self.residuals is not None:
            self.residuals = np.asarray(self.residuals, dtype=np.float64)
            if self.residuals.shape != (self.num_frames, len(self.residual_names)):
                raise ValueError(
                    f"RobotMotion.residuals must have shape ({self.num_frames}, {len(self.residual_names)}), "
                    f"got {self.residuals.shape}"
                )

    @property
    def num_frames(self) -> int:
        """Frames of the clip (its length in seconds is ``num_frames / fps``)."""
        return int(self.qpos.shape[0])

    @property
    def root_pos(self) -> np.ndarray:
        """(T, 3) root position, metres, Z up."""
        return self.qpos[:, :3]

    @property
    def root_rot(self) -> np.ndarray:
        """(T, 4) root orientation, quaternion **(w, x, y, z)** (MuJoCo's order)."""
        return self.qpos[:, 3:7]

    @property
    def dof_pos(self) -> np.ndarray:
        """(T, nq - 7) the joints after the root, in the order of :attr:`joint_names`."""
        return self.qpos[:, 7:]

    @property
    def columns(self) -> tuple[str, ...]:
        """Names of the qpos columns (the CSV header)."""
        return ROOT_COLUMNS + self.joint_names

    def residual_summary(self) -> dict[str, dict[str, float]]:
        """Per tracked joint, the mean and largest residual over the clip (metres)."""
        if self.residuals is None:
            return {}
        return {
            name: {"mean_m": float(self.residuals[:, k].mean()), "max_m": float(self.residuals[:, k].max())}
            for k, name in enumerate(self.residual_names)
        }

    def save(self, path: str | Path, format: str | None = None, *, fps: float | None = None) -> Path:
        """Write the clip to `path` and return the path.

        Args:
            path: the file; its suffix must fit the format.
            format: ``"csv"`` (the project's, default for .csv), ``"npz"`` (the project's, default
                for .npz), ``"mjlab"`` (.npz, mjlab's tracking clip), ``"gmr"`` (.pkl, default for
                .pkl) or ``"lafan_csv"`` (.csv, no header, quaternion x, y, z, w). See
                :mod:`motion_env.retarget.files`.
            fps: the rate to write (resampled): default 50 for mjlab, 30 for lafan_csv, else the
                clip's own.

        Raises:
            ValueError: a suffix that does not fit the format, or a clip that fails the checks
                (non-finite numbers, a root quaternion that is not unit, another joint count than
                the robot's); nothing is written then.
        """
        return write_robot_motion(self, path, format, fps)


def load_robot_motion(path: str | Path, *, robot: str | None = None, fps: float | None = None) -> RobotMotion:
    """Read a robot clip in any format of :mod:`motion_env.retarget.files` back into a :class:`RobotMotion`.

    The format is told from the file: a .csv with ``#`` header lines is the project's CSV, one
    without is a LAFAN-style CSV; an .npz with ``joint_pos`` and ``body_pos_w`` is mjlab's, one
    with ``root_pos`` the project's (or GMR's npz); a .pkl is GMR's pickle (read without running
    any code it names: numbers and numpy arrays only).

    Args:
        path: the file.
        robot: the robot, for files that do not name it (LAFAN-style CSV, mjlab's own npz): its
            joint names label the columns, and its joint count must match them.
        fps: the rate of a LAFAN-style CSV (default 30; the other formats record theirs).

    Raises:
        ValueError: naming the file and the column or key: a wrong column count, a quaternion that
            is not unit or in an unknown order, missing keys, non-numbers.
        FileNotFoundError: no file at `path`.
    """
    clip = read_robot_motion(path, robot=robot, fps=fps)
    return RobotMotion(clip.qpos, clip.fps, clip.joint_names, clip.robot, clip.residuals, clip.residual_names)
