"""Kinematic replay: fit a motion onto the humanoid, then measure it frame by frame with MuJoCo.

:func:`measure` runs ``mj_forward`` on every frame (joint positions, geoms, contacts between
limbs, centre of mass) and ``mj_inverse`` with finite-difference velocities and accelerations
(the wrench the root would need), and returns per-frame arrays. The checks that turn them into a
verdict live in :mod:`motion_env.replay.plausibility`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.optimize import nnls

from motion_env.motion.rotations import quat_to_axis_angle
from motion_env.motion.types import Motion
from motion_env.replay.fit import clip_rest_directions, fit_qpos
from motion_env.replay.humanoid import DEFAULT_MASS, joint_ranges_rad, to_mujoco
from motion_env.replay.inputs import check_mass, check_motion
from motion_env.replay.mjcf import ModelIndex, load_model, model_index

CONTACT_HEIGHT = 0.05
"""A body point this close to the floor (m) can be pushed by it: the floor of a mocap take and
the placement of its foot joints are good to a few centimetres."""

FRICTION = 1.0  # ground friction coefficient, as the model's geoms (a rubber sole on a hard floor)


@dataclass
class Measurements:
    """Per-frame measurements of one motion replayed on the humanoid (MuJoCo frame, Z up).

    T = frames. Heights are above the floor (negative: below it).
    """

    fps: float
    mass: float
    rest_directions: np.ndarray  # (22, 3) rest pose of the humanoid built for this motion
    qpos: np.ndarray  # (T, nq) fitted humanoid poses
    fit_error: np.ndarray  # (T, 22) distance between the humanoid's joints and the motion's (m)
    lowest: np.ndarray  # (T,) height of the lowest point of the body
    lowest_geom: list[str]  # (T,) name of the geom holding that point
    com: np.ndarray  # (T, 3) centre of mass
    soles: np.ndarray  # (T, 4, 3) bottom of left heel, left toe, right heel, right toe
    self_depth: np.ndarray  # (T,) deepest overlap between two limbs (m), 0 if none
    self_pair: list[tuple[str, str]]  # (T,) the geoms of that overlap ("", "") if none
    limit_excess: np.ndarray  # (T, K) angle beyond the range, per ball joint (rad), K = BALL_JOINTS
    limit_axis: np.ndarray  # (T, K) which bound: 0..5 = (x lo, x hi, y lo, y hi, z lo, z hi)
    joints: np.ndarray  # (T, 22, 3) the motion's joints in the MuJoCo frame
    floor_points: np.ndarray  # (T, P, 3) body points the floor may push (geoms' lowest points)
    residual_force: np.ndarray  # (T,) root force the ground cannot supply, per kg (N/kg)
    residual_torque: np.ndarray  # (T,) root torque the ground cannot supply, per kg (N m/kg)

    @property
    def num_frames(self) -> int:
        return int(self.qpos.shape[0])


def _geom_points(model: mujoco.MjModel, xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
    """Bottom points of every geom's end spheres, (T, G, 2, 3): capsules have two, spheres one
    (repeated). These are the points through which the floor can touch the body."""
    size = model.geom_size  # (G, 3): radius, half-length
    axis = xmat.reshape(xmat.shape[:-1] + (3, 3))[..., :, 2]  # (T, G, 3) local z in the world
    is_capsule = (model.geom_type == mujoco.mjtGeom.mjGEOM_CAPSULE)[:, None]
    half = np.where(is_capsule, size[:, 1:2], 0.0)  # (G, 1)
    ends = xpos[:, :, None, :] + np.stack([1.0, -1.0])[None, None, :, None] * (
        half[None, :, :, None] * axis[:, :, None, :]
    )
    ends[..., 2] -= size[None, :, None, 0]
    return ends


def _velocities(model: mujoco.MjModel, qpos: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """qvel (T, nv) by central differences and qacc (T, nv) by differences of half-step
    velocities, both with MuJoCo's own quaternion arithmetic (``mj_differentiatePos``)."""
    n = len(qpos)
    half = np.zeros((max(n - 1, 0), model.nv))  # velocity between frames t and t+1
    for t in range(n - 1):
        mujoco.mj_differentiatePos(model, half[t], dt, qpos[t], qpos[t + 1])
    qvel = np.zeros((n, model.nv))
    qacc = np.zeros((n, model.nv))
    if n >= 2:
        qvel[0], qvel[-1] = half[0], half[-1]
        qvel[1:-1] = 0.5 * (half[:-1] + half[1:])
    if n >= 3:
        qacc[1:-1] = (half[1:] - half[:-1]) / dt
        qacc[0], qacc[-1] = qacc[1], qacc[-2]
    return qvel, qacc


