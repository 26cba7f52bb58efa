"""A robot trajectory measured in MuJoCo frame by frame: the robot's side of :mod:`.kinematic`.

:func:`measure_robot` takes a robot's ``qpos`` (T, nq) (free root first: x, y, z, qw, qx, qy, qz,
then the joints in the order of the XML) and its MuJoCo model, runs ``mj_forward`` on every frame
and ``mj_inverse`` on finite-difference velocities and accelerations (through
:func:`motion_env.replay.kinematic.root_inverse_dynamics`, the humanoid's own function), and
returns per-frame arrays. The checks that turn them into a verdict are in :mod:`.robot`.

- The floor is the highest upward-facing plane of the world body (z = 0 in the robot scenes
  shipped with :mod:`motion_env.retarget`; a model without a floor gets z = 0). Heights are
  measured from it.
- Collision geoms are the robot's geoms with ``contype`` or ``conaffinity`` set. Their surface is
  sampled once (:class:`GeomPoints`: a mesh's convex-hull vertices, as MuJoCo collides them; box
  corners; cylinder rims; sphere and capsule centres with their radius) and the lowest sample is
  the geom's lowest point.
- The feet are the bodies :func:`find_feet` names; each gets a heel and a toe point on its sole.
- A clip not at the replay's 20 fps (:data:`motion_env.motion.skeleton.FPS`, the rate of the
  humanoid's calibration) is also measured resampled to 20 fps (:func:`resample_qpos`):
  :attr:`RobotMeasurements.replay`, for the checks built on steps and accelerations.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from motion_env.motion.skeleton import FPS
from motion_env.replay.inputs import check_positive, check_qpos
from motion_env.replay.kinematic import CONTACT_HEIGHT, deepest_contact, root_inverse_dynamics

FOOT_BODIES: tuple[tuple[str, str], ...] = (
    ("left_ankle_roll_link", "right_ankle_roll_link"),  # Unitree G1 (and H1-2)
    ("left_foot_link", "right_foot_link"),  # Booster T1
)
"""Known (left, right) foot bodies, tried in order before the name patterns of :func:`find_feet`."""
FOOT_WORDS = ("foot", "ankle", "sole", "toe")
SOLE_BAND = 0.01  # m: sole samples this close to the lowest, rearmost or foremost one count
_G = mujoco.mjtGeom
_RIM = 16  # samples per cylinder rim: the lowest point is then off by < 2 % of the radius


@dataclass
class RobotMeasurements:
    """Per-frame measurements of a robot trajectory (MuJoCo frame, Z up, heights above the floor)."""

    fps: float
    mass: float  # kg, the robot's whole mass
    name: str  # the model's name
    feet: tuple[str, str]  # the left and right foot bodies
    floor: float  # height of the floor in the model (m); the arrays below are relative to it
    qpos: np.ndarray  # (T, nq) as given (quaternions normalised)
    lowest: np.ndarray  # (T,) height of the lowest point of any collision geom
    lowest_geom: list[str]  # (T,) the geom holding it (its name, else its body's)
    com: np.ndarray  # (T, 3) centre of mass
    soles: np.ndarray  # (T, 4, 3) left heel, left toe, right heel, right toe
    self_depth: np.ndarray  # (T,) deepest contact between two of the robot's geoms (m), 0 if none
    self_pair: list[tuple[str, str]]  # (T,) the geoms of that contact, ("", "") if none
    limit_excess: np.ndarray  # (T, J) angle beyond the range, per limited hinge or ball joint (rad)
    limit_joints: list[str]  # (J,) their names
    limit_ranges: np.ndarray  # (J, 2) their ranges (rad; a ball joint: 0, largest angle)
    floor_points: np.ndarray  # (T, P, 3) geom points the floor may push (inf: none)
    residual_force: np.ndarray  # (T,) root force the ground cannot supply, per kg (N/kg)
    residual_torque: np.ndarray  # (T,) root torque the ground cannot supply, per kg (N m/kg)
    replay: RobotMeasurements | None = None  # the clip resampled to 20 fps (None: it is at 20 fps)

    @property
    def num_frames(self) -> int:
        return int(self.qpos.shape[0])


def load_robot_model(model: mujoco.MjModel | str | Path) -> mujoco.MjModel:
    """`model` itself, or the MJCF scene at that path compiled; ValueError when it has no free
    root as its first joint."""
    if not isinstance(model, mujoco.MjModel):
        path = Path(model)
        if not path.is_file():
            raise FileNotFoundError(f"no MuJoCo model at {path}")
        model = mujoco.MjModel.from_xml_path(str(path))
    if model.njnt == 0 or model.jnt_type[0] != mujoco.mjtJoint.mjJNT_FREE:
        raise ValueError("the robot model must have a free root joint first (qpos x, y, z, qw, qx, qy, qz)")
    return model


def model_name(model: mujoco.MjModel) -> str:
    """The name of the model (``<mujoco model="...">``)."""
    return bytes(model.names[: model.names.index(b"\0")]).decode() or "robot"


def floor_height(model: mujoco.MjModel) -> float:
    """Height of the floor: the highest plane of the world body facing up; 0 when there is none."""
    heights = []
    for g in np.flatnonzero((model.geom_bodyid == 0) & (model.geom_type == _G.mjGEOM_PLANE)):
        up = np.zeros(9)
        mujoco.mju_quat2Mat(up, model.geom_quat[g])
        if up[8] > 0.999:  # the plane's normal (its local z) points up
            heights.append(float(model.geom_pos[g, 2]))
    return max(heights, default=0.0)


def geom_name(model: mujoco.MjModel, geom: int) -> str:
    """A geom's name, else its body's."""
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or mujoco.mj_id2name(
        model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[geom])
    )


def collision_geoms(model: mujoco.MjModel) -> np.ndarray:
    """The robot's collision geoms: not on the world body, ``contype`` or ``conaffinity`` set."""
    colliding = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
    return np.flatnonzero(colliding & (model.geom_bodyid > 0))


