"""Top-down PNG of one or more root paths with their waypoints and obstacles: :func:`plot_path`."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle

from motion_env.motion.kinematics import heading_from_joints
from motion_env.motion.types import Motion
from motion_env.motion.validation import check_joints
from motion_env.render.drawing import (
    MAX_LABELLED_WAYPOINTS,
    OBSTACLE_COLOR,
    WAYPOINT_COLOR,
    as_obstacles,
    as_waypoints,
    hex_rgb,
    obstacle_extent,
    waypoint_time,
)
from motion_env.render.video import check_fps

PALETTE = ["#1f6fd1", "#f08c1a", "#2f9e44", "#9c36b5", "#0c8599", "#e8590c", "#5c940d", "#c2255c"]
"""Colours of the paths, in order."""


def plot_path(
    motion_or_motions: Motion | Sequence[Motion],
    path: str | Path,
    *,
    waypoints: np.ndarray | Sequence | None = None,
    obstacles: np.ndarray | Sequence | None = None,
    title: str | None = None,
) -> Path:
    """Top-down PNG of the root path(s): the floor seen from above, 1 m grid, equal aspect.

    +X points to the left so that the picture is a true view from above (a character walking up
    the page that turns to its left turns to the left of the page). Each path gets a start dot,
    an end square and a facing arrow every second; waypoints are numbered rings (timed ones say
    their frame and its time in seconds, "f40 (2.0 s)", and a dotted line joins each to where the
    pelvis was at that frame).

    Args:
        motion_or_motions: one :class:`Motion` or several (drawn in different colours).
        path: output `.png`.
        waypoints: (K, 2) / (K, 3) (third column: frame index); default: the first motion's.
        obstacles: (N, 3) circles x, z, radius.
        title: default: the caption of a single motion.

    Returns:
        The path written.

    Raises:
        ValueError: naming the argument: a path that is not a .png, no motion, joints with NaN
            or infinite values (the frames), a rate not > 0, bad waypoints or obstacles.
        TypeError: something other than a :class:`Motion` among the motions.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: plot_path writes a .png, got suffix {path.suffix!r}")
    motions = _checked_motions(motion_or_motions)
    if waypoints is None:
        waypoints = next((m.waypoints for m in motions if m.waypoints is not None), None)
    wps, obs = as_waypoints(waypoints), as_obstacles(obstacles)
    if title is None and len(motions) == 1:
        title = motions[0].text

    fig = Figure(figsize=(7.0, 7.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    extent = []
    for n, m in enumerate(motions):
        name = m.text or Path(m.meta.get("source", "")).name or f"motion {n + 1}"
        name = "root path" if len(motions) == 1 else name if len(name) <= 50 else name[:49] + "\u2026"
        extent.append(_draw_motion(ax, m, PALETTE[n % len(PALETTE)], name, wps))
    if wps is not None:
        extent.append(wps[:, :2])
        _draw_waypoints(ax, wps, motions[0].fps)
    if obs is not None:
        for x, z, r in obs:
            ax.add_patch(Circle((x, z), r, fc=(*hex_rgb(OBSTACLE_COLOR), 0.5), ec=OBSTACLE_COLOR))
        extent.append(obstacle_extent(obs))
    _frame(ax, np.concatenate(extent))
    if title:
        ax.set_title("\n".join(textwrap.wrap(title, 70)), fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path


def _checked_motions(motion_or_motions: Motion | Sequence[Motion]) -> list[Motion]:
    """The motions to plot as a list, each checked (ValueError or TypeError naming it)."""
    motions = [motion_or_motions] if isinstance(motion_or_motions, Motion) else list(motion_or_motions)
    if not motions:
        raise ValueError("plot_path needs at least one motion")
    for n, m in enumerate(motions):
        name = "motion_or_motions" + ("" if isinstance(motion_or_motions, Motion) else f"[{n}]")
        if not isinstance(m, Motion):
            raise TypeError(f"{name} must be a motion_env.Motion, got {type(m).__name__}")
        check_joints(m.joints, f"{name}.joints")  # it may have changed since it was made
        check_fps(m.fps, f"{name}.fps")
    return motions


def _draw_motion(ax: Axes, m: Motion, color: str, name: str, wps: np.ndarray | None) -> np.ndarray:
    """One motion's root path with its start dot, end square and a facing arrow every second, and
    dotted lines from its timed waypoints to where its pelvis was then. Returns the path (T, 2)."""
    root = m.joints[:, 0, [0, 2]].astype(np.float64)
    ax.plot(root[:, 0], root[:, 1], "-", color=color, lw=2, label=name)
    ax.plot(*root[0], "o", color=color, ms=8, mec="white", zorder=5)
    ax.plot(*root[-1], "s", color=color, ms=8, mec="white", zorder=5)
    step = max(1, int(round(m.fps)))
    idx = np.arange(0, m.num_frames, step)
    theta = heading_from_joints(m.joints)[idx]
    ax.quiver(
        root[idx, 0], root[idx, 1], np.sin(theta), np.cos(theta), color=color, angles="xy",
        scale_units="inches", scale=3.0, width=0.005, zorder=4,
    )  # fmt: skip
    if wps is not None and len(wps) <= MAX_LABELLED_WAYPOINTS:
        for x, z, t in wps:
            if not np.isnan(t) and 0 <= t < m.num_frames:
                at = root[int(round(t))]
                ax.plot([x, at[0]], [z, at[1]], ":", color=color, lw=1.2)
    return root


def _draw_waypoints(ax: Axes, wps: np.ndarray, fps: float) -> None:
    """Waypoints (K, 3) as numbered rings, timed ones labelled with their frame and time at `fps`;
    too many for labels, as one dotted line."""
    if len(wps) > MAX_LABELLED_WAYPOINTS:
        ax.plot(wps[:, 0], wps[:, 1], ":", color=WAYPOINT_COLOR, lw=2, label="waypoints")
        return
    ax.plot(wps[:, 0], wps[:, 1], "o", color="white", mec=WAYPOINT_COLOR, mew=2, ms=13, zorder=6,
            label="waypoints (dotted: pelvis at that time)" if not np.isnan(wps[:, 2]).all()
            else "waypoints")  # fmt: skip
    for k, (x, z, t) in enumerate(wps):
        ax.annotate(str(k + 1), (x, z), ha="center", va="center", fontsize=7, color=WAYPOINT_COLOR,
                    fontweight="bold", zorder=7)  # fmt: skip
        if not np.isnan(t):
            ax.annotate(waypoint_time(t, fps), (x, z), xytext=(9, 9),
                        textcoords="offset points", fontsize=8, color=WAYPOINT_COLOR)  # fmt: skip


def _frame(ax: Axes, pts: np.ndarray) -> None:
    """Square limits around every drawn point (N, 2) seen from above, the grid, the axis labels and
    the legend."""
    lo, hi = pts.min(0), pts.max(0)
    half = max((hi - lo).max() / 2 * 1.1, 1.0)
    mid = (lo + hi) / 2
    ax.set_xlim(mid[0] + half, mid[0] - half)  # +X to the left: seen from above
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)  \u2190 +x")
    ax.set_ylabel("z (m)")
    ax.grid(True, color="#dee2e6")
    ax.set_axisbelow(True)
    # Marker meanings, drawn once in grey rather than once per motion.
    ax.plot([], [], "o", color="#495057", ms=7, label="start")
    ax.plot([], [], "s", color="#495057", ms=7, label="end")
    ax.plot([], [], marker=r"$\rightarrow$", ls="none", color="#495057", ms=12, label="facing, every 1 s")
    ax.legend(loc="best", fontsize=8, framealpha=0.85)
