"""Physical tracking: can the simulated humanoid follow the motion with its joints alone?

PD control drives every ball joint toward the replayed pose, with the joint torques of inverse
dynamics (the floor's share of the forces removed, :func:`kinematic.inverse_dynamics`) as a
feed-forward; nothing pushes or holds the root. The result says how long the humanoid stays up.
It is a rough test (a PD tracker is no learned controller: most real walks fall within seconds)
and is reported next to the plausibility checks, not as one of them.
"""

from __future__ import annotations

import mujoco
import numpy as np

from motion_env.motion.skeleton import JOINT_NAMES
from motion_env.motion.types import Motion
from motion_env.motion.validation import check_positive
from motion_env.replay.humanoid import BALL_JOINTS, DEFAULT_MASS
from motion_env.replay.kinematic import Measurements, inverse_dynamics, measure
from motion_env.replay.mjcf import ModelIndex, load_model, model_index

STIFFNESS = 20.0  # N m/rad per kg of body mass, for the legs and spine
_GAIN_SHARE = {"neck": 0.3, "collar": 0.3, "shoulder": 0.2, "elbow": 0.1}  # of STIFFNESS
DAMPING_RATIO = 0.1  # s: derivative gain / proportional gain
FALL_DROP = 0.4  # m: fallen once the head is this far below where the motion has it


def track(
    motion: Motion,
    mass: float = DEFAULT_MASS,
    measurements: Measurements | None = None,
    stiffness: float = STIFFNESS,
) -> dict:
    """Simulate the humanoid tracking `motion` and report how long it stays up.

    measurements: the motion's :func:`kinematic.measure` result, if already computed.
    Returns a dict: ``stayed_up_s``, ``duration_s``, ``fell`` (bool), ``fell_at_frame`` (or
    None), ``mean_joint_error_cm`` (22 joints, while up), ``root_drift_m`` (horizontal distance of
    the pelvis from the motion's when the run ended), ``message``.
    """
    stiffness = check_positive(stiffness, "stiffness", " of N m/rad per kg")
    m = measure(motion, mass) if measurements is None else measurements
    model = load_model(m.mass, m.rest_directions)
    index = model_index(model)
    dt = 1.0 / m.fps
    qfrc, _ = inverse_dynamics(model, index, m.qpos, m.floor_points, dt)
    n = m.num_frames
    half = np.zeros((max(n - 1, 1), model.nv))  # velocity between frames t and t+1
    for t in range(n - 1):
        mujoco.mj_differentiatePos(model, half[t], dt, m.qpos[t], m.qpos[t + 1])
    # Gains scale with the body mass: legs and spine carry the whole body in stance.
    kp = _stiffness_gains(model, index, stiffness * m.mass)
    errors, fell_at, drift = _simulate(model, index, m.qpos, half, qfrc, kp, dt)
    return _result(errors, fell_at, drift, n, m.fps)


def _stiffness_gains(model: mujoco.MjModel, index: ModelIndex, gain: float) -> np.ndarray:
    """(nv,) proportional gains: `gain` (N m/rad) on the legs and spine, a share of it elsewhere."""
    kp = np.zeros(model.nv)
    for k, j in enumerate(BALL_JOINTS):
        kind = JOINT_NAMES[j].split("_")[-1]
        kp[index.ball_dof[k] : index.ball_dof[k] + 3] = gain * _GAIN_SHARE.get(kind, 1.0)
    return kp


def _simulate(
    model: mujoco.MjModel,
    index: ModelIndex,
    qpos: np.ndarray,
    half: np.ndarray,
    qfrc: np.ndarray,
    kp: np.ndarray,
    dt: float,
) -> tuple[list[np.ndarray], int | None, float]:
    """Step the humanoid from frame 0 of `qpos` (T, nq) under PD control towards each next frame
    (`half`: (T-1, nv) velocities between frames) plus the feed-forward torques `qfrc` (T, nv),
    until it falls or the motion ends. Returns the per-frame joint errors (22,) while up, the frame
    it fell at (None if it did not) and the pelvis's horizontal distance from the motion's then."""
    kd = DAMPING_RATIO * kp
    # The damping half of the PD runs as joint damping, which the implicit integrator handles:
    # explicit damping this stiff blows up across the light, short thorax between two spine joints.
    model.dof_damping[:] = kd
    head = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "head")
    pelvis = int(index.joint_bodies[0])

    data = mujoco.MjData(model)
    data.qpos[:] = qpos[0]
    data.qvel[:] = half[0]
    mujoco.mj_forward(model, data)
    substeps = max(1, round(dt / model.opt.timestep))
    target = np.zeros(model.nq)
    err = np.zeros(model.nv)
    errors = []
    fell_at = None
    ref = mujoco.MjData(model)
    for t in range(len(qpos) - 1):
        for s in range(substeps):
            target[:] = qpos[t]
            mujoco.mj_integratePos(model, target, half[t], (s + 1) / substeps * dt)
            mujoco.mj_differentiatePos(model, err, 1.0, data.qpos, target)
            data.qfrc_applied[:] = kp * err + kd * half[t] + qfrc[t]
            data.qfrc_applied[:6] = 0.0  # no help on the root
            mujoco.mj_step(model, data)
        ref.qpos[:] = qpos[t + 1]
        mujoco.mj_kinematics(model, ref)
        errors.append(
            np.linalg.norm(data.site_xpos[index.joint_sites] - ref.site_xpos[index.joint_sites], axis=1)
        )
        if data.site_xpos[head, 2] < ref.site_xpos[head, 2] - FALL_DROP:
            fell_at = t + 1
            break
    drift = float(np.linalg.norm(data.xpos[pelvis, :2] - ref.xpos[pelvis, :2]))
    return errors, fell_at, drift


def _result(errors: list[np.ndarray], fell_at: int | None, drift: float, n: int, fps: float) -> dict:
    """The dict :func:`track` returns, its message included."""
    frames_up = (fell_at if fell_at is not None else n) / fps
    mean_err = float(100 * np.mean(errors)) if errors else 0.0
    if fell_at is None:
        message = (
            f"the simulated humanoid followed the whole {n / fps:.1f} s with joint torques only "
            f"(mean joint error {mean_err:.1f} cm, pelvis {100 * drift:.0f} cm off at the end)"
        )
    else:
        message = (
            f"the simulated humanoid fell after {frames_up:.1f} s of {n / fps:.1f} s "
            f"(frame {fell_at}) when tracking with joint torques only"
        )
    return {
        "stayed_up_s": float(frames_up),
        "duration_s": float(n / fps),
        "fell": fell_at is not None,
        "fell_at_frame": fell_at,
        "mean_joint_error_cm": mean_err,
        "root_drift_m": drift,
        "message": message,
    }