def _limit_excess(qpos: np.ndarray, index: ModelIndex) -> tuple[np.ndarray, np.ndarray]:
    """Angle (T, K) by which each ball joint's rotation vector leaves its per-axis range."""
    quats = np.stack([qpos[:, a : a + 4] for a in index.ball_qpos], axis=1)  # (T, K, 4)
    rotvec = quat_to_axis_angle(quats)  # (T, K, 3) in the parent body's frame
    ranges = joint_ranges_rad()  # (K, 3, 2)
    below = ranges[None, :, :, 0] - rotvec  # > 0 when under the lower bound
    above = rotvec - ranges[None, :, :, 1]
    excess = np.stack([below, above], axis=-1).reshape(rotvec.shape[:2] + (6,))  # (T, K, 6)
    return np.maximum(excess.max(-1), 0.0), excess.argmax(-1)


def deepest_contact(
    data: mujoco.MjData, among: np.ndarray, names: list[str]
) -> tuple[float, tuple[str, str]]:
    """The deepest of the current contacts between two geoms that `among` (ngeom,) marks: its
    depth (m) and its geoms' `names`; ``(0.0, ("", ""))`` when no two of them overlap."""
    if data.ncon:
        pairs = data.contact.geom
        dist = np.where(among[pairs[:, 0]] & among[pairs[:, 1]], data.contact.dist, np.inf)
        k = int(np.argmin(dist))
        if dist[k] < 0:
            return float(-dist[k]), (names[pairs[k, 0]], names[pairs[k, 1]])
    return 0.0, ("", "")


