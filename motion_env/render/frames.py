"""One pose as an RGB image, for Gymnasium's ``render_mode="rgb_array"``: :func:`render_frame`.

It keeps a :class:`motion_env.render.skeleton.SkeletonRenderer` per image size and camera, so that
an env's frames reuse one matplotlib figure.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from motion_env.render.camera import Camera
from motion_env.render.drawing import as_xz, check_size
from motion_env.render.skeleton import SkeletonRenderer

_RENDERERS: dict[tuple[int, int, Camera], SkeletonRenderer] = {}


def render_frame(
    joints: np.ndarray,
    *,
    path: np.ndarray | None = None,
    target: np.ndarray | Sequence[float] | None = None,
    waypoints: np.ndarray | None = None,
    obstacles: np.ndarray | None = None,
    center: np.ndarray | Sequence[float] | None = None,
    title: str | None = None,
    label: str | None = None,
    highlight: bool = False,
    inset: bool | None = None,
    width: int = 640,
    height: int = 480,
    camera: Camera | None = None,
) -> np.ndarray:
    """Draw one pose as an RGB image (for Gymnasium's ``render_mode="rgb_array"``).

    Args:
        joints: (22, 3) world joint positions in metres.
        path: (N, 2) x, z or (N, 3) root path x, z, heading walked so far (drawn on the floor).
        target: (2,) x, z of the current goal.
        waypoints: (K, 2) / (K, 3) waypoints (third column: frame index).
        obstacles: (N, 3) circles x, z, radius.
        center: (2,) x, z the camera looks at; default: the pelvis.
        title, label: caption at the top, small text at the bottom-left.
        highlight: draw the skeleton red with a red border.
        inset: top-down map in a corner; None = when path, target, waypoints or obstacles are
            given.
        width, height: image size in pixels.
        camera: a :class:`Camera`; default: a front-left oblique view from 4.8 m.

    Returns:
        (height, width, 3) uint8 RGB image.

    Raises:
        ValueError: naming the argument: joints not (22, 3) or with NaN or infinite values,
            points of `path`, `target`, `waypoints`, `obstacles` or `center` that are not finite,
            width or height not an int of at least 64 pixels.
    """
    width, height = check_size(width, height)
    if camera is not None and not isinstance(camera, Camera):
        raise TypeError(f"camera must be a motion_env.render.Camera, got {type(camera).__name__}")
    key = (width, height, camera or Camera())
    renderer = _RENDERERS.get(key)
    if renderer is None:
        if len(_RENDERERS) >= 8:  # a figure per size is a few MB: keep only recent sizes
            del _RENDERERS[next(iter(_RENDERERS))]
        renderer = _RENDERERS[key] = SkeletonRenderer(key[0], key[1], key[2])
    return renderer.draw(
        joints,
        center=center,
        trail=as_xz(path, "path"),  # the renderer calls it the trail: check it under its name here
        waypoints=waypoints,
        target=target,
        obstacles=obstacles,
        title=title,
        label=label,
        highlight=highlight,
        inset=inset,
    )
