"""A robot to retarget onto: the compiled MuJoCo model, its mapping table, and what follows from
the two (frame ids, the rest geometry, the foot geoms, the joint layout).

- :data:`ROBOTS_DIR`: the robot folders shipped with the package (``robots/<name>/``: the
  Menagerie model, its ``LICENSE`` and ``README.md``, and the mapping table ``retarget.json``);
- :func:`known_robots`: their names;
- :func:`load_robot`: a known name, a mapping table (.json) or any humanoid MJCF (.xml, mapping
  guessed from its body names by :func:`motion_env.retarget.guess.guess_table`) -> :class:`Robot`.
"""

from __future__ import annotations

import difflib
import functools
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from motion_env.retarget.floor import GeomPoints, collision_geoms
from motion_env.retarget.limits import clip_to_limits, soft_limited
from motion_env.retarget.table import RobotTable, Task, read_table

__all__ = ["ROBOTS_DIR", "TABLE_NAME", "Kinematics", "Robot", "known_robots", "load_robot", "subtree"]

ROBOTS_DIR = Path(str(resources.files("motion_env.retarget").joinpath("robots")))
TABLE_NAME = "retarget.json"
_FREE = mujoco.mjtJoint.mjJNT_FREE
_OBJ = {"body": mujoco.mjtObj.mjOBJ_BODY, "site": mujoco.mjtObj.mjOBJ_SITE}


def known_robots() -> tuple[str, ...]:
    """Names of the robots shipped with the package (folders of :data:`ROBOTS_DIR` with a table)."""
    return tuple(sorted(p.parent.name for p in ROBOTS_DIR.glob(f"*/{TABLE_NAME}")))


def _name_id(model: mujoco.MjModel, kind: str, name: str, where: str) -> int:
    """The id of a body or site, or ValueError naming the close matches."""
    i = mujoco.mj_name2id(model, _OBJ[kind], name)
    if i < 0:
        count = model.nbody if kind == "body" else model.nsite
        names = [mujoco.mj_id2name(model, _OBJ[kind], k) or "" for k in range(count)]
        close = difflib.get_close_matches(name, names, n=3)
        hint = f"; did you mean {close}?" if close else ""
        raise ValueError(f"{where}: the model has no {kind} named {name!r}{hint}")
    return i


@dataclass
class Kinematics:
    """Where a robot clip puts its tracked frames and how low it reaches, per frame.

    Attributes:
        frame_positions: (T, K, 3) world position of each of the robot's K tracked frames.
        foot_lowest: (T,) height of the lowest point of the foot geoms (metres, floor at 0).
        lowest: (T,) height of the lowest point of all the robot's collision geoms.
        com: (T, 3) the robot's centre of mass.
    """

    frame_positions: np.ndarray
    foot_lowest: np.ndarray
    lowest: np.ndarray
    com: np.ndarray


