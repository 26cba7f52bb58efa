"""Robot clip files: the project's own CSV and npz, and the files motion trackers read.

- ``csv`` (.csv, the project's): ``#`` header lines (robot, fps, the root quaternion order, the
  column names), then one row of qpos per frame; quaternion **w, x, y, z**; the clip's rate.
- ``npz`` (.npz, the project's): ``root_pos``, ``root_rot`` (**x, y, z, w**, as ``root_rot_order``
  says), ``dof_pos``, ``fps``, ``joint_names``, ``robot``, ``residuals``; the clip's rate.
- ``mjlab`` (.npz): mjlab's tracking clip (:mod:`.tracking`): ``fps``, ``joint_pos``, ``joint_vel``,
  ``body_pos_w``, ``body_quat_w`` (**w, x, y, z**), ``body_lin_vel_w``, ``body_ang_vel_w``, float32,
  with ``joint_names``, ``body_names``, ``robot`` beside them; 50 fps.
- ``gmr`` (.pkl): GMR's pickle, a dict of ``fps``, ``root_pos``, ``root_rot`` (**x, y, z, w**),
  ``dof_pos``, ``local_body_pos``, ``link_body_list``, and ``joint_names`` (wbc-mjlab reads it);
  the clip's rate.
- ``lafan_csv`` (.csv): the layout of Unitree's retargeted LAFAN1 release, read by mjlab's
  ``csv_to_npz``: no header, rows of root x, y, z, quaternion **x, y, z, w**, joints; 30 fps.

The format follows the suffix where one suffix means one format: .pkl is ``gmr``; .csv is the
project's ``csv`` and .npz the project's ``npz`` unless ``lafan_csv`` or ``mjlab`` is asked for.
Everything is checked before a byte is written (finite numbers, unit quaternions, the robot's
joint count); :func:`read_robot_motion` reads every format back, as :class:`ClipArrays`
(:func:`motion_env.retarget.load_robot_motion` wraps them into a ``RobotMotion``).

This module does not import :mod:`.result` (``result`` imports it): the writers take any object
with ``RobotMotion``'s attributes (:class:`MotionLike`), and the readers return plain arrays.
"""

from __future__ import annotations

import pickle
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from motion_env.retarget.robot import Robot, load_robot
from motion_env.retarget.tracking import body_names, resample_qpos, tracking_arrays

__all__ = [
    "DEFAULT_FPS",
    "FORMATS",
    "ROOT_COLUMNS",
    "ClipArrays",
    "MotionLike",
    "infer_format",
    "read_robot_motion",
    "write_robot_motion",
]

ROOT_COLUMNS = ("root_x", "root_y", "root_z", "root_qw", "root_qx", "root_qy", "root_qz")

FORMATS: dict[str, str] = {"csv": ".csv", "npz": ".npz", "mjlab": ".npz", "gmr": ".pkl", "lafan_csv": ".csv"}
_BY_SUFFIX = {".csv": "csv", ".npz": "npz", ".pkl": "gmr"}
DEFAULT_FPS: dict[str, float] = {"mjlab": 50.0, "lafan_csv": 30.0}  # the rest: the clip's own rate
_UNIT_TOLERANCE = 1e-3
_XYZW = [1, 2, 3, 0]  # w, x, y, z -> x, y, z, w
_WXYZ = [3, 0, 1, 2]  # x, y, z, w -> w, x, y, z


class MotionLike(Protocol):
    """What the writers read of a clip: the attributes of :class:`~motion_env.retarget.RobotMotion`.

    A clip to resample is rebuilt as ``type(motion)(qpos, fps, joint_names, robot)``.
    """

    qpos: np.ndarray
    fps: float
    joint_names: tuple[str, ...]
    robot: str
    residuals: np.ndarray | None
    residual_names: tuple[str, ...]

    @property
    def root_pos(self) -> np.ndarray: ...

    @property
    def root_rot(self) -> np.ndarray: ...

    @property
    def dof_pos(self) -> np.ndarray: ...

    @property
    def columns(self) -> tuple[str, ...]: ...


