"""Pictures of the MuJoCo replay humanoid (:mod:`motion_env.replay`).

- :class:`HumanoidView`: the env's frames for ``render_style="humanoid"``: each pose is fitted to
  the humanoid's joint angles (:func:`motion_env.replay.fit.fit_qpos`) and drawn offscreen with
  the trail, the waypoints, the target and the obstacles added to the scene as extra geoms;
- :func:`render_humanoid_video`: the video of a replay (``motion-env replay --video``): on a
  frame where a check fails the humanoid turns red and the failing checks are named in the
  corner; a timeline along the bottom shows every problem stretch of the clip. Frames go through
  the one :class:`motion_env.render.video.VideoWriter`.

Rendering uses ``mujoco.Renderer``: offscreen OpenGL needs ``MUJOCO_GL=egl`` (or ``osmesa``) on a
machine without a display. This module sets it to "egl" when unset, before it imports mujoco;
that only helps when mujoco has not been imported yet.
"""

from __future__ import annotations

import os
from contextlib import closing

os.environ.setdefault("MUJOCO_GL", "egl")

from pathlib import Path  # noqa: E402

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from motion_env.render.video import VideoWriter, check_video_path  # noqa: E402
from motion_env.replay.fit import fit_qpos  # noqa: E402
from motion_env.replay.kinematic import Measurements  # noqa: E402
from motion_env.replay.mjcf import load_model, model_index  # noqa: E402

_PROBLEM_RGBA = np.array([0.9, 0.1, 0.1, 1.0])
_BAR = 14  # pixels: height of the timeline
_TRAIL_RGBA = np.array([0.36, 0.49, 0.98, 1.0], np.float32)
_WAYPOINT_RGBA = np.array([0.61, 0.21, 0.71, 1.0], np.float32)
_TARGET_RGBA = np.array([0.84, 0.2, 0.42, 1.0], np.float32)
_OBSTACLE_RGBA = np.array([0.53, 0.56, 0.59, 0.9], np.float32)
_OBSTACLE_HEIGHT = 0.8
_TRAIL_EVERY = 4  # draw every 4th trail point (a dot per 0.2 s)


def _offscreen_renderer(model: mujoco.MjModel, width: int, height: int, hint: str) -> mujoco.Renderer:
    """A ``mujoco.Renderer`` of `model` at this size, or RuntimeError saying what to set."""
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    try:
        return mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # mujoco raises FatalError, not exported as a type everywhere
        raise RuntimeError(
            f"MuJoCo could not open an offscreen OpenGL context ({exc}); set MUJOCO_GL=egl or osmesa "
            f"before Python imports mujoco{hint}"
        ) from exc


