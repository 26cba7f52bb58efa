"""What a motion-tracking controller reads: a robot clip's bodies and velocities, from its own model.

mjlab's tracking task (and the trackers built on it: BeyondMimic, wbc-mjlab) reads a clip as the
npz that mjlab's ``csv_to_npz`` writes: joint positions and velocities, and the world pose and
velocity of every body of the robot, frame by frame. :func:`tracking_arrays` computes the same
arrays with MuJoCo from the robot's model, by the same conventions as ``csv_to_npz``:

- velocities are finite differences at the clip's rate: central inside the clip, one-sided at its
  two ends (``torch.gradient``) for the root position and the joints; the root's angular velocity
  from the rotation between the frames before and after (``q[t+1] * conj(q[t-1])``), the first and
  last frames repeating their neighbour's;
- those become MuJoCo's qvel (the free joint's angular velocity in the root's own frame), and each
  body's velocity is that of its origin (not its centre of mass), in world axes
  (``mj_objectVelocity``), as mjlab's ``body_link_lin_vel_w`` and ``body_link_ang_vel_w``;
- body positions and orientations from ``mj_kinematics`` (``xpos``, ``xquat`` in w, x, y, z).

:func:`resample_qpos` changes a clip's rate (linear for positions and joints, normalised linear
for quaternions), as ``csv_to_npz`` does before it writes 50 fps.
"""

from __future__ import annotations

import mujoco
import numpy as np

from motion_env.motion.kinematics import resample
from motion_env.motion.rotations import qfix, qinv, qmul, qnormalize, qrot, quat_to_axis_angle
from motion_env.retarget.robot import Robot, subtree
from motion_env.retarget.smoothing import quaternion_columns

__all__ = ["TRACKING_FPS", "body_names", "resample_qpos", "tracking_arrays"]

TRACKING_FPS = 50.0  # mjlab's tracking task steps at 50 Hz (decimation 4 of a 200 Hz simulation)
_SCALAR = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
_FREE, _BALL = int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL)


def resample_qpos(model: mujoco.MjModel, qpos: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """qpos (T, nq) at `src_fps` -> (T', nq) at `dst_fps`, frame k at time k / dst_fps.

    Positions and joint angles are interpolated linearly; quaternions (free and ball joints) too,
    after putting consecutive ones in one hemisphere, then normalised.
    """
    qpos = np.array(qpos, dtype=np.float64)
    if src_fps == dst_fps:
        return qpos
    columns = quaternion_columns(model)
    for a in columns:
        qpos[:, a : a + 4] = qfix(qpos[:, a : a + 4])
    out = resample(qpos, src_fps, dst_fps)
    for a in columns:
        out[:, a : a + 4] = qnormalize(out[:, a : a + 4])
    return out


def body_names(robot: Robot) -> tuple[str, ...]:
    """The robot's bodies in model order, its root first (every body but the world and the scene's)."""
    return tuple(mujoco.mj_id2name(robot.model, mujoco.mjtObj.mjOBJ_BODY, b) for b in _bodies(robot))


def _bodies(robot: Robot) -> list[int]:
    return subtree(robot.model, [robot.root])


def _angular_velocity(quat: np.ndarray, dt: float) -> np.ndarray:
    """(T, 3) world angular velocity of a rotation sequence (T, 4) w, x, y, z, as mjlab's
    ``_so3_derivative``: the rotation from frame t - 1 to t + 1 over 2 dt, the ends repeated."""
    if quat.shape[0] < 3:
        # Too short for a central difference: one forward difference for every frame.
        step = quat_to_axis_angle(qmul(quat[-1:], qinv(quat[:1]))) / (dt * max(quat.shape[0] - 1, 1))
        return np.repeat(step, quat.shape[0], axis=0)
    omega = quat_to_axis_angle(qmul(quat[2:], qinv(quat[:-2]))) / (2.0 * dt)
    return np.concatenate([omega[:1], omega, omega[-1:]], axis=0)


def _qvel(robot: Robot, qpos: np.ndarray, fps: float) -> np.ndarray:
    """(T, nv) MuJoCo qvel of a clip by finite differences (see the module docstring)."""
    model, dt = robot.model, 1.0 / fps
    edge = 1 if qpos.shape[0] >= 2 else None
    qvel = np.zeros((qpos.shape[0], model.nv))
    for j in range(model.njnt):
        a, v = int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])
        kind = int(model.jnt_type[j])
        if kind in _SCALAR and edge:
            qvel[:, v] = np.gradient(qpos[:, a], dt, edge_order=edge)
        elif kind == _FREE:
            quat = qfix(qnormalize(qpos[:, a + 3 : a + 7]))
            if edge:
                qvel[:, v : v + 3] = np.gradient(qpos[:, a : a + 3], dt, axis=0, edge_order=edge)
            # The free joint's angular velocity is in the body's own frame.
            qvel[:, v + 3 : v + 6] = qrot(qinv(quat), _angular_velocity(quat, dt))
        elif kind == _BALL:
            quat = qfix(qnormalize(qpos[:, a : a + 4]))
            # A ball joint's velocity is in its child's frame: the parent's change does not enter.
            qvel[:, v : v + 3] = qrot(qinv(quat), _angular_velocity(quat, dt))
    return qvel


def tracking_arrays(robot: Robot, qpos: np.ndarray, fps: float) -> dict[str, np.ndarray]:
    """The arrays of mjlab's tracking npz for a clip qpos (T, nq) at `fps` (no resampling here).

    Returns float32 arrays: ``joint_pos``, ``joint_vel`` (T, nj) in the model's joint order (the
    root's free joint left out); ``body_pos_w``, ``body_lin_vel_w``, ``body_ang_vel_w`` (T, nb, 3)
    and ``body_quat_w`` (T, nb, 4, w x y z) of :func:`body_names`' bodies, root first.

    Raises ValueError for a robot with a ball joint (a tracker's joint_pos holds one angle a joint).
    """
    model = robot.model
    joints = [j for j in range(model.njnt) if j != model.body_jntadr[robot.root]]
    ball = [j for j in joints if int(model.jnt_type[j]) not in _SCALAR]
    if ball:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, ball[0])
        raise ValueError(
            f"{robot.name}: joint {name!r} is a ball joint; a tracking clip holds one angle per "
            "joint (hinge and slide joints only)"
        )
    qpos = np.asarray(qpos, dtype=np.float64)
    qvel = _qvel(robot, qpos, fps)
    bodies = _bodies(robot)
    num_frames = qpos.shape[0]
    pos = np.empty((num_frames, len(bodies), 3))
    quat = np.empty((num_frames, len(bodies), 4))
    vel = np.empty((num_frames, len(bodies), 6))  # angular, then linear (MuJoCo's order)
    data = mujoco.MjData(model)
    for t in range(num_frames):
        data.qpos[:], data.qvel[:] = qpos[t], qvel[t]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        pos[t], quat[t] = data.xpos[bodies], data.xquat[bodies]
        for k, b in enumerate(bodies):
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, vel[t, k], 0)
    qadr, vadr = model.jnt_qposadr[joints], model.jnt_dofadr[joints]
    arrays = {
        "joint_pos": qpos[:, qadr],
        "joint_vel": qvel[:, vadr],
        "body_pos_w": pos,
        "body_quat_w": quat,
        "body_lin_vel_w": vel[..., 3:],
        "body_ang_vel_w": vel[..., :3],
    }
    return {key: value.astype(np.float32) for key, value in arrays.items()}