@dataclass
class ClipArrays:
    """A clip as read from a file, unchecked (``RobotMotion`` is this with its fields checked)."""

    qpos: np.ndarray
    fps: float
    joint_names: tuple[str, ...]
    robot: str
    residuals: np.ndarray | None = None
    residual_names: tuple[str, ...] = field(default=())


def infer_format(path: str | Path, format: str | None = None) -> str:
    """The format to write `path` in: `format` checked against the suffix, or the suffix's format."""
    path = Path(path)
    suffix = path.suffix.lower()
    if format is None:
        if suffix not in _BY_SUFFIX:
            raise ValueError(f"{path}: a robot motion is saved as .csv, .npz or .pkl, not {suffix!r}")
        return _BY_SUFFIX[suffix]
    if format not in FORMATS:
        raise ValueError(f"unknown robot motion format {format!r}: one of {sorted(FORMATS)}")
    if suffix != FORMATS[format]:
        raise ValueError(f"{path}: format {format!r} is written to a {FORMATS[format]} file, not {suffix!r}")
    return format


def _robot_or_none(name: str) -> Robot | None:
    if not name:
        return None
    try:
        return load_robot(name)
    except (FileNotFoundError, ValueError):  # made on another machine, or a name of the user's own
        return None


def _check(path: Path, arrays: dict[str, Any], quaternions: tuple[str, ...]) -> None:
    """Every float array finite and every quaternion unit, or ValueError naming the file and array."""
    for key, value in arrays.items():
        value = np.asarray(value) if value is not None else None
        if value is None or value.dtype.kind != "f":
            continue
        bad = np.argwhere(~np.isfinite(value))
        if bad.size:
            where = tuple(int(i) for i in bad[0])
            raise ValueError(f"{path}: {key} has a non-finite value at index {where}; nothing written")
    for key in quaternions:
        norm = np.linalg.norm(np.asarray(arrays[key], dtype=np.float64), axis=-1)
        bad = np.argwhere(np.abs(norm - 1.0) > _UNIT_TOLERANCE)
        if bad.size:
            raise ValueError(
                f"{path}: {key} at index {tuple(int(i) for i in bad[0])} is not a unit quaternion (norm "
                f"{norm[tuple(bad[0])]:.4f}); nothing written"
            )


def _check_robot(path: Path, motion: MotionLike, robot: Robot | None) -> None:
    """The clip's joints are the robot's, in its order (when the robot can be loaded)."""
    if robot is None or robot.joint_names == motion.joint_names:
        return
    if len(robot.joint_names) != len(motion.joint_names):
        raise ValueError(
            f"{path}: the clip has {len(motion.joint_names)} joints but robot {motion.robot!r} has "
            f"{len(robot.joint_names)} ({', '.join(robot.joint_names[:3])}, ...); nothing written"
        )
    k = next(k for k, (a, b) in enumerate(zip(motion.joint_names, robot.joint_names)) if a != b)
    raise ValueError(
        f"{path}: the clip's joint {k} is {motion.joint_names[k]!r}, robot {motion.robot!r}'s is "
        f"{robot.joint_names[k]!r}; nothing written"
    )


def _write_csv(path: Path, motion: MotionLike) -> None:
    # One message (no file name in it), so Python's warning filter shows it once per caller.
    warnings.warn(
        "the project's robot CSV has a header and the root quaternion as w, x, y, z; tools that "
        "read LAFAN-style CSVs (mjlab's csv_to_npz, Unitree's LAFAN1 retargets) want "
        "format='lafan_csv' (no header, x, y, z, w)",
        UserWarning,
        stacklevel=4,
    )
    header = "\n".join(
        [
            "motion_env robot motion: MuJoCo qpos, one row per frame",
            f"robot: {motion.robot}",
            f"fps: {motion.fps:g}",
            "root quaternion order: wxyz",
            "columns: " + ",".join(motion.columns),
        ]
    )
    np.savetxt(path, motion.qpos, delimiter=",", fmt="%.6f", header=header, comments="# ")


