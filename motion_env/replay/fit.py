"""Joint positions -> humanoid qpos: fit every body's rotation to the observed joint positions.

The fit is closed-form and vectorised over frames, in MuJoCo's frame (see
:func:`humanoid.to_mujoco`):

- the pelvis and the chest, which have several child joints, get the rotation that best maps
  their rest child offsets onto the observed ones (Kabsch / Wahba, by SVD);
- a thigh or a shin points along its bone, and turns so that the knee bends in the plane it
  points into; a straight leg turns with the pelvis (so a knee bent a little backwards shows as
  a negative flexion, and toes turned out as a turn of the ankle);
- an upper arm points along its bone and turns so that the elbow bends in the plane of the
  forearm (towards the chest's forward when the arm is straight);
- the two lumbar bodies point along the spine and share out the twist between pelvis and chest;
- every other body (neck, clavicles, forearms, feet) takes the shortest-arc rotation of its bone
  relative to its parent, as its twist is not observable from joint positions.

Positions are then exact up to bone-length differences and the rest shape of the pelvis and
chest; :func:`motion_env.replay.plausibility.evaluate` reports the remaining error per joint.
"""

from __future__ import annotations

import mujoco
import numpy as np

from motion_env.motion.rotations import qbetween, qfix, quat_from_matrix, quat_to_matrix
from motion_env.motion.skeleton import BONE_LENGTHS, JOINT_INDEX, NUM_JOINTS, PARENTS
from motion_env.motion.validation import check_joints
from motion_env.replay.humanoid import BALL_JOINTS, CHILDREN, REST_DIRECTIONS, rest_positions, to_mujoco
from motion_env.replay.mjcf import ModelIndex

_EPS = 1e-9
_FORWARD = np.array([1.0, 0.0, 0.0])  # MuJoCo frame
_LEFT = np.array([0.0, 1.0, 0.0])
# Weights of the twist references that take over when a leg or an arm is straight: the pelvis's
# forward for a leg (the foot's direction is no guide: at toe-off it can point backwards), the
# chest's forward for an arm.
_LEG_TWIST_PRIOR = 0.25
_FOOT_PITCH_RANGE = (np.deg2rad(5.0), np.deg2rad(60.0))
_KNEE_PLANE_SURE = 0.35  # knee offset (in thigh lengths; ~40 degrees of flexion) trusted alone
_ARM_TWIST_PRIOR = 0.5


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), _EPS)


def _frame(primary: np.ndarray, secondary: np.ndarray) -> np.ndarray:
    """Orthonormal frames (..., 3, 3) with columns (primary, secondary made normal, their cross)."""
    u = _unit(primary)
    v = _unit(secondary - (secondary * u).sum(-1, keepdims=True) * u)
    return np.stack([u, v, np.cross(u, v)], axis=-1)


def _triad(a: np.ndarray, b: np.ndarray, obs_a: np.ndarray, obs_b: np.ndarray) -> np.ndarray:
    """World rotations (T, 3, 3) mapping rest vectors (a, b) (3,) onto observed (T, 3) ones.

    The primary vector is matched exactly, the secondary only fixes the twist about it.
    """
    rest = _frame(a, b)
    return _frame(obs_a, obs_b) @ rest.T


def _kabsch(rest: np.ndarray, obs: np.ndarray) -> np.ndarray:
    """Rotations (T, 3, 3) best mapping rest vectors (K, 3) onto observed (T, K, 3) (least squares)."""
    h = np.einsum("ki,tkj->tij", rest, obs)  # (T, 3, 3) cross-covariance
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.transpose(0, 2, 1) @ u.transpose(0, 2, 1)))
    fix = np.ones((len(obs), 3))
    fix[:, 2] = d
    return vt.transpose(0, 2, 1) @ (fix[:, :, None] * u.transpose(0, 2, 1))


def _swing(parent_world: np.ndarray, rest_dir: np.ndarray, obs_dir: np.ndarray) -> np.ndarray:
    """World rotations (T, 3, 3) of a body whose local rotation is the shortest arc taking its
    rest bone direction onto the observed one, seen from its parent."""
    local_obs = np.einsum("tji,tj->ti", parent_world, obs_dir)  # parent^T @ obs
    local = quat_to_matrix(qbetween(np.broadcast_to(rest_dir, local_obs.shape), local_obs))
    return parent_world @ local


