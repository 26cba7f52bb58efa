"""Offscreen video of a replayed motion on the MuJoCo humanoid, with the problem frames marked.

Rendering uses ``mujoco.Renderer``; without a display set ``MUJOCO_GL=egl`` (or ``osmesa``)
before ``mujoco`` is first imported (the ``motion-env replay`` command does this itself). On a
frame where a check fails the humanoid turns red and the failing checks are named in the
corner; a timeline along the bottom shows every problem stretch of the clip.
"""

from __future__ import annotations

from pathlib import Path

import imageio.v2 as imageio
import mujoco
import numpy as np

from motion_env.replay.humanoid import load_model, model_index
from motion_env.replay.kinematic import Measurements

_PROBLEM_RGBA = np.array([0.9, 0.1, 0.1, 1.0])
_BAR = 14  # pixels: height of the timeline


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


def render_video(
    measurements: Measurements,
    report: dict,
    path: str | Path,
    width: int = 640,
    height: int = 360,
) -> Path:
    """Write the replay of `measurements` to `path` (.mp4 via imageio-ffmpeg, or .gif).

    report: the :func:`motion_env.replay.evaluate.report` of the same measurements, whose
    failing frames are marked. The camera follows the pelvis from the front left.
    """
    path = Path(path)
    if path.suffix.lower() not in (".mp4", ".gif"):
        raise ValueError(f"{path}: the video must be an .mp4 or a .gif")
    m = measurements
    model = load_model(m.mass, m.rest_directions)
    index = model_index(model)
    data = mujoco.MjData(model)
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    try:
        renderer = mujoco.Renderer(model, height=height, width=width)
    except Exception as exc:  # mujoco raises FatalError (not exported as a type everywhere)
        raise RuntimeError(
            f"MuJoCo could not open an offscreen OpenGL context ({exc}); set MUJOCO_GL=egl "
            "(or osmesa) in the environment before Python imports mujoco"
        ) from exc

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
    verdict = "plausible" if report["plausible"] else "not plausible: " + ", ".join(report["failed"])

    fps = m.fps
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = (
        imageio.get_writer(path, fps=fps, codec="libx264", quality=7, macro_block_size=8)
        if path.suffix.lower() == ".mp4"
        else imageio.get_writer(path, mode="I", duration=1000.0 / fps, loop=0)
    )
    try:
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
            writer.append_data(frame)
    finally:
        writer.close()
        renderer.close()
    return path