def _npz_arrays(motion: MotionLike) -> dict[str, Any]:
    arrays = {
        "root_pos": motion.root_pos,
        "root_rot": motion.root_rot[:, _XYZW],
        "root_rot_order": np.array("xyzw"),
        "dof_pos": motion.dof_pos,
        "fps": np.float64(motion.fps),
        "joint_names": np.array(motion.joint_names, dtype=str),
        "robot": np.array(motion.robot),
    }
    if motion.residuals is not None:
        arrays["residuals"] = motion.residuals
        arrays["residual_names"] = np.array(motion.residual_names, dtype=str)
    return arrays


def _mjlab_arrays(motion: MotionLike, robot: Robot) -> dict[str, Any]:
    arrays: dict[str, Any] = {"fps": np.array([motion.fps])}  # (1,), as mjlab's csv_to_npz writes it
    arrays.update(tracking_arrays(robot, motion.qpos, motion.fps))
    arrays["joint_names"] = np.array(motion.joint_names, dtype=str)
    arrays["body_names"] = np.array(body_names(robot), dtype=str)
    arrays["robot"] = np.array(motion.robot)
    return arrays


def _gmr_dict(motion: MotionLike, robot: Robot | None) -> dict[str, Any]:
    """GMR's keys (``scripts/bvh_to_robot_dataset.py``) and ``joint_names`` (read by wbc-mjlab)."""
    out: dict[str, Any] = {
        "fps": int(motion.fps) if float(motion.fps).is_integer() else motion.fps,
        "root_pos": motion.root_pos.copy(),
        "root_rot": motion.root_rot[:, _XYZW],
        "dof_pos": motion.dof_pos.copy(),
        "local_body_pos": None,
        "link_body_list": None,
        "joint_names": list(motion.joint_names),
        "robot": motion.robot,
    }
    if robot is not None and robot.joint_names == motion.joint_names:
        # GMR's local_body_pos: every body with the root at the origin, unrotated.
        local = motion.qpos.copy()
        local[:, robot.root_qpos : robot.root_qpos + 7] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
        out["local_body_pos"] = tracking_arrays(robot, local, motion.fps)["body_pos_w"]
        out["link_body_list"] = list(body_names(robot))
    return out


def write_robot_motion(
    motion: MotionLike, path: str | Path, format: str | None = None, fps: float | None = None
) -> Path:
    """Write `motion` to `path` as `format` (default: by the suffix; see the module docstring),
    resampled to `fps` (default: 50 for mjlab, 30 for lafan_csv, else the clip's own rate)."""
    path = Path(path)
    format = infer_format(path, format)
    robot = _robot_or_none(motion.robot)
    if format == "mjlab" and robot is None:
        raise ValueError(
            f"{path}: the mjlab format needs the robot's model, and the clip's robot is "
            f"{motion.robot or 'not named'}; give RobotMotion.robot a known robot or an MJCF path"
        )
    _check_robot(path, motion, robot)
    root = "the root quaternion qpos[:, 3:7]"
    _check(path, {"qpos": motion.qpos, root: motion.root_rot}, (root,))
    fps = DEFAULT_FPS.get(format, motion.fps) if fps is None else float(fps)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    if fps != motion.fps:
        motion = _resampled(motion, fps, robot)
    if format == "gmr":
        payload: dict[str, Any] = _gmr_dict(motion, robot)
        _check(path, payload, ("root_rot",))
    elif format in ("npz", "mjlab"):
        payload = _npz_arrays(motion) if format == "npz" else _mjlab_arrays(motion, robot)
        _check(path, payload, ("root_rot",) if format == "npz" else ("body_quat_w",))
    path.parent.mkdir(parents=True, exist_ok=True)  # only once every check has passed
    if format == "csv":
        _write_csv(path, motion)
    elif format == "lafan_csv":
        rows = np.concatenate([motion.root_pos, motion.root_rot[:, _XYZW], motion.dof_pos], axis=1)
        np.savetxt(path, rows, delimiter=",", fmt="%.6f")
    elif format == "gmr":
        with path.open("wb") as f:
            pickle.dump(payload, f, protocol=4)
    else:
        np.savez(path, **payload)
    return path