def _text_image(text: str, height: int, color: str) -> np.ndarray:
    """Render one line of text to an RGBA uint8 array (matplotlib's Agg backend, no display)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dpi = 100
    fig = Figure(figsize=(8, height / dpi), dpi=dpi)
    fig.patch.set_alpha(0.0)
    fig.text(0.005, 0.5, text, color=color, fontsize=height * 0.45, va="center", ha="left", weight="bold")
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba()).copy()


def _blit(frame: np.ndarray, rgba: np.ndarray, top: int, left: int) -> None:
    h = min(rgba.shape[0], frame.shape[0] - top)
    w = min(rgba.shape[1], frame.shape[1] - left)
    alpha = rgba[:h, :w, 3:4] / 255.0
    region = frame[top : top + h, left : left + w]
    region[:] = (alpha * rgba[:h, :w, :3] + (1 - alpha) * region).astype(np.uint8)


def problem_frames(report: dict, num_frames: int) -> list[list[str]]:
    """For every frame, the names of the checks of `report` that fail there."""
    out: list[list[str]] = [[] for _ in range(num_frames)]
    for name, check in report["checks"].items():
        for a, b in check["frames"]:
            for t in range(max(a, 0), min(b, num_frames - 1) + 1):
                out[t].append(name)
    return out


def render_humanoid_video(
    measurements: Measurements,
    report: dict,
    path: str | Path,
    width: int = 640,
    height: int = 360,
) -> Path:
    """Write the replay of `measurements` to `path` (.mp4 or .gif, :class:`VideoWriter`).

    report: the :func:`motion_env.replay.plausibility.report` (or :func:`~motion_env.replay.evaluate`
    result) of the same measurements, whose failing frames are marked. The camera follows the
    pelvis from the front left.
    """
    path = check_video_path(path, width, height)
    m = measurements
    model = load_model(m.mass, m.rest_directions)
    index = model_index(model)
    data = mujoco.MjData(model)
    renderer = _offscreen_renderer(model, width, height, "")

    problems = problem_frames(report, m.num_frames)
    rgba = model.geom_rgba.copy()
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.distance, camera.azimuth, camera.elevation = 4.0, 150.0, -12.0
    pelvis = m.qpos[:, :3]
    # A camera that follows the pelvis smoothly over the ground, at a fixed height.
    k = max(1, round(0.5 * m.fps))
    kernel = np.ones(k) / k
    padded = np.pad(pelvis[:, :2], ((k // 2, k - 1 - k // 2), (0, 0)), mode="edge")
    follow = np.stack([np.convolve(padded[:, i], kernel, "valid") for i in range(2)], axis=1)
    timeline = np.zeros((_BAR, width, 3), dtype=np.uint8)
    timeline[:] = (60, 60, 60)
    for t, names in enumerate(problems):
        if names:
            a = int(t / m.num_frames * width)
            b = max(a + 1, int((t + 1) / m.num_frames * width))
            timeline[:, a:b] = (220, 30, 30)
    labels: dict[str, np.ndarray] = {}
    if not report.get("judged", True):
        verdict = "too short to judge"
    else:
        verdict = "plausible" if report["plausible"] else "not plausible: " + ", ".join(report["failed"])

    fps = m.fps
    with closing(renderer), VideoWriter(path, fps) as writer:
        for t in range(m.num_frames):
            data.qpos[:] = m.qpos[t]
            mujoco.mj_forward(model, data)
            model.geom_rgba[:] = rgba
            if problems[t]:
                model.geom_rgba[index.body_geoms] = _PROBLEM_RGBA
            camera.lookat[:] = (follow[t, 0], follow[t, 1], 0.9)
            renderer.update_scene(data, camera)
            frame = renderer.render().copy()
            frame[-_BAR:] = timeline
            cursor = min(width - 2, int(t / max(m.num_frames - 1, 1) * (width - 2)))
            frame[-_BAR:, cursor : cursor + 2] = 255
            text = f"frame {t}  {t / fps:5.2f} s   " + (
                "PROBLEM: " + ", ".join(problems[t]) if problems[t] else verdict
            )
            if text not in labels:
                labels[text] = _text_image(text, 26, "#ff5050" if problems[t] else "white")
            _blit(frame, labels[text], 4, 6)
            writer.append(frame)
    return path


class HumanoidView:
    """An offscreen MuJoCo renderer of the replay humanoid, reused across frames.

    Raises:
        RuntimeError: MuJoCo cannot open an offscreen OpenGL context here.
    """

    def __init__(self, width: int, height: int) -> None:
        self.model = load_model()
        self.index = model_index(self.model)
        self.data = mujoco.MjData(self.model)
        self.renderer = _offscreen_renderer(self.model, width, height, ", or use render_style='stick'")
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance, self.camera.azimuth, self.camera.elevation = 5.0, 150.0, -18.0

    def draw(
        self,
        joints: np.ndarray,
        trail: np.ndarray | None = None,
        target: np.ndarray | None = None,
        waypoints: np.ndarray | None = None,
        obstacles: np.ndarray | None = None,
    ) -> np.ndarray:
        """RGB image (height, width, 3) uint8 of one pose (22, 3) and the scene around it.

        trail: (N, 2) x, z walked so far; target: (2,); waypoints: (K, 2+); obstacles: (M, 3) circles.
        """
        qpos = fit_qpos(np.asarray(joints, np.float64)[None], self.model, self.index)[0]
        self.data.qpos[:] = qpos
        mujoco.mj_forward(self.model, self.data)
        pelvis = np.asarray(joints, np.float64)[0]
        # MuJoCo's frame: x = motion z (forward), y = motion x (left), z = up.
        self.camera.lookat[:] = (pelvis[2], pelvis[0], 0.9)
        self.renderer.update_scene(self.data, self.camera)
        scene = self.renderer.scene
        eye = np.eye(3).reshape(-1)

        def add(
            kind: int, size: tuple[float, float, float], xz: np.ndarray, z: float, rgba: np.ndarray
        ) -> None:
            if scene.ngeom >= scene.maxgeom:
                return
            pos = np.array([xz[1], xz[0], z], np.float64)
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], kind, np.array(size, np.float64), pos, eye, rgba)
            scene.ngeom += 1

        sphere, cylinder = mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER
        if trail is not None and len(trail):
            for point in np.asarray(trail)[::_TRAIL_EVERY]:
                add(sphere, (0.03, 0.03, 0.03), point, 0.02, _TRAIL_RGBA)
        if waypoints is not None:
            for point in np.asarray(waypoints)[:, :2]:
                add(cylinder, (0.15, 0.15, 0.01), point, 0.01, _WAYPOINT_RGBA)
        if target is not None:
            add(cylinder, (0.06, 0.06, 0.4), np.asarray(target), 0.4, _TARGET_RGBA)
        if obstacles is not None:
            for x, z, r in np.asarray(obstacles):
                add(
                    cylinder,
                    (r, r, 0.5 * _OBSTACLE_HEIGHT),
                    np.array([x, z]),
                    0.5 * _OBSTACLE_HEIGHT,
                    _OBSTACLE_RGBA,
                )
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()
