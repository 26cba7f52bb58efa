"""Pictures: stick-figure frames and videos, top-down path plots, MuJoCo humanoid videos."""

from motion_env.render.stick import (
    VIDEO_SUFFIXES,
    Camera,
    SkeletonRenderer,
    plot_path,
    render_frame,
    render_video,
)

__all__ = ["VIDEO_SUFFIXES", "Camera", "SkeletonRenderer", "plot_path", "render_frame", "render_video"]