def clip_rest_directions(joints: np.ndarray) -> np.ndarray:
    """Rest bone directions (22, 3) whose pelvis and chest have the clip's own shape.

    Mocap sources place the hips, collars and neck differently around the pelvis and spine3
    (the canonical skeleton fixes bone lengths, not these angles), and a rigid pelvis of the
    wrong shape shifts the whole leg. The median offsets of those joints in a pelvis (chest)
    frame built from the hip (collar) line and the spine, mirrored to be symmetric, replace the
    defaults of :data:`humanoid.REST_DIRECTIONS`, and so does the pitch of a flat foot; limbs
    keep theirs. joints: (T, 22, 3), Y up, floor at y = 0.
    """
    joints = check_joints(joints)
    j = JOINT_INDEX
    dirs = REST_DIRECTIONS.copy()
    for centre, left, right, up in (
        ("pelvis", "left_hip", "right_hip", "spine1"),
        ("spine3", "left_collar", "right_collar", "neck"),
    ):
        c, lj, rj, uj = j[centre], j[left], j[right], j[up]
        # Motion-frame columns: x = across (left), y = up, z = x cross y = forward.
        frames = _frame(joints[:, lj] - joints[:, rj], joints[:, uj] - joints[:, c])
        local = np.einsum("tji,tkj->tki", frames, joints[:, [lj, rj, uj]] - joints[:, c : c + 1])
        med = _unit(np.median(_unit(local), axis=0))  # (3, 3): left, right, up
        side = 0.5 * (med[0] + med[1] * np.array([-1.0, 1.0, 1.0]))
        dirs[lj] = _unit(side)
        dirs[rj] = _unit(side * np.array([-1.0, 1.0, 1.0]))
        dirs[uj] = _unit(med[2] * np.array([0.0, 1.0, 1.0]))
    # The foot: pitch of the ankle->toe bone when the foot is flat, from the low ankle and toe
    # heights of the clip (the ankle sits 5 to 10 cm above the toe joint, depending on the source).
    drop = []
    for side in ("left", "right"):
        ankle, toe = joints[:, j[f"{side}_ankle"], 1], joints[:, j[f"{side}_foot"], 1]
        drop.append((np.percentile(ankle, 10) - np.percentile(toe, 10)) / BONE_LENGTHS[j[f"{side}_foot"]])
    pitch = np.clip(np.arcsin(np.clip(np.mean(drop), -1.0, 1.0)), *_FOOT_PITCH_RANGE)
    for side in ("left", "right"):
        dirs[j[f"{side}_foot"]] = np.array([0.0, -np.sin(pitch), np.cos(pitch)])
    return dirs