def _resampled(motion: MotionLike, fps: float, robot: Robot | None) -> MotionLike:
    if robot is None:
        raise ValueError(
            f"resampling a clip from {motion.fps:g} to {fps:g} fps needs its robot's model; the clip's "
            f"robot is {motion.robot or 'not named'}"
        )
    qpos = resample_qpos(robot.model, motion.qpos, motion.fps, fps)
    # The clip's own class (RobotMotion); residuals are per source frame, so none are carried over.
    return type(motion)(qpos, fps, motion.joint_names, motion.robot)


# ---------------------------------------------------------------------------------------- reading


def _read_csv(path: Path) -> ClipArrays:
    meta: dict[str, str] = {}
    with path.open() as f:
        for line in f:
            if not line.startswith("#"):
                break
            key, _, value = line[1:].strip().partition(": ")
            meta[key] = value
    if "columns" not in meta or "fps" not in meta:
        raise ValueError(f"{path}: not a robot motion CSV (no '# fps:' and '# columns:' header lines)")
    order = meta.get("root quaternion order", "wxyz")
    expected = {"wxyz": ROOT_COLUMNS, "xyzw": ROOT_COLUMNS[:3] + tuple(ROOT_COLUMNS[i] for i in (4, 5, 6, 3))}
    if order not in expected:
        raise ValueError(f"{path}: unknown root quaternion order {order!r} in the header (wxyz or xyzw)")
    columns = meta["columns"].split(",")
    for k, (got, want) in enumerate(zip(columns[:7], expected[order])):
        if got != want:
            raise ValueError(f"{path}: column {k + 1} is {got!r}; with order {order} it should be {want!r}")
    qpos = _numbers(path)
    if qpos.shape[1] != len(columns):
        raise ValueError(
            f"{path}: {qpos.shape[1]} numbers per row but the header names {len(columns)} columns"
        )
    if order == "xyzw":
        qpos[:, 3:7] = qpos[:, 3:7][:, _WXYZ]
    _check_unit_rows(path, qpos[:, 3:7], "columns 4-7")
    return ClipArrays(qpos, float(meta["fps"]), tuple(columns[7:]), meta.get("robot", ""))


def _numbers(path: Path) -> np.ndarray:
    try:
        return np.loadtxt(path, delimiter=",", ndmin=2, comments="#")
    except ValueError as exc:  # a row of another length, or text where a number belongs
        raise ValueError(f"{path}: not a CSV of numbers ({exc})") from None


def _check_unit_rows(path: Path, quat: np.ndarray, where: str) -> None:
    norm = np.linalg.norm(quat, axis=-1)
    bad = np.flatnonzero(~(np.abs(norm - 1.0) <= _UNIT_TOLERANCE))
    if bad.size:
        raise ValueError(
            f"{path}: {where} (the root quaternion), row {bad[0] + 1}: norm {norm[bad[0]]:.4f}, not 1; "
            "not the layout this format has (root x, y, z, quaternion, joints)"
        )


def _check_xyzw(path: Path, quat_xyzw: np.ndarray, where: str) -> None:
    """Refuse a root quaternion that reads upside down as x, y, z, w but upright as w, x, y, z."""
    up_xyzw = 1.0 - 2.0 * (quat_xyzw[:, 0] ** 2 + quat_xyzw[:, 1] ** 2)  # world z of the root's z axis
    up_wxyz = 1.0 - 2.0 * (quat_xyzw[:, 1] ** 2 + quat_xyzw[:, 2] ** 2)
    if np.median(up_xyzw) < 0.0 < 0.5 < np.median(up_wxyz):
        raise ValueError(
            f"{path}: {where} should be a quaternion x, y, z, w, but read so the robot stands on its "
            "head, and read as w, x, y, z it stands upright: unknown quaternion order (convert the "
            "file to x, y, z, w, or save it with format 'csv', which names its order)"
        )


