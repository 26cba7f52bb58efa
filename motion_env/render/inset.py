"""The top-down map drawn in the top-right corner of a stick-figure frame.

It is rotated so that "up" on the map is the 3-D camera's view direction, and shows the route,
the trail walked so far, the waypoints, the target, the obstacles and the character's heading.
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from motion_env.motion.kinematics import heading_from_joints
from motion_env.render.drawing import (
    MAX_LABELLED_WAYPOINTS,
    OBSTACLE_COLOR,
    SPINE_COLOR,
    TARGET_COLOR,
    TRAIL_COLOR,
    WAYPOINT_COLOR,
    floor_ring,
    hex_rgb,
)


class Inset:
    """Top-down map in the top-right corner, rotated so that "up" is the camera's view direction."""

    def __init__(self, figure: Figure, basis: np.ndarray, aspect: float, font: float) -> None:
        height = 0.30
        width = height / aspect
        self.ax = figure.add_axes((1.0 - width - 0.015, 1.0 - height - 0.015 - 0.06, width, height))
        self.ax.set_xticks([])
        self.ax.set_yticks([])
        self.ax.set_facecolor((1, 1, 1, 0.85))
        for spine in self.ax.spines.values():
            spine.set_edgecolor("#868e96")
        # Map axes: the camera's horizontal right and forward directions (a view from above).
        right = basis[0, [0, 2]] / np.linalg.norm(basis[0, [0, 2]])
        forward = basis[2, [0, 2]] / np.linalg.norm(basis[2, [0, 2]])
        self._rot = np.stack([right, forward], 1)  # (2, 2): xz @ rot -> map coordinates
        self._obstacles = PolyCollection([], facecolor=(*hex_rgb(OBSTACLE_COLOR), 0.6), edgecolor="none")
        self.ax.add_collection(self._obstacles)
        (self._path,) = self.ax.plot([], [], "--", color=TRAIL_COLOR, lw=0.8, alpha=0.6)
        (self._trail,) = self.ax.plot([], [], "-", color=TRAIL_COLOR, lw=1.2)
        (self._waypoints,) = self.ax.plot([], [], "o", color=WAYPOINT_COLOR, ms=3.5)
        (self._dense,) = self.ax.plot([], [], ":", color=WAYPOINT_COLOR, lw=1.2)
        (self._target,) = self.ax.plot([], [], "*", color=TARGET_COLOR, ms=9)
        (self._heading,) = self.ax.plot([], [], "-", color=SPINE_COLOR, lw=1.5)
        (self._me,) = self.ax.plot([], [], "o", color=SPINE_COLOR, ms=4)
        self.dynamic = [*self.ax.lines, *self.ax.collections]

    def _map(self, xz: np.ndarray | None) -> np.ndarray:
        return np.empty((0, 2)) if xz is None else xz @ self._rot

    def update(
        self,
        visible: bool,
        joints: np.ndarray,
        scene: list[np.ndarray],
        trail: np.ndarray | None,
        path: np.ndarray | None,
        wps: np.ndarray | None,
        target: np.ndarray | None,
        obs: np.ndarray | None,
        bounds: np.ndarray | None,
    ) -> None:
        self.ax.set_visible(visible)
        if not visible:
            return
        pos = joints[0, [0, 2]]
        theta = float(heading_from_joints(joints[None].astype(np.float32))[0])
        facing = np.array([math.sin(theta), math.cos(theta)])
        self._trail.set_data(*self._map(trail).T)
        self._path.set_data(*self._map(path).T)
        dense = wps is not None and len(wps) > MAX_LABELLED_WAYPOINTS
        self._waypoints.set_data(*self._map(None if wps is None or dense else wps[:, :2]).T)
        self._dense.set_data(*self._map(wps[:, :2] if dense else None).T)
        self._target.set_data(*self._map(None if target is None else target[None]).T)
        self._me.set_data(*self._map(pos[None]).T)
        if bounds is None:
            pts = np.concatenate([pos[None], *scene])
            bounds = np.array([pts[:, 0].min(), pts[:, 0].max(), pts[:, 1].min(), pts[:, 1].max()])
        corners = np.array([[bounds[a], bounds[b]] for a in (0, 1) for b in (2, 3)]) @ self._rot
        lo, hi = corners.min(0), corners.max(0)
        half = max((hi - lo).max() / 2 + 0.5, 1.5)
        mid = (lo + hi) / 2
        self.ax.set_xlim(mid[0] - half, mid[0] + half)
        self.ax.set_ylim(mid[1] - half, mid[1] + half)
        arrow = self._map(np.stack([pos, pos + facing * half * 0.18]))
        self._heading.set_data(*arrow.T)
        circles = [] if obs is None else [floor_ring(o[:2], o[2])[:, [0, 2]] @ self._rot for o in obs]
        self._obstacles.set_verts(circles)
