"""The selected character on a robot, live: its stream retargeted frame by frame and the robot
drawn with its own meshes.

- :class:`RobotFigure` (no web page): a :class:`~motion_env.retarget.StreamRetargeter` for one
  character and the robot's forward kinematics; :meth:`RobotFigure.step` turns the character's
  frame into a :class:`RobotPose`, every body's world pose in the studio's axes.
- :class:`RobotView`: the robot's visual meshes as viser nodes, added once (one frame node per
  body, its meshes as children at their place on the body); each frame moves the body frames only.

MuJoCo's world is Z up and the robot faces +X; the studio's is Y up, facing +Z
(:func:`motion_env.replay.humanoid.to_mujoco`). The body poses are turned into the studio's axes
here, once.

The retargeter scales the walk by the robot's leg length (as the files kept for trackers are):
the robot starts where its character stands when the view is chosen, and its shorter steps take it
less far. It is drawn where its own steps take it (its feet do not slide); the camera follows it.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from motion_env.args import install_line
from motion_env.replay.humanoid import from_mujoco

if TYPE_CHECKING:  # the session uses this module without viser (the optional studio extra)
    import viser

__all__ = ["ROBOT_CHOICES", "RobotFigure", "RobotPose", "RobotView", "robot_meshes"]

# What the panel offers: its label -> the robot's name (:func:`motion_env.retarget.known_robots`).
ROBOT_CHOICES = {"Unitree G1": "unitree_g1", "Booster T1": "booster_t1"}

# The rotation that takes MuJoCo's axes to the studio's (from_mujoco as a quaternion, w x y z).
_MJ_TO_SCENE = np.zeros(4)
mujoco.mju_mat2Quat(_MJ_TO_SCENE, from_mujoco(np.eye(3)).T.reshape(-1).astype(np.float64))


def _needs_mink() -> None:
    if importlib.util.find_spec("mink") is None:
        raise ValueError(f"the robot view needs the mink package: {install_line('robots')}")


@dataclass(frozen=True)
class RobotPose:
    """Every body's world pose, studio axes (Y up).

    Attributes:
        robot: the robot's name.
        character: the index of the character it shows.
        qpos: (nq,) the retargeted MuJoCo pose (about the floor point the view started at).
        positions: (nbody, 3) body origins, metres.
        wxyz: (nbody, 4) body orientations, unit quaternions w x y z.
        root: (3,) the root body's origin (the pelvis).
    """

    robot: str
    character: int
    qpos: np.ndarray
    positions: np.ndarray
    wxyz: np.ndarray
    root: np.ndarray


class RobotFigure:
    """One character retargeted onto `robot` as it streams.

    Args:
        robot: a known robot name (:data:`ROBOT_CHOICES` values).

    Raises:
        ValueError: mink (the ``robots`` extra) is not installed, or the robot is unknown.
    """

    def __init__(self, robot: str) -> None:
        _needs_mink()
        from motion_env.retarget import StreamRetargeter

        self.name = robot
        self._retarget = StreamRetargeter(robot, batch=1)
        self.model = self._retarget.robot.model
        self._root = self._retarget.robot.root
        self._data = mujoco.MjData(self.model)
        self._anchor: np.ndarray | None = None  # (3,) the floor point under the first frame's pelvis

    def reset(self) -> None:
        """The next frame is a first frame (a new episode, another character)."""
        self._retarget.reset()
        self._anchor = None

    def step(self, joints: np.ndarray, character: int = 0) -> RobotPose:
        """The robot's pose for the frame `joints` (22, 3) of character `character`, studio axes."""
        joints = np.asarray(joints, np.float64)
        if self._anchor is None:
            self._anchor = joints[0] * (1.0, 0.0, 1.0)
        qpos = self._retarget.step((joints - self._anchor)[None])[0]
        return self.pose(qpos, character)

    def pose(self, qpos: np.ndarray, character: int = 0) -> RobotPose:
        """Forward kinematics of `qpos` (nq,), in the studio's axes."""
        data = self._data
        data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, data)
        wxyz = np.empty((self.model.nbody, 4))
        for b in range(self.model.nbody):
            mujoco.mju_mulQuat(wxyz[b], _MJ_TO_SCENE, data.xquat[b])
        positions = from_mujoco(data.xpos) + (0.0 if self._anchor is None else self._anchor)
        return RobotPose(self.name, character, qpos.copy(), positions, wxyz, positions[self._root].copy())


@dataclass(frozen=True)
class MeshGeom:
    """A visual mesh of a robot, in its body's frame."""

    body: int
    vertices: np.ndarray  # (V, 3) float32, the geom's frame
    faces: np.ndarray  # (F, 3) uint32
    rgb: tuple[int, int, int]
    position: np.ndarray  # (3,) the geom in its body
    wxyz: np.ndarray  # (4,)


def robot_meshes(model: mujoco.MjModel) -> list[MeshGeom]:
    """The visual mesh geoms of `model` (those that collide with nothing; every mesh geom when
    none is purely visual), with their colours."""
    meshes = [g for g in range(model.ngeom) if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH]
    visual = [g for g in meshes if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0]
    out = []
    for g in visual or meshes:
        m = model.geom_dataid[g]
        v0, nv = model.mesh_vertadr[m], model.mesh_vertnum[m]
        f0, nf = model.mesh_faceadr[m], model.mesh_facenum[m]
        mat = model.geom_matid[g]
        rgba = model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g]
        out.append(
            MeshGeom(
                body=int(model.geom_bodyid[g]),
                vertices=model.mesh_vert[v0 : v0 + nv].astype(np.float32),
                faces=model.mesh_face[f0 : f0 + nf].astype(np.uint32),
                rgb=tuple(int(round(255 * c)) for c in rgba[:3]),
                position=model.geom_pos[g].copy(),
                wxyz=model.geom_quat[g].copy(),
            )
        )
    return out


class RobotView:
    """The robot's nodes in a viser scene: shown for one robot at a time, added the first time that
    robot is shown and kept (hidden) when another is chosen."""

    def __init__(self, scene: viser.SceneApi) -> None:
        self._scene = scene
        self._roots: dict[str, viser.FrameHandle] = {}  # robot name -> the node above all of its bodies
        self._bodies: dict[str, list] = {}  # robot name -> its body frame nodes
        self._shown: str | None = None

    def _add(self, name: str, model: mujoco.MjModel) -> list:
        scene = self._scene
        self._roots[name] = scene.add_frame(f"/robot_{name}", show_axes=False)
        bodies = [scene.add_frame(f"/robot_{name}/body{b}", show_axes=False) for b in range(model.nbody)]
        for k, geom in enumerate(robot_meshes(model)):
            scene.add_mesh_simple(
                f"/robot_{name}/body{geom.body}/mesh{k}",
                geom.vertices,
                geom.faces,
                color=geom.rgb,
                position=tuple(geom.position),
                wxyz=tuple(geom.wxyz),
            )
        return bodies

    def draw(self, pose: RobotPose | None) -> None:
        """Show `pose` (None: no robot)."""
        name = None if pose is None else pose.robot
        if name != self._shown:
            for other, root in self._roots.items():
                root.visible = other == name
            self._shown = name
        if pose is None:
            return
        if name not in self._bodies:
            from motion_env.retarget.robot import load_robot  # cached: the retargeter's model

            self._bodies[name] = self._add(name, load_robot(name).model)
        for node, position, wxyz in zip(self._bodies[name], pose.positions, pose.wxyz, strict=True):
            node.position = position
            node.wxyz = wxyz