class Robot:
    """A compiled robot model with its mapping table.

    Attributes:
        name: the table's robot name (a known name, or the MJCF's file stem).
        key: how it was asked for: a known name, or the resolved path of its MJCF or table.
        table: the :class:`~motion_env.retarget.table.RobotTable`.
        model: the compiled ``mujoco.MjModel`` (shared: do not modify it).
        tasks: the tracked tasks (a cost above zero), in the table's order.
        joint_names: names of the qpos entries after the free root, in order: a hinge or slide
            joint's name; for a ball joint, four (``<name>_qw``, ``_qx``, ``_qy``, ``_qz``).
        home: (nq,) the home pose (the table's keyframe, else the model's qpos0 inside the limits).
        rest_points: human joint -> (3,) position of the robot frame that follows it, in the
            robot's rest pose (qpos0, root at the origin, unrotated).
        rest_rotations: (len(tasks), 3, 3) orientation of each task's frame in that pose.
        rest_root: (3,) the root body's position in that pose.
        rest_sole: height of the lowest foot point in that pose.
        feet: "left", "right" -> the :class:`~motion_env.retarget.floor.GeomPoints` of each foot;
            foot_geoms: both; body_geoms: every collision geom of the robot.
        rest_feet: "left", "right" -> (G, 3) positions and (G, 9) orientations of the foot's
            geoms in the rest pose.
    """

    def __init__(self, table: RobotTable, model: mujoco.MjModel, key: str | None = None) -> None:
        where = table.source or table.robot
        self.name, self.table, self.model = table.robot, table, model
        self.key = key or table.robot
        self.root = _name_id(model, "body", table.root, where)
        if model.body_jntnum[self.root] < 1 or model.jnt_type[model.body_jntadr[self.root]] != _FREE:
            raise ValueError(f"{where}: the root body {table.root!r} has no free joint")
        self.root_qpos = int(model.jnt_qposadr[model.body_jntadr[self.root]])
        if any(model.jnt_type[j] == _FREE for j in range(model.njnt) if j != model.body_jntadr[self.root]):
            raise ValueError(f"{where}: the model has more than one free joint; retargeting needs one body")
        self.joint_names = _qpos_names(model, skip=int(model.body_jntadr[self.root]))
        self.tasks: tuple[Task, ...] = tuple(
            t for t in table.tasks if t.position_cost > 0 or t.orientation_cost > 0
        )
        self._frame_ids = {(t.type, t.frame): _name_id(model, t.type, t.frame, where) for t in table.tasks}
        self.feet: dict[str, GeomPoints] = {}
        for side, foot in table.feet.items():
            geoms = collision_geoms(model, subtree(model, [_name_id(model, "body", foot, where)]))
            if geoms.size == 0:
                raise ValueError(f"{where}: the {side} foot {foot!r} has no geoms to stand on")
            self.feet[side] = GeomPoints(model, geoms)
        self.foot_geoms = GeomPoints(model, np.concatenate([g.geoms for g in self.feet.values()]))
        self.body_geoms = GeomPoints(model, collision_geoms(model))
        self.home = self._home(where)
        self._soft_models: dict[float, mujoco.MjModel] = {}
        self._geom_points: dict[tuple[int, ...], GeomPoints] = {}  # subsets of body_geoms
        self._rest(table)

    def _home(self, where: str) -> np.ndarray:
        model = self.model
        if self.table.home is not None:
            key = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, self.table.home)
            if key < 0:
                raise ValueError(f"{where}: the model has no keyframe named {self.table.home!r}")
            return clip_to_limits(model, model.key_qpos[key].copy())
        return clip_to_limits(model, model.qpos0.copy())

    def _rest(self, table: RobotTable) -> None:
        """Rest geometry: qpos0 inside the limits, the root at the origin, unrotated."""
        data = mujoco.MjData(self.model)
        data.qpos[:] = clip_to_limits(self.model, self.model.qpos0.copy())
        data.qpos[self.root_qpos : self.root_qpos + 7] = (0, 0, 0, 1, 0, 0, 0)
        mujoco.mj_kinematics(self.model, data)
        self.rest_points = {t.human: self.frame_position(data, t).copy() for t in table.tasks if t.human}
        self.rest_rotations = np.stack([self.frame_rotation(data, t) for t in self.tasks])
        self.rest_root = data.xpos[self.root].copy()
        ids = self.foot_geoms.geoms
        self.rest_sole = float(
            self.foot_geoms.lowest(data.geom_xpos[ids][None], data.geom_xmat[ids][None]).min()
        )
        self.rest_feet = {
            side: (data.geom_xpos[g.geoms].copy(), data.geom_xmat[g.geoms].copy())
            for side, g in self.feet.items()
        }

    def soft_model(self, soft_limit: float) -> mujoco.MjModel:
        """The model with each joint range shrunk to `soft_limit` of itself about its centre
        (:func:`~motion_env.retarget.limits.soft_limited`); made once per share."""
        if soft_limit not in self._soft_models:
            self._soft_models[soft_limit] = soft_limited(self.model, soft_limit)
        return self._soft_models[soft_limit]

    def kinematics(self, qpos: np.ndarray) -> Kinematics:
        """Forward kinematics of a clip, qpos (T, nq) -> :class:`Kinematics`."""
        data = mujoco.MjData(self.model)
        num_frames = qpos.shape[0]
        frames = np.empty((num_frames, len(self.tasks), 3))
        geoms = np.concatenate([self.foot_geoms.geoms, self.body_geoms.geoms])
        xpos = np.empty((num_frames, geoms.size, 3))
        xmat = np.empty((num_frames, geoms.size, 9))
        com = np.empty((num_frames, 3))
        for t in range(num_frames):
            data.qpos[:] = qpos[t]
            mujoco.mj_kinematics(self.model, data)
            mujoco.mj_comPos(self.model, data)
            frames[t] = [self.frame_position(data, task) for task in self.tasks]
            xpos[t], xmat[t] = data.geom_xpos[geoms], data.geom_xmat[geoms]
            com[t] = data.subtree_com[self.root]
        feet = self.foot_geoms.geoms.size
        foot_lowest = self.foot_geoms.lowest(xpos[:, :feet], xmat[:, :feet]).min(axis=1)
        return Kinematics(
            frame_positions=frames,
            foot_lowest=foot_lowest,
            lowest=self._lowest(xpos[:, feet:], xmat[:, feet:], foot_lowest),
            com=com,
        )

    def _lowest(self, xpos: np.ndarray, xmat: np.ndarray, foot_lowest: np.ndarray) -> np.ndarray:
        """(T,) lowest point of all collision geoms, given their poses (T, G, 3), (T, G, 9).

        The exact lowest point of a mesh geom costs a pass over its hull's vertices every frame;
        a geom whose bounding sphere stays above the feet's lowest point in every frame cannot be
        lower, so only the others are measured (most frames: the feet alone).
        """
        ids = self.body_geoms.geoms
        below = ((xpos[..., 2] - self.model.geom_rbound[ids]) < foot_lowest[:, None]).any(axis=0)
        keep = tuple(np.flatnonzero(below))
        if not keep:
            return foot_lowest.copy()
        if keep not in self._geom_points:
            self._geom_points[keep] = GeomPoints(self.model, ids[list(keep)])
        cols = list(keep)
        lowest = self._geom_points[keep].lowest(xpos[:, cols], xmat[:, cols]).min(axis=1)
        return np.minimum(lowest, foot_lowest)

    def frame_id(self, task: Task) -> int:
        return self._frame_ids[(task.type, task.frame)]

    def frame_position(self, data: mujoco.MjData, task: Task) -> np.ndarray:
        """(3,) world position of a task's frame in `data` (after kinematics)."""
        return (data.xpos if task.type == "body" else data.site_xpos)[self.frame_id(task)]

    def frame_rotation(self, data: mujoco.MjData, task: Task) -> np.ndarray:
        """(3, 3) world orientation of a task's frame in `data` (after kinematics)."""
        return (data.xmat if task.type == "body" else data.site_xmat)[self.frame_id(task)].reshape(3, 3)


