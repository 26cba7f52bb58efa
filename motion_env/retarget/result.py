"""`RobotMotion`: a clip of robot joint positions (MuJoCo qpos), with CSV and npz files.

The qpos layout is MuJoCo's: the free root (position x, y, z in metres, then the orientation
quaternion w, x, y, z), then every other joint in the model's order (for the two shipped robots,
the hinge joints, in radians). MuJoCo's world is Z up and the robot faces +X at zero yaw.

Files (:meth:`RobotMotion.save`, :func:`load_robot_motion`, chosen by the suffix):

- ``.csv``: one row of qpos per frame, comma-separated; ``#`` comment lines first name the robot,
  the frame rate and the columns (``root_x, root_y, root_z, root_qw, root_qx, root_qy, root_qz``,
  then the joint names). ``numpy.loadtxt(path, delimiter=",")`` reads the numbers.
- ``.npz``: GMR's fields: ``root_pos`` (T, 3), ``root_rot`` (T, 4) in **xyzw** order (as GMR
  writes it; ``root_rot_order`` says so), ``dof_pos`` (T, nq - 7), ``fps``, ``joint_names``; and
  ``robot``, ``residuals``, ``residual_names``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["ROOT_COLUMNS", "RobotMotion", "load_robot_motion"]

ROOT_COLUMNS = ("root_x", "root_y", "root_z", "root_qw", "root_qx", "root_qy", "root_qz")
_SUFFIXES = (".csv", ".npz")


@dataclass
class RobotMotion:
    """A robot clip.

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

    qpos: np.ndarray
    fps: float
    joint_names: tuple[str, ...]
    robot: str
    residuals: np.ndarray | None = None
    residual_names: tuple[str, ...] = field(default=())

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

    def save(self, path: str | Path) -> Path:
        """Write the clip as ``.csv`` (qpos rows) or ``.npz`` (GMR's fields), by the suffix."""
        path = Path(path)
        suffix = path.suffix.lower()
        if suffix not in _SUFFIXES:
            raise ValueError(f"{path}: a robot motion is saved as one of {_SUFFIXES}, not {suffix!r}")
        path.parent.mkdir(parents=True, exist_ok=True)
        if suffix == ".csv":
            header = "\n".join(
                [
                    "motion_env robot motion: MuJoCo qpos, one row per frame",
                    f"robot: {self.robot}",
                    f"fps: {self.fps:g}",
                    "root quaternion order: wxyz",
                    "columns: " + ",".join(self.columns),
                ]
            )
            np.savetxt(path, self.qpos, delimiter=",", fmt="%.6f", header=header, comments="# ")
            return path
        arrays = {
            "root_pos": self.root_pos,
            "root_rot": self.root_rot[:, [1, 2, 3, 0]],
            "root_rot_order": np.array("xyzw"),
            "dof_pos": self.dof_pos,
            "fps": np.float64(self.fps),
            "joint_names": np.array(self.joint_names, dtype=str),
            "robot": np.array(self.robot),
        }
        if self.residuals is not None:
            arrays["residuals"] = self.residuals
            arrays["residual_names"] = np.array(self.residual_names, dtype=str)
        np.savez(path, **arrays)
        return path


def _read_csv(path: Path) -> RobotMotion:
    meta: dict[str, str] = {}
    with path.open() as f:
        for line in f:
            if not line.startswith("#"):
                break
            key, _, value = line[1:].strip().partition(": ")
            meta[key] = value
    if "columns" not in meta or "fps" not in meta:
        raise ValueError(f"{path}: not a robot motion CSV (no '# fps:' and '# columns:' header lines)")
    columns = meta["columns"].split(",")
    qpos = np.loadtxt(path, delimiter=",", ndmin=2)
    if qpos.shape[1] != len(columns) or tuple(columns[:7]) != ROOT_COLUMNS:
        raise ValueError(
            f"{path}: {qpos.shape[1]} numbers per row but the header names {len(columns)} columns"
        )
    return RobotMotion(qpos, float(meta["fps"]), tuple(columns[7:]), meta.get("robot", ""))


def _read_npz(path: Path) -> RobotMotion:
    with np.load(path, allow_pickle=False) as data:
        missing = [k for k in ("root_pos", "root_rot", "dof_pos", "fps") if k not in data]
        if missing:
            raise ValueError(f"{path}: missing fields {missing} (keys: {sorted(data.keys())})")
        order = str(data["root_rot_order"]) if "root_rot_order" in data else "xyzw"  # GMR's
        if order not in ("xyzw", "wxyz"):
            raise ValueError(f"{path}: root_rot_order must be 'xyzw' or 'wxyz', got {order!r}")
        rot = data["root_rot"] if order == "wxyz" else data["root_rot"][:, [3, 0, 1, 2]]
        qpos = np.concatenate([data["root_pos"], rot, data["dof_pos"]], axis=1)
        dofs = data["dof_pos"].shape[1]
        names = tuple(data["joint_names"]) if "joint_names" in data else tuple(f"dof{i}" for i in range(dofs))
        residuals = data["residuals"] if "residuals" in data else None
        residual_names = tuple(data["residual_names"]) if "residual_names" in data else ()
        robot = str(data["robot"]) if "robot" in data else ""
        return RobotMotion(qpos, float(data["fps"]), names, robot, residuals, residual_names)


def load_robot_motion(path: str | Path) -> RobotMotion:
    """Read a clip written by :meth:`RobotMotion.save` (.csv or .npz; a GMR-style npz too)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no robot motion file at {path}")
    suffix = path.suffix.lower()
    if suffix not in _SUFFIXES:
        raise ValueError(f"{path}: a robot motion file is one of {_SUFFIXES}, not {suffix!r}")
    return _read_csv(path) if suffix == ".csv" else _read_npz(path)