def measure(motion: Motion, mass: float = DEFAULT_MASS) -> Measurements:
    """Replay `motion` on the humanoid of total mass `mass` (kg) and measure every frame.

    Each frame is fitted (:mod:`motion_env.replay.fit`) and run through ``mj_forward``; then
    ``mj_inverse`` (constraints off) gives the wrench the root needs for the observed
    accelerations, and the part the floor cannot supply is found by non-negative least squares
    over friction-cone forces at the body points within :data:`CONTACT_HEIGHT` of the floor.

    Raises ValueError for joints of a wrong shape or with NaN or infinite values (naming the
    frames), a rate that is not > 0 or a mass that is not a positive number.
    """
    joints, fps = check_motion(motion)
    mass = check_mass(mass)
    rest = clip_rest_directions(joints)
    model = load_model(mass, rest)
    index = model_index(model)
    data = mujoco.MjData(model)
    qpos = fit_qpos(joints, model, index, rest)
    n = len(qpos)
    dt = 1.0 / fps
    body_geoms = index.body_geoms
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(model.ngeom)]
    limbs = np.arange(model.ngeom) != index.floor_geom

    sites = np.zeros((n, len(index.joint_sites), 3))
    xpos = np.zeros((n, model.ngeom, 3))
    xmat = np.zeros((n, model.ngeom, 9))
    com = np.zeros((n, 3))
    self_depth = np.zeros(n)
    self_pair: list[tuple[str, str]] = [("", "")] * n
    for t in range(n):
        data.qpos[:] = qpos[t]
        mujoco.mj_forward(model, data)
        sites[t] = data.site_xpos[index.joint_sites]
        xpos[t] = data.geom_xpos
        xmat[t] = data.geom_xmat
        com[t] = data.subtree_com[index.joint_bodies[0]]
        self_depth[t], self_pair[t] = deepest_contact(data, limbs, names)

    points = _geom_points(model, xpos, xmat)[:, body_geoms]  # (T, G, 2, 3)
    heights = points[..., 2].reshape(n, -1)
    flat = heights.argmin(axis=1)
    lowest = heights[np.arange(n), flat]
    lowest_geom = [names[body_geoms[i // 2]] for i in flat]
    sole_ids = [index.foot_geoms[s] for s in ("left", "right")]
    # Heel and toe of each foot: the mean of its two sole capsules' end points.
    full = _geom_points(model, xpos, xmat)
    # MuJoCo turns a fromto capsule's z axis from `to` towards `from` (toe -> heel), so end 0
    # (plus the axis) is the heel.
    soles = np.stack([full[:, ids, end].mean(axis=1) for ids in sole_ids for end in (0, 1)], axis=1)

    excess, axis = _limit_excess(qpos, index)
    _, residual = inverse_dynamics(model, index, qpos, points.reshape(n, -1, 3), dt)
    return Measurements(
        fps=fps,
        mass=mass,
        rest_directions=rest,
        qpos=qpos,
        fit_error=np.linalg.norm(sites - to_mujoco(joints), axis=-1),
        lowest=lowest,
        lowest_geom=lowest_geom,
        com=com,
        soles=soles,
        self_depth=self_depth,
        self_pair=self_pair,
        limit_excess=excess,
        limit_axis=axis,
        joints=to_mujoco(joints),
        floor_points=points.reshape(n, -1, 3),
        residual_force=np.linalg.norm(residual[:, :3], axis=1) / mass,
        residual_torque=np.linalg.norm(residual[:, 3:], axis=1) / mass,
    )


def inverse_dynamics(
    model: mujoco.MjModel, index: ModelIndex, qpos: np.ndarray, points: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`root_inverse_dynamics` of the humanoid, whose free root is the pelvis."""
    return root_inverse_dynamics(model, int(index.joint_bodies[0]), qpos, points, dt)


def root_inverse_dynamics(
    model: mujoco.MjModel, root: int, qpos: np.ndarray, points: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised forces of the replayed motion, split into what the floor supplies and the rest.

    ``mj_inverse`` (constraints off) gives the forces the motion needs, from finite-difference
    velocities and accelerations; the floor's share is the friction-cone force at the candidate
    points (T, P, 3) within CONTACT_HEIGHT of the floor that best supplies the root's wrench (non-
    negative least squares). `root` is the body of the model's free joint, the first joint (the
    humanoid's pelvis, a robot's base). Returns ``(qfrc (T, nv), residual (T, 6))``: the joint
    torques with the floor's forces accounted for (the root's entries are the residual), and the
    residual root wrench: world force (3) and torque in the root's frame (3), in N and N m.
    """
    n = len(qpos)
    qvel, qacc = _velocities(model, qpos, dt)
    inv = model.__copy__()
    inv.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    data = mujoco.MjData(inv)
    # Friction pyramid edges: the floor pushes up, with up to FRICTION times that sideways.
    edges = np.array(
        [[FRICTION, 0, 1], [-FRICTION, 0, 1], [0, FRICTION, 1], [0, -FRICTION, 1]], dtype=np.float64
    ).T  # (3, 4)
    jacp = np.zeros((3, model.nv))
    qfrc = np.zeros((n, model.nv))
    for t in range(n):
        data.qpos[:] = qpos[t]
        data.qvel[:] = qvel[t]
        data.qacc[:] = qacc[t]
        mujoco.mj_inverse(inv, data)
        qfrc[t] = data.qfrc_inverse
        near = points[t][points[t, :, 2] < CONTACT_HEIGHT]
        if not len(near):
            continue
        jacs = []
        for p in near:
            mujoco.mj_jac(inv, data, jacp, None, np.array([p[0], p[1], 0.0]), root)
            jacs.append(jacp.T @ edges)  # (nv, 4): generalised force of each edge's unit force
        basis = np.concatenate(jacs, axis=1)  # (nv, 4P)
        coef, _ = nnls(basis[:6], qfrc[t, :6], maxiter=200)
        qfrc[t] -= basis @ coef
    return qfrc, qfrc[:, :6].copy()