def _robot_joints(path: Path, robot: str | None, count: int, where: str) -> tuple[str, ...]:
    """Joint names for `count` joint columns: the robot's (counts must agree), else dof0, dof1, ..."""
    if not robot:
        return tuple(f"dof{i}" for i in range(count))
    names = load_robot(robot).joint_names
    if len(names) != count:
        raise ValueError(
            f"{path}: {count} joints in {where}, but robot {robot!r} has {len(names)} "
            f"({names[0]}, ..., {names[-1]}): a file for another robot, or another layout"
        )
    return names


def _read_lafan_csv(path: Path, robot: str | None, fps: float | None) -> ClipArrays:
    rows = _numbers(path)
    if rows.shape[1] < 8:
        raise ValueError(
            f"{path}: {rows.shape[1]} columns per row; a LAFAN-style CSV has root x, y, z, quaternion "
            "x, y, z, w, then the joints (8 or more)"
        )
    names = _robot_joints(path, robot, rows.shape[1] - 7, f"columns 8-{rows.shape[1]}")
    _check_unit_rows(path, rows[:, 3:7], "columns 4-7")
    _check_xyzw(path, rows[:, 3:7], "columns 4-7")
    qpos = np.concatenate([rows[:, :3], rows[:, 3:7][:, _WXYZ], rows[:, 7:]], axis=1)
    return ClipArrays(qpos, DEFAULT_FPS["lafan_csv"] if fps is None else fps, names, robot or "")


def _read_npz(path: Path, robot: str | None) -> ClipArrays:
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # np.load raises several types for a corrupt file
        raise ValueError(f"{path}: not a readable .npz file ({exc})") from exc
    with data:
        keys = set(data.keys())
        try:
            if {"joint_pos", "body_pos_w", "body_quat_w"} <= keys:
                return _from_mjlab(path, data, robot)
            if {"root_pos", "root_rot", "dof_pos", "fps"} <= keys:
                return _from_npz(path, data, robot)
        except ValueError as exc:
            if "allow_pickle" not in str(exc):
                raise
            raise ValueError(f"{path}: holds a pickled object array, not loaded (it can run code)") from None
    raise ValueError(
        f"{path}: neither a robot motion npz (root_pos, root_rot, dof_pos, fps) nor an mjlab tracking "
        f"npz (joint_pos, body_pos_w, body_quat_w); its keys are {sorted(keys)}"
    )