def _shape_samples(model: mujoco.MjModel, g: int) -> tuple[np.ndarray, float]:
    """Surface samples (n, 3) of geom `g` in its frame, and the radius around each sample."""
    kind, size = model.geom_type[g], model.geom_size[g]
    if kind == _G.mjGEOM_SPHERE:
        return np.zeros((1, 3)), float(size[0])
    if kind == _G.mjGEOM_CAPSULE:
        return np.array([[0, 0, size[1]], [0, 0, -size[1]]], dtype=np.float64), float(size[0])
    if kind == _G.mjGEOM_BOX:
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
        return corners * size, 0.0
    if kind == _G.mjGEOM_CYLINDER:
        angle = np.linspace(0, 2 * np.pi, _RIM, endpoint=False)
        ring = np.stack([size[0] * np.cos(angle), size[0] * np.sin(angle)], axis=1)
        return np.concatenate([np.c_[ring, np.full(_RIM, h)] for h in (size[1], -size[1])]), 0.0
    if kind == _G.mjGEOM_ELLIPSOID:
        k = np.arange(64) + 0.5  # a Fibonacci sphere, stretched
        z, phi = 1 - 2 * k / 64, np.pi * (1 + 5**0.5) * k
        unit = np.stack([np.sqrt(1 - z**2) * np.cos(phi), np.sqrt(1 - z**2) * np.sin(phi), z], axis=1)
        return unit * size[:3], 0.0
    mesh = model.geom_dataid[g]
    if kind == _G.mjGEOM_MESH and mesh >= 0:
        start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
        verts = model.mesh_vert[start : start + count]
        graph = model.mesh_graphadr[mesh]
        if graph >= 0:  # the convex hull MuJoCo collides: numvert, numface, edgeadr[numvert], ids
            num = model.mesh_graph[graph]
            verts = verts[model.mesh_graph[graph + 2 + num : graph + 2 + 2 * num]]
        return np.asarray(verts, dtype=np.float64), 0.0
    return np.zeros((1, 3)), 0.0  # planes, height fields: their origin