def _qpos_names(model: mujoco.MjModel, skip: int) -> tuple[str, ...]:
    """A name per qpos entry of every joint but `skip` (the root), in qpos order."""
    names: list[str] = []
    for j in range(model.njnt):
        if j == skip:
            continue
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            names += [f"{name}_{c}" for c in ("qw", "qx", "qy", "qz")]
        else:
            names.append(name)
    return tuple(names)


def subtree(model: mujoco.MjModel, bodies: list[int]) -> list[int]:
    """The bodies and all their descendants."""
    out = set(bodies)
    for b in range(model.nbody):  # parents come before children in MuJoCo's body order
        if model.body_parentid[b] in out:
            out.add(b)
    return sorted(out)


def _resolve(robot: str | os.PathLike) -> tuple[str, RobotTable | None, Path]:
    """(key, table or None for an MJCF to guess, model path)."""
    text = os.fspath(robot)
    looks_like_path = isinstance(robot, os.PathLike) or text.lower().endswith((".xml", ".json"))
    looks_like_path = looks_like_path or os.sep in text or "/" in text
    if not looks_like_path:
        known = known_robots()
        if text not in known:
            raise ValueError(
                f"unknown robot {text!r}: the known robots are {list(known)}; or give the path to a "
                f"humanoid MJCF (.xml) or to a mapping table (.json)"
            )
        table = read_table(ROBOTS_DIR / text / TABLE_NAME)
        return text, table, table.model
    path = Path(text).expanduser().resolve()
    if not path.is_file():
        raise FileNotFoundError(f"no robot model at {text}")
    if path.suffix.lower() == ".json":
        table = read_table(path)
        return str(path), table, table.model
    if path.suffix.lower() != ".xml":
        raise ValueError(f"{text}: a robot is a known name, an MJCF (.xml) or a mapping table (.json)")
    return str(path), None, path


def _compile(path: Path, where: str) -> mujoco.MjModel:
    if not path.is_file():
        raise FileNotFoundError(f"{where}: no MJCF at {path}")
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as exc:  # MuJoCo's XML and compile errors
        raise ValueError(f"{path}: MuJoCo could not load the model ({exc})") from exc


@functools.lru_cache(maxsize=8)
def _load(key: str) -> Robot:
    _, table, model_path = _resolve(key)
    model = _compile(model_path, table.source if table else key)
    if table is None:
        from motion_env.retarget.guess import guess_table

        table = guess_table(model, model_path)
    return Robot(table, model, key)


def load_robot(robot: str | os.PathLike) -> Robot:
    """The :class:`Robot` for a known name (:func:`known_robots`), a mapping table (.json) or a
    humanoid MJCF (.xml, the mapping guessed from its body names). Loaded once per process.

    Raises ValueError for an unknown name (listing the known ones), a model that is not a humanoid
    ("no legs found") or a table that does not fit its model; FileNotFoundError for a missing file.
    """
    key, _, _ = _resolve(robot)
    return _load(key)
