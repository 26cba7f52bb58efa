"""A video of a robot clip: MuJoCo's offscreen renderer, frames through the one
:class:`motion_env.render.video.VideoWriter` (.mp4 or .gif).

Offscreen OpenGL on a machine without a display needs ``MUJOCO_GL=egl`` (or ``osmesa``) before
MuJoCo is first imported; this module sets "egl" when it is unset, which helps only when mujoco
has not been imported yet.
"""

from __future__ import annotations

import copy
import os
from contextlib import closing

os.environ.setdefault("MUJOCO_GL", "egl")

from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from motion_env.render.video import VideoWriter, check_fps, check_video_path, frame_indices  # noqa: E402
from motion_env.retarget.result import RobotMotion  # noqa: E402
from motion_env.retarget.robot import Robot, load_robot  # noqa: E402

__all__ = ["render_robot_video"]


def _scene(robot: Robot) -> mujoco.MjModel:
    """A copy of the robot's model, with a floor and a light added when the MJCF has none."""
    model = robot.model
    if (model.geom_type[model.geom_bodyid == 0] == mujoco.mjtGeom.mjGEOM_PLANE).any():
        return copy.copy(model)  # the renderer's size is set on it
    spec = mujoco.MjSpec.from_file(str(robot.table.model))
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], rgba=[0.3, 0.35, 0.4, 1])
    spec.worldbody.add_light(pos=[0, 0, 4], dir=[0, 0, -1])
    return spec.compile()


def render_robot_video(
    motion: RobotMotion,
    path: str | Path,
    *,
    fps: float | None = None,
    width: int = 640,
    height: int = 480,
) -> Path:
    """Write a video of `motion` on its robot to `path` (.mp4 or .gif); returns the path.

    The camera follows the root from the front left at a fixed height. fps: the video's rate
    (default: the clip's, at most 30; frames are dropped to match).

    Raises:
        ValueError: a path that is not .mp4 or .gif, or a bad size.
        RuntimeError: no offscreen OpenGL context (set ``MUJOCO_GL=egl`` or ``osmesa``).
    """
    path = check_video_path(path, width, height)
    fps = check_fps(fps if fps is not None else min(motion.fps, 30.0), "fps")
    robot = load_robot(motion.robot)
    model = _scene(robot)
    if model.nq != motion.qpos.shape[1]:
        raise ValueError(
            f"{motion.robot}: the model has nq {model.nq}, the clip {motion.qpos.shape[1]} columns"
        )
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # mujoco raises FatalError, not exported as a type everywhere
        raise RuntimeError(
            f"MuJoCo could not open an offscreen OpenGL context ({exc}); set MUJOCO_GL=egl or osmesa "
            "before Python imports mujoco"
        ) from exc
    data = mujoco.MjData(model)
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance, camera.azimuth, camera.elevation = 3.0, 150.0, -15.0
    root = motion.root_pos
    # Follow a moving average of the root, so that the camera does not sway with each step.
    k = max(1, round(0.5 * motion.fps))
    padded = np.pad(root[:, :2], ((k // 2, k - 1 - k // 2), (0, 0)), mode="edge")
    follow = np.stack([np.convolve(padded[:, i], np.ones(k) / k, "valid") for i in range(2)], axis=1)
    height_m = float(np.median(root[:, 2]))
    with closing(renderer), VideoWriter(path, fps) as writer:
        for t in frame_indices(motion.num_frames, motion.fps, fps):
            data.qpos[:] = motion.qpos[t]
            mujoco.mj_forward(model, data)
            camera.lookat[:] = (follow[t, 0], follow[t, 1], 0.7 * height_m)
            renderer.update_scene(data, camera)
            writer.append(renderer.render().copy())
    return path