def _names(data: Any, key: str, default: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(str(n) for n in data[key]) if key in data else default


def _from_npz(path: Path, data: Any, robot: str | None) -> ClipArrays:
    order = str(data["root_rot_order"]) if "root_rot_order" in data else "xyzw"  # GMR's
    if order not in ("xyzw", "wxyz"):
        raise ValueError(f"{path}: root_rot_order must be 'xyzw' or 'wxyz', got {order!r}")
    rot = data["root_rot"] if order == "wxyz" else data["root_rot"][:, _WXYZ]
    qpos = np.concatenate([data["root_pos"], rot, data["dof_pos"]], axis=1)
    robot = str(data["robot"]) if "robot" in data else robot or ""
    dofs = data["dof_pos"].shape[1]
    names = _names(data, "joint_names", ()) or _robot_joints(path, robot, dofs, "dof_pos")
    residuals = data["residuals"] if "residuals" in data else None
    return ClipArrays(qpos, float(data["fps"]), names, robot, residuals, _names(data, "residual_names", ()))


def _from_mjlab(path: Path, data: Any, robot: str | None) -> ClipArrays:
    """The root is the first body (mjlab's bodies are the robot's, root first)."""
    quat = data["body_quat_w"][:, 0]
    qpos = np.concatenate([data["body_pos_w"][:, 0], quat, data["joint_pos"]], axis=1).astype(np.float64)
    _check_unit_rows(path, quat, "body_quat_w[:, 0]")
    robot = str(data["robot"]) if "robot" in data else robot or ""
    count = data["joint_pos"].shape[1]
    names = _names(data, "joint_names", ()) or _robot_joints(path, robot, count, "joint_pos")
    fps = float(np.ravel(data["fps"])[0]) if "fps" in data else DEFAULT_FPS["mjlab"]
    return ClipArrays(qpos, fps, names, robot)


class _ArrayUnpickler(pickle.Unpickler):
    """Unpickles numbers, strings, lists, dicts and numpy arrays only: a pickle names the code it
    runs, and a motion file has no reason to run any."""

    _ALLOWED = {
        (module, name)
        for module in ("numpy", "numpy.core.multiarray", "numpy._core.multiarray")
        for name in ("ndarray", "dtype", "_reconstruct", "scalar")
    } | {("numpy", "float64"), ("numpy", "float32"), ("numpy", "int64")}

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in self._ALLOWED or module.startswith("numpy.dtypes"):
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refused to load {module}.{name} (only numbers and numpy arrays)")


def _read_gmr(path: Path, robot: str | None, fps: float | None) -> ClipArrays:
    try:
        with path.open("rb") as f:
            data = _ArrayUnpickler(f).load()
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as exc:
        raise ValueError(f"{path}: not a GMR motion pickle ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a GMR motion pickle holds a dict, this one a {type(data).__name__}")
    missing = [k for k in ("fps", "root_pos", "root_rot", "dof_pos") if k not in data]
    if missing:
        raise ValueError(f"{path}: missing keys {missing} (keys: {sorted(data)})")
    root_rot = np.asarray(data["root_rot"], dtype=np.float64)
    if root_rot.ndim != 2 or root_rot.shape[1] != 4:
        raise ValueError(f"{path}: root_rot must be (T, 4) quaternions x, y, z, w, not {root_rot.shape}")
    _check_unit_rows(path, root_rot, "root_rot")
    _check_xyzw(path, root_rot, "root_rot")
    dof_pos = np.asarray(data["dof_pos"], dtype=np.float64)
    robot = str(data.get("robot") or robot or "")
    names = tuple(data.get("joint_names") or ()) or _robot_joints(path, robot, dof_pos.shape[1], "dof_pos")
    root_pos = np.asarray(data["root_pos"], dtype=np.float64)
    qpos = np.concatenate([root_pos, root_rot[:, _WXYZ], dof_pos], axis=1)
    return ClipArrays(qpos, float(data["fps"]) if fps is None else fps, names, robot)


def read_robot_motion(path: str | Path, *, robot: str | None = None, fps: float | None = None) -> ClipArrays:
    """Read a robot clip in any format of the module docstring, as :class:`ClipArrays`.

    :func:`motion_env.retarget.load_robot_motion` is this, checked and wrapped into a
    ``RobotMotion``; its docstring has the arguments and errors.

    The format is told from the file: a .csv with ``#`` header lines is the project's CSV, one
    without is a LAFAN-style CSV; an .npz with ``joint_pos`` and ``body_pos_w`` is mjlab's, one
    with ``root_pos`` the project's (or GMR's npz); a .pkl is GMR's pickle (read without running
    any code it names: numbers and numpy arrays only).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no robot motion file at {path}")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        with path.open() as f:
            header = f.readline().startswith("#")
        return _read_csv(path) if header else _read_lafan_csv(path, robot, fps)
    if suffix == ".npz":
        return _read_npz(path, robot)
    if suffix == ".pkl":
        return _read_gmr(path, robot, fps)
    raise ValueError(f"{path}: a robot motion file is .csv, .npz or .pkl, not {suffix!r}")