class GeomPoints:
    """Surface samples of a set of geoms, turned into world points of a pose at once: the one
    lowest-point implementation of the package (the retargeter's floor uses it too)."""

    def __init__(self, model: mujoco.MjModel, geoms: np.ndarray) -> None:
        self.geoms = np.asarray(geoms, dtype=int)
        samples = [_shape_samples(model, int(g)) for g in self.geoms]
        self.local = np.concatenate([s for s, _ in samples])  # (N, 3)
        self.radius = np.concatenate([np.full(len(s), r) for s, r in samples])  # (N,)
        counts = np.array([len(s) for s, _ in samples])
        self.owner = np.repeat(np.arange(len(samples)), counts)  # (N,) index into geoms
        self.ends = np.cumsum(counts).astype(int)
        self.starts = self.ends - counts

    def bottoms(self, data: mujoco.MjData) -> np.ndarray:
        """(N, 3) world points, each a sample lowered by its radius (the geom's surface below it)."""
        xpos = data.geom_xpos[self.geoms][self.owner]
        xmat = data.geom_xmat[self.geoms].reshape(-1, 3, 3)[self.owner]
        out = xpos + np.einsum("nij,nj->ni", xmat, self.local)
        out[:, 2] -= self.radius
        return out

    def lowest_per_geom(self, points: np.ndarray) -> np.ndarray:
        """(G,) height of each geom's lowest point, from :meth:`bottoms`."""
        return np.minimum.reduceat(points[:, 2], self.starts)

    def lowest(self, xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
        """(T, G) height of each geom's lowest point over many poses at once (no MjData).

        xpos: (T, G, 3) the geoms' world positions; xmat: (T, G, 9) their orientations (MuJoCo's
        row-major ``geom_xmat``), both in the order of ``self.geoms``.
        """
        down = xmat[:, self.owner, 6:9]  # (T, N, 3): how each local axis projects on world z
        z = xpos[:, self.owner, 2] + np.einsum("tnj,nj->tn", down, self.local) - self.radius
        return np.minimum.reduceat(z, self.starts, axis=1)


def _side(name: str) -> str:
    low = name.lower()
    if "left" in low or low.startswith("l_"):
        return "left"
    if "right" in low or low.startswith("r_"):
        return "right"
    return ""


def _subtree(model: mujoco.MjModel, body: int) -> np.ndarray:
    """Ids of `body` and every body below it."""
    inside = np.zeros(model.nbody, dtype=bool)
    inside[body] = True
    for b in range(body + 1, model.nbody):  # MuJoCo numbers a parent before its children
        inside[b] = inside[model.body_parentid[b]]
    return np.flatnonzero(inside)


def find_feet(model: mujoco.MjModel, feet: tuple[str, str] | None = None) -> tuple[int, int]:
    """Ids of the (left, right) foot bodies: `feet` by name; else the first pair of
    :data:`FOOT_BODIES` the model has; else, for the first of :data:`FOOT_WORDS` that names a body
    of each side ('left'/'l_', 'right'/'r_') with collision geoms below it, the deepest such body."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(model.nbody)]
    if feet is not None:
        missing = [f for f in feet if f not in names]
        if len(feet) != 2 or missing:
            raise ValueError(f"feet must name the left and right foot bodies of the model, missing {missing}")
        return names.index(feet[0]), names.index(feet[1])
    for left, right in FOOT_BODIES:
        if left in names and right in names:
            return names.index(left), names.index(right)
    colliding = set(model.geom_bodyid[collision_geoms(model)].tolist())
    depth = np.zeros(model.nbody, dtype=int)
    for b in range(1, model.nbody):
        depth[b] = depth[model.body_parentid[b]] + 1
    for word in FOOT_WORDS:
        found = []
        for side in ("left", "right"):
            bodies = [
                b
                for b, n in enumerate(names)
                if word in n.lower() and _side(n) == side and colliding & set(_subtree(model, b).tolist())
            ]
            found.append(max(bodies, key=lambda b: depth[b]) if bodies else -1)
        if min(found) > 0:
            return found[0], found[1]
    raise ValueError(
        f"no foot bodies found in {model_name(model)} (tried {FOOT_BODIES} and names with {FOOT_WORDS} "
        "and left/right): name them with feet=(left, right)"
    )


def sole_points(model: mujoco.MjModel, feet: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """The heel and toe of each foot: ``(bodies (4,), local points (4, 3))`` in the order left heel,
    left toe, right heel, right toe, each fixed in its foot body's frame.

    Found in the model's first keyframe (else ``qpos0``): among the bottom samples of the foot's
    collision geoms (its body and those below it) within :data:`SOLE_BAND` of the lowest, the
    mean of the rearmost and of the foremost ones (within SOLE_BAND) along the root's heading.
    """
    data = mujoco.MjData(model)
    data.qpos[:] = model.key_qpos[0] if model.nkey else model.qpos0
    mujoco.mj_kinematics(model, data)
    forward = data.xmat[model.jnt_bodyid[0]].reshape(3, 3)[:, 0].copy()
    forward[2] = 0.0
    forward /= max(np.linalg.norm(forward), 1e-9)
    bodies, points = [], []
    for foot in feet:
        geoms = collision_geoms(model)
        geoms = geoms[np.isin(model.geom_bodyid[geoms], _subtree(model, foot))]
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, foot)
        if not len(geoms):
            raise ValueError(f"the foot body {name!r} has no collision geoms (none below it either)")
        world = GeomPoints(model, geoms).bottoms(data)
        sole = world[world[:, 2] <= world[:, 2].min() + SOLE_BAND]
        along = sole @ forward
        rotation, origin = data.xmat[foot].reshape(3, 3), data.xpos[foot]
        for end in (sole[along <= along.min() + SOLE_BAND], sole[along >= along.max() - SOLE_BAND]):
            bodies.append(foot)
            points.append(rotation.T @ (end.mean(axis=0) - origin))
    return np.array(bodies), np.array(points)


def limited_joints(model: mujoco.MjModel) -> np.ndarray:
    """Ids of the joints with a range to check: limited hinges and limited balls."""
    kinds = np.isin(model.jnt_type, [mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_BALL])
    return np.flatnonzero(kinds & (model.jnt_limited != 0))


def limit_excess(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """(T, J) angle (rad) by which each of :func:`limited_joints` leaves its range (0 inside): a
    hinge's angle beyond ``jnt_range``, a ball's rotation angle beyond ``jnt_range[1]``."""
    out = []
    for j in limited_joints(model):
        a = model.jnt_qposadr[j]
        low, high = model.jnt_range[j]
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
            out.append(np.maximum(np.maximum(low - qpos[:, a], qpos[:, a] - high), 0.0))
        else:
            w = np.abs(qpos[:, a]) / np.linalg.norm(qpos[:, a : a + 4], axis=1)
            out.append(np.maximum(2 * np.arccos(np.clip(w, 0.0, 1.0)) - high, 0.0))
    return np.stack(out, axis=1) if out else np.zeros((len(qpos), 0))


def resample_qpos(model: mujoco.MjModel, qpos: np.ndarray, fps: float, new_fps: float) -> np.ndarray:
    """`qpos` (T, nq) at `fps` resampled to `new_fps` over the same time span (from frame 0 to at
    most the last frame), interpolated joint by joint as MuJoCo integrates (quaternions along
    the shortest rotation)."""
    n = len(qpos)
    times = np.arange(0.0, (n - 1) / fps + 1e-9, 1.0 / new_fps)
    out = np.zeros((len(times), model.nq))
    step = np.zeros(model.nv)
    for i, time in enumerate(times):
        a = min(int(time * fps), max(n - 2, 0))
        out[i] = qpos[a]
        if n > 1:
            mujoco.mj_differentiatePos(model, step, 1.0, qpos[a], qpos[a + 1])
            mujoco.mj_integratePos(model, out[i], step, time * fps - a)
    return out


def measure_robot(
    qpos: np.ndarray,
    model: mujoco.MjModel | str | Path,
    fps: float,
    feet: tuple[str, str] | None = None,
    resample: bool = True,
) -> RobotMeasurements:
    """Measure robot trajectory `qpos` (T, nq) at `fps` frames per second on `model` (an MjModel
    or an MJCF path), frame by frame; when `resample` and `fps` is not 20, the same measured on
    the clip resampled to 20 fps goes in ``replay``.

    ``mj_forward`` gives the geoms (lowest point, floor candidates), the centre of mass, the sole
    points and the contacts between the robot's own geoms (MuJoCo already leaves out parent-child
    pairs and ``<exclude>`` pairs); ``mj_inverse`` with constraints off gives the root wrench the
    motion needs, and the part the floor cannot supply is what non-negative friction-cone forces
    at the geom points within CONTACT_HEIGHT of the floor leave over (as for the humanoid).

    Raises ValueError for a qpos of a wrong shape or with NaN/infinite values, a rate not > 0, a
    model without a free root first, or feet that cannot be found.
    """
    model = load_robot_model(model)
    fps = check_positive(fps, "fps", " of frames per second")
    qpos = check_qpos(qpos, model.nq)
    floor = floor_height(model)
    local = qpos.copy()
    local[:, 2] -= floor  # measure from a floor at z = 0
    feet_ids = find_feet(model, feet)
    root = int(model.jnt_bodyid[0])
    frames = _measure_frames(model, local, feet_ids, root)
    mass = float(model.body_subtreemass[root])
    _, residual = root_inverse_dynamics(model, root, local, frames["floor_points"], 1.0 / fps)
    body = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in feet_ids]
    replay = None
    if resample and abs(fps - FPS) > 1e-6:
        replay = measure_robot(resample_qpos(model, qpos, fps, FPS), model, FPS, feet, resample=False)
    joints = limited_joints(model)
    ranges = model.jnt_range[joints].copy()
    ranges[model.jnt_type[joints] == mujoco.mjtJoint.mjJNT_BALL, 0] = 0.0
    return RobotMeasurements(
        fps=fps,
        mass=mass,
        name=model_name(model),
        feet=(body[0], body[1]),
        floor=floor,
        qpos=qpos,
        **frames,
        limit_excess=limit_excess(model, qpos),
        limit_joints=[mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in joints],
        limit_ranges=ranges,
        residual_force=np.linalg.norm(residual[:, :3], axis=1) / mass,
        residual_torque=np.linalg.norm(residual[:, 3:], axis=1) / mass,
        replay=replay,
    )


def _measure_frames(model: mujoco.MjModel, qpos: np.ndarray, feet: tuple[int, int], root: int) -> dict:
    """``mj_forward`` on every frame of `qpos` (T, nq), the floor at z = 0: the per-frame fields of
    :class:`RobotMeasurements` that the pose alone gives (``lowest``, ``lowest_geom``, ``com``,
    ``soles``, ``self_depth``, ``self_pair``, ``floor_points``)."""
    sole_bodies, sole_local = sole_points(model, feet)
    geoms = collision_geoms(model)
    shapes = GeomPoints(model, geoms)
    names = [geom_name(model, g) for g in range(model.ngeom)]
    robot_geom = model.geom_bodyid > 0

    n = len(qpos)
    data = mujoco.MjData(model)
    lowest = np.zeros(n)
    lowest_geom = [""] * n
    com = np.zeros((n, 3))
    soles = np.zeros((n, 4, 3))
    self_depth = np.zeros(n)
    self_pair: list[tuple[str, str]] = [("", "")] * n
    floor_points = np.full((n, 5 * len(geoms), 3), np.inf)
    for t in range(n):
        data.qpos[:] = qpos[t]
        mujoco.mj_forward(model, data)
        points = shapes.bottoms(data)
        per_geom = shapes.lowest_per_geom(points)
        k = int(np.argmin(per_geom))
        lowest[t], lowest_geom[t] = per_geom[k], names[geoms[k]]
        for k in np.flatnonzero(per_geom < CONTACT_HEIGHT):
            mine = points[shapes.starts[k] : shapes.ends[k]]
            near = mine[mine[:, 2] < CONTACT_HEIGHT]
            # The extremes of the geom's part near the floor span its support polygon.
            pick = np.unique([*near[:, :2].argmin(axis=0), *near[:, :2].argmax(axis=0), near[:, 2].argmin()])
            floor_points[t, 5 * k : 5 * k + len(pick)] = near[pick]
        com[t] = data.subtree_com[root]
        rotation = data.xmat[sole_bodies].reshape(-1, 3, 3)
        soles[t] = data.xpos[sole_bodies] + np.einsum("kij,kj->ki", rotation, sole_local)
        self_depth[t], self_pair[t] = deepest_contact(data, robot_geom, names)
    return {
        "lowest": lowest,
        "lowest_geom": lowest_geom,
        "com": com,
        "soles": soles,
        "self_depth": self_depth,
        "self_pair": self_pair,
        "floor_points": floor_points,
    }
