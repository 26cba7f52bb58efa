"""Every picture of a motion; what is where:

- :mod:`.frames`: :func:`render_frame`, one stick-figure pose as an RGB array (the envs' frames);
- :mod:`.video`: THE video writer (:class:`~motion_env.render.video.VideoWriter`, .mp4 / .gif,
  :data:`VIDEO_SUFFIXES`) and :func:`render_video`, a stick-figure video of a motion;
- :mod:`.plot`: :func:`plot_path`, a top-down PNG of root paths, waypoints and obstacles;
- :mod:`.skeleton`: :class:`SkeletonRenderer`, the stick-figure renderer behind frames and videos;
  :mod:`.camera` its :class:`Camera`, :mod:`.inset` the top-down map in a frame's corner,
  :mod:`.drawing` the colours and input checks shared by all stick-figure pictures;
- :mod:`.humanoid`: the MuJoCo replay humanoid: the env's ``render_style="humanoid"`` frames
  (``HumanoidView``) and the replay video (``render_humanoid_video``). It imports mujoco, so it is
  loaded only when one of these two names is first used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from motion_env.render.camera import Camera
from motion_env.render.frames import render_frame
from motion_env.render.plot import plot_path
from motion_env.render.skeleton import SkeletonRenderer
from motion_env.render.video import VIDEO_SUFFIXES, render_video

if TYPE_CHECKING:
    from motion_env.render.humanoid import HumanoidView, render_humanoid_video

__all__ = [
    "VIDEO_SUFFIXES",
    "Camera",
    "HumanoidView",
    "SkeletonRenderer",
    "plot_path",
    "render_frame",
    "render_humanoid_video",
    "render_video",
]

_LAZY = {"HumanoidView": "motion_env.render.humanoid", "render_humanoid_video": "motion_env.render.humanoid"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'motion_env.render' has no attribute {name!r}")