def fit_rotations(
    joints: np.ndarray, rest_directions: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """World rotation of every body of the humanoid from joint positions.

    joints: (T, 22, 3) positions in the motion frame (Y up); rest_directions: the model's rest
    bone directions (22, 3), default :data:`humanoid.REST_DIRECTIONS`. Returns ``(positions (T, 22, 3),
    world (T, 22, 3, 3))`` in MuJoCo's frame; ``world[:, j]`` is the rotation of the body whose
    origin is joint j (identity in the rest pose), and is left as identity for leaf joints.
    """
    joints = check_joints(joints)
    j = JOINT_INDEX
    p = to_mujoco(joints)
    rest = to_mujoco(rest_positions(rest_directions))
    n = p.shape[0]

    def vec(a: int | str, b: int | str) -> np.ndarray:  # observed a -> b, (T, 3)
        a, b = j.get(a, a), j.get(b, b)
        return p[:, b] - p[:, a]

    def rvec(a: int | str, b: int | str) -> np.ndarray:  # rest a -> b, (3,)
        a, b = j.get(a, a), j.get(b, b)
        return rest[b] - rest[a]

    world = np.broadcast_to(np.eye(3), (n, NUM_JOINTS, 3, 3)).copy()

    def multi(joint: int) -> np.ndarray:
        kids = CHILDREN[joint]
        obs = np.stack([_unit(vec(joint, c)) * np.linalg.norm(rvec(joint, c)) for c in kids], axis=1)
        return _kabsch(np.stack([rvec(joint, c) for c in kids]), obs)

    world[:, j["pelvis"]] = multi(j["pelvis"])
    world[:, j["spine3"]] = multi(j["spine3"])

    # Lumbar bodies: point along the spine, twist shared out between pelvis and chest.
    left_pelvis = world[:, j["pelvis"]] @ _LEFT
    left_chest = world[:, j["spine3"]] @ _LEFT
    for name, child, w_chest in (("spine1", "spine2", 1 / 3), ("spine2", "spine3", 2 / 3)):
        lateral = (1 - w_chest) * left_pelvis + w_chest * left_chest
        world[:, j[name]] = _triad(rvec(name, child), _LEFT, vec(name, child), lateral)

    chest_fwd = world[:, j["spine3"]] @ _FORWARD
    pelvis_fwd = world[:, j["pelvis"]] @ _FORWARD
    for side in ("left", "right"):
        hip, knee, ankle, toe = (j[f"{side}_{k}"] for k in ("hip", "knee", "ankle", "foot"))
        # Where the knee points: its offset from the hip-ankle line (length ~ sin(flexion / 2)),
        # and the pelvis's forward, which fades out as the knee bends and decides when it is straight.
        line = _unit(vec(hip, ankle))
        thigh = vec(hip, knee)
        knee_out = (thigh - (thigh * line).sum(-1, keepdims=True) * line) / np.linalg.norm(rvec(hip, knee))
        fade = np.clip(1.0 - np.linalg.norm(knee_out, axis=-1, keepdims=True) / _KNEE_PLANE_SURE, 0.0, 1.0)
        leg_fwd = knee_out + _LEG_TWIST_PRIOR * fade * pelvis_fwd
        rest_fwd = _LEG_TWIST_PRIOR * _FORWARD
        world[:, hip] = _triad(rvec(hip, knee), rest_fwd, thigh, leg_fwd)
        world[:, knee] = _triad(rvec(knee, ankle), rest_fwd, vec(knee, ankle), leg_fwd)
        world[:, ankle] = _swing(world[:, knee], _unit(rvec(ankle, toe)), _unit(vec(ankle, toe)))

        collar, shoulder, elbow, wrist = (j[f"{side}_{k}"] for k in ("collar", "shoulder", "elbow", "wrist"))
        world[:, collar] = _swing(
            world[:, j["spine3"]], _unit(rvec(collar, shoulder)), _unit(vec(collar, shoulder))
        )
        arm_rest = _unit(rvec(elbow, wrist)) + _ARM_TWIST_PRIOR * _FORWARD
        arm_obs = _unit(vec(elbow, wrist)) + _ARM_TWIST_PRIOR * chest_fwd
        world[:, shoulder] = _triad(rvec(shoulder, elbow), arm_rest, vec(shoulder, elbow), arm_obs)
        world[:, elbow] = _swing(world[:, shoulder], _unit(rvec(elbow, wrist)), _unit(vec(elbow, wrist)))

    neck, head = j["neck"], j["head"]
    world[:, neck] = _swing(world[:, j["spine3"]], _unit(rvec(neck, head)), _unit(vec(neck, head)))
    return p, world


def fit_qpos(
    joints: np.ndarray, model: mujoco.MjModel, index: ModelIndex, rest_directions: np.ndarray | None = None
) -> np.ndarray:
    """qpos (T, nq) of the humanoid that reproduces joint positions (T, 22, 3) (motion frame).

    `model` must be built with the same `rest_directions` (see :func:`motion_env.replay.mjcf.load_model`).
    The free joint takes the pelvis position and world rotation; each ball joint the rotation of
    its body relative to its parent body. Quaternions are made continuous in time.
    """
    p, world = fit_rotations(joints, rest_directions)
    n = p.shape[0]
    parents = np.array([PARENTS[b] for b in BALL_JOINTS])
    local = np.einsum("tkji,tkjl->tkil", world[:, parents], world[:, list(BALL_JOINTS)])  # parent^T child
    local_q = qfix(quat_from_matrix(local))  # (T, K, 4) w, x, y, z as MuJoCo stores them
    root_q = qfix(quat_from_matrix(world[:, 0]))
    qpos = np.zeros((n, model.nq))
    qpos[:, 0:3] = p[:, 0]
    qpos[:, 3:7] = root_q
    for k, adr in enumerate(index.ball_qpos):
        qpos[:, adr : adr + 4] = local_q[:, k]
    return qpos
