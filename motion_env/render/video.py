"""Videos: THE video writer (:class:`VideoWriter`, .mp4 or .gif) and the stick-figure video.

- :data:`VIDEO_SUFFIXES`, :func:`check_video_path`, :func:`check_fps`: what a video path and
  rate must be, checked before any work;
- :class:`VideoWriter`: streams RGB frames to an .mp4 (ffmpeg, H.264) or a .gif (Pillow); used
  here and by the MuJoCo humanoid video (:func:`motion_env.render.humanoid.render_humanoid_video`);
- :func:`render_video`: a stick-figure video of a motion
  (:class:`motion_env.render.skeleton.SkeletonRenderer` frame by frame).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from motion_env.motion.types import Motion
from motion_env.motion.validation import check_joints, check_positive
from motion_env.render.camera import Camera, follow_centers, framing_camera
from motion_env.render.drawing import as_obstacles, as_waypoints, check_size, obstacle_extent
from motion_env.render.skeleton import SkeletonRenderer

VIDEO_SUFFIXES = (".mp4", ".gif")
_MAP_EXTENT = 4.0  # metres: videos of routes wider than this get a top-down map


def check_video_path(path: str | Path, width: int | None = None, height: int | None = None) -> Path:
    """`path` as a Path if it names a video type we write, and the size, when given, is positive
    ints (even ones for an .mp4); else ValueError naming the argument."""
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"{path}: unknown video type {path.suffix!r} (expected one of {VIDEO_SUFFIXES})")
    if width is not None and height is not None:
        check_size(width, height, minimum=1)
        if path.suffix.lower() == ".mp4":
            for name, value in (("width", width), ("height", height)):
                if value % 2:
                    raise ValueError(
                        f"an .mp4 needs an even frame size: {name} is {value} (got {width}x{height})"
                    )
    return path


def check_fps(fps: float, name: str = "fps") -> float:
    """`fps` as a float if it is a positive frame rate, else ValueError naming `name`."""
    return check_positive(fps, name)


def frame_indices(num_frames: int, src_fps: float, fps: float) -> np.ndarray:
    """Source frame shown at each output frame when the video is written at `fps`."""
    count = max(1, int(np.floor(num_frames * fps / src_fps + 0.5)))
    return np.minimum((np.arange(count) * src_fps / fps + 1e-6).astype(int), num_frames - 1)


class VideoWriter:
    """Streams RGB frames to an .mp4 (ffmpeg, H.264) or a .gif (Pillow, a palette per frame).

    Call :meth:`append` per frame, then :meth:`close`; on an error, :meth:`abort` removes the
    half-written file. As a context manager (``with VideoWriter(path, fps) as writer:``) it closes
    on success and aborts on an error. The type is the suffix of `path` (:func:`check_video_path`).
    """

    def __init__(self, path: str | Path, fps: float) -> None:
        self.path, self.fps = check_video_path(path), check_fps(fps)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._gif: list = []
        self._mp4 = None
        if self.path.suffix.lower() == ".mp4":
            import imageio.v2 as imageio

            # macro_block_size=2: yuv420p needs even sizes; imageio's default 16 would rescale.
            self._mp4 = imageio.get_writer(
                self.path, format="FFMPEG", fps=self.fps, codec="libx264", quality=7,
                pixelformat="yuv420p", macro_block_size=2,
            )  # fmt: skip

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, error: type[BaseException] | None, *_: object) -> None:
        if error is None:
            self.close()
        else:
            self.abort()

    def append(self, frame: np.ndarray) -> None:
        """Add one (height, width, 3) uint8 RGB frame."""
        if self._mp4 is not None:
            self._mp4.append_data(frame)
        else:
            from PIL import Image

            # Quantising now keeps a long GIF at one byte per pixel in memory. Median cut costs
            # ~25 ms a frame but, unlike the faster octree, leaves no bands in the floor gradient.
            self._gif.append(Image.fromarray(frame).quantize(colors=255, method=Image.Quantize.MEDIANCUT))

    def abort(self) -> None:
        """Stop without leaving a half-written video behind."""
        self._gif.clear()
        if self._mp4 is not None:
            self._mp4.close()
        self.path.unlink(missing_ok=True)

    def close(self) -> None:
        """Finish the file (a .gif is written only now)."""
        if self._mp4 is not None:
            self._mp4.close()
        elif self._gif:
            self._gif[0].save(
                self.path,
                save_all=True,
                append_images=self._gif[1:],
                duration=max(20, int(round(1000 / self.fps))),
                loop=0,
            )


def render_video(
    motion: Motion,
    path: str | Path,
    *,
    fps: float | None = None,
    waypoints: np.ndarray | Sequence | None = None,
    obstacles: np.ndarray | Sequence | None = None,
    highlight_frames: Iterable[int] | None = None,
    title: str | None = None,
    highlight_label: str | None = None,
    camera: str = "follow",
    width: int = 640,
    height: int = 480,
) -> Path:
    """Write a stick-figure video of a motion (.mp4 or .gif, chosen by the suffix of `path`).

    The view is a perspective front-left oblique; the floor grid, the root trail, the waypoints,
    the obstacles, the caption and a frame counter are drawn, and when the route reaches beyond
    the view a top-down map shows all of it.

    Args:
        motion: the clip; `motion.joints` (T, 22, 3).
        path: output file, `.mp4` (H.264) or `.gif`.
        fps: frame rate of the video; default `motion.fps`. At another rate each video frame
            shows the motion frame current at its time.
        waypoints: (K, 2) / (K, 3) (third column: frame index); default `motion.waypoints`.
        obstacles: (N, 3) circles x, z, radius.
        highlight_frames: motion frame indices to draw in red (e.g. physically implausible ones).
        title: caption at the top; default `motion.text`.
        highlight_label: text shown in the corner on highlighted frames.
        camera: "follow" (a camera that tracks the smoothed pelvis) or "fixed" (one view that
            frames the whole route).
        width, height: frame size in pixels (even numbers for .mp4).

    Returns:
        The path written.

    Raises:
        ValueError: before anything is written, naming the argument: joints of a wrong shape or
            with NaN or infinite values (the frames), fps not > 0, width or height not an int of
            at least 64 pixels or odd for an .mp4, bad waypoints, obstacles or highlight frames.
    """
    if not isinstance(motion, Motion):
        raise TypeError(f"render_video expects a motion_env.Motion, got {type(motion).__name__}")
    check_size(width, height)
    path = check_video_path(path, width, height)
    if camera not in ("follow", "fixed"):
        raise ValueError(f"camera must be 'follow' or 'fixed', got {camera!r}")
    joints = check_joints(motion.joints, "motion.joints")  # it may have changed since it was made
    source_fps = check_fps(motion.fps, "motion.fps")
    fps = check_fps(fps) if fps is not None else source_fps
    wps = as_waypoints(motion.waypoints if waypoints is None else waypoints)
    obs = as_obstacles(obstacles)
    title = motion.text if title is None else title
    root_xz = joints[:, 0, [0, 2]]
    indices = frame_indices(motion.num_frames, motion.fps, fps)
    flagged = _flagged(highlight_frames, indices, motion.num_frames)
    cam, centers, inset, bounds = _view(camera, joints, wps, obs, motion.fps, width / height)
    renderer = SkeletonRenderer(width, height, cam)
    # What every frame shows alike; the loop adds the pose, the view's centre, the trail so far,
    # the frame number and whether it is highlighted.
    scene = dict(
        path=root_xz, waypoints=wps, obstacles=obs, fps=motion.fps, title=title, flag=highlight_label,
        inset=inset, inset_bounds=bounds,
    )  # fmt: skip
    with VideoWriter(path, fps) as writer:
        for src, flag in zip(indices, flagged):
            frame = renderer.draw(
                joints[src],
                center=centers[src],
                trail=root_xz[: src + 1],
                frame=int(src),
                label=f"frame {src} (0-{motion.num_frames - 1})   {src / motion.fps:5.2f} s",
                highlight=flag,
                **scene,
            )
            writer.append(frame)
    return path


def _flagged(highlight_frames: Iterable[int] | None, indices: np.ndarray, num_frames: int) -> list[bool]:
    """Whether each output frame, showing source frame ``indices[i]``, is drawn in red
    (ValueError for a highlight frame outside the motion's `num_frames`)."""
    highlighted = np.zeros(num_frames + 1, dtype=bool)
    for f in highlight_frames or ():
        if not 0 <= int(f) < num_frames:
            raise ValueError(f"highlight frame {f} is outside the motion's {num_frames} frames")
        highlighted[int(f)] = True
    # An output frame stands for every source frame until the next one: flag it if any is.
    stops = [*indices[1:], num_frames]
    return [bool(highlighted[src : max(stop, src + 1)].any()) for src, stop in zip(indices, stops)]


def _view(
    camera: str,
    joints: np.ndarray,
    wps: np.ndarray | None,
    obs: np.ndarray | None,
    fps: float,
    aspect: float,
) -> tuple[Camera, np.ndarray, bool, np.ndarray]:
    """Where the video looks: ``(camera, centres (T, 2), inset, bounds)``.

    "fixed": the one camera that frames the whole body motion and the scene; "follow": the
    default camera on the smoothed pelvis, with a top-down map (`inset`) when the scene is wider
    than the view. `bounds` is the scene's floor extent (x min, x max, z min, z max) for that map.
    """
    root_xz = joints[:, 0, [0, 2]]
    scene = [root_xz]
    if wps is not None:
        scene.append(wps[:, :2])
    if obs is not None:
        scene.append(obstacle_extent(obs))
    scene_xz = np.concatenate(scene)
    bounds = np.array(
        [scene_xz[:, 0].min(), scene_xz[:, 0].max(), scene_xz[:, 1].min(), scene_xz[:, 1].max()]
    )
    if camera == "fixed":
        body = joints.reshape(-1, 3)
        floor = np.stack([scene_xz[:, 0], np.zeros(len(scene_xz)), scene_xz[:, 1]], -1)
        cam, fixed_center = framing_camera(np.concatenate([body, floor]), Camera(), aspect)
        return cam, np.repeat(fixed_center[None], len(joints), 0), False, bounds
    # The map is only worth its corner when the route does not fit in the follow view.
    inset = bool((bounds[1::2] - bounds[::2]).max() > _MAP_EXTENT)
    return Camera(), follow_centers(root_xz, fps), inset, bounds
