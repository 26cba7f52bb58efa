"""The stick-figure renderer: :class:`SkeletonRenderer` draws 22-joint poses into RGB arrays.

The 3-D view is our own perspective projection (:class:`motion_env.render.camera.Camera`) drawn
with plain 2-D matplotlib artists on one reused Agg figure: each frame only updates line data and
redraws the moving artists over a cached background, which is many times faster than rebuilding
matplotlib's 3-D axes (about 7 ms of CPU for a 640x480 frame). The floor grid, the trail, the
waypoints, the target and the obstacles are drawn around the figure; the top-down map in the
corner is :class:`motion_env.render.inset.Inset`.

World conventions (see :mod:`motion_env.motion.skeleton`): metres, Y up, floor at y = 0, the
character faces +Z at heading 0 and its left is +X.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from motion_env.motion.skeleton import CHAINS
from motion_env.render.camera import Camera
from motion_env.render.drawing import (
    HIGHLIGHT_COLOR,
    LEFT_COLOR,
    MAX_LABELLED_WAYPOINTS,
    OBSTACLE_COLOR,
    PASSED_COLOR,
    RIGHT_COLOR,
    SPINE_COLOR,
    TARGET_COLOR,
    TRAIL_COLOR,
    WAYPOINT_COLOR,
    as_joints,
    as_obstacles,
    as_waypoints,
    as_xz,
    check_size,
    convex_hull,
    floor_ring,
    hex_rgb,
    obstacle_extent,
    waypoint_time,
    with_breaks,
)
from motion_env.render.inset import Inset

_SKY_TOP = np.array([0.80, 0.86, 0.93])
_SKY_HORIZON = np.array([0.96, 0.97, 0.98])
_FLOOR_FAR = np.array([0.93, 0.93, 0.92])
_FLOOR_NEAR = np.array([0.83, 0.83, 0.81])

# Chains drawn per colour group: the legs and arms start at the pelvis / spine3 (HumanML3D).
_LEFT_CHAINS = tuple(c for c in CHAINS if c[1] in (1, 13))
_RIGHT_CHAINS = tuple(c for c in CHAINS if c[1] in (2, 14))
_SPINE_CHAINS = tuple(c for c in CHAINS if c not in _LEFT_CHAINS + _RIGHT_CHAINS)
_HEAD = 15

_NEAR = 0.05  # metres: points closer to the camera plane than this are not drawn
_GRID_RADIUS = 8.0  # metres of floor grid drawn around the camera target
_OBSTACLE_HEIGHT = 0.8  # obstacles are drawn as cylinders this tall
_GRID_ALPHAS = (0.55, 0.42, 0.3, 0.2, 0.11, 0.05)  # grid opacity from the target outwards
_REFERENCE_DISTANCE = 4.8  # metres at which the skeleton is drawn with its nominal line width


def _chains(joints: np.ndarray, chains: Sequence[Sequence[int]]) -> np.ndarray:
    return with_breaks(joints[list(c)] for c in chains)


def _waypoint_label(index: int, time_frames: float, fps: float) -> str:
    """'2' for the second waypoint untimed, '2: f40 (2.0 s)' timed at frame 40."""
    if np.isnan(time_frames):
        return str(index + 1)
    return f"{index + 1}: {waypoint_time(time_frames, fps)}"


class SkeletonRenderer:
    """Draws frames of the 22-joint skeleton into RGB arrays, reusing one matplotlib figure.

    Build one per image size and call :meth:`draw` for every frame;
    :func:`motion_env.render.frames.render_frame` keeps a cached instance per size for callers that
    do not want to hold one.

    Args:
        width, height: image size in pixels.
        camera: the :class:`Camera` (orientation, distance, lens); it follows `center`.
    """

    def __init__(self, width: int = 640, height: int = 480, camera: Camera | None = None) -> None:
        self.width, self.height = check_size(width, height)
        if camera is not None and not isinstance(camera, Camera):
            raise TypeError(f"camera must be a motion_env.render.Camera, got {type(camera).__name__}")
        self.camera = camera or Camera()
        self._basis = self.camera.basis()
        self._aspect = self.width / self.height
        dpi = 100
        self.figure = Figure(figsize=(self.width / dpi, self.height / dpi), dpi=dpi)
        self._canvas = FigureCanvasAgg(self.figure)
        ax = self.figure.add_axes((0.0, 0.0, 1.0, 1.0))
        ax.set_axis_off()
        ax.set_xlim(-self._aspect, self._aspect)
        ax.set_ylim(-1.0, 1.0)
        self._ax = ax
        # Font sizes scale with the image so that small env frames stay legible.
        self._font = max(7.0, 11.0 * self.height / 480)

        horizon = self.camera.focal * math.tan(math.radians(self.camera.elevation_deg))
        ax.add_collection(self._background(horizon))
        # Grid lines fade with distance; one line artist per fade level keeps drawing cheap.
        self._grid = [
            ax.plot([], [], "-", color="#6c717a", lw=0.9, alpha=a, zorder=1)[0] for a in _GRID_ALPHAS
        ]
        self._obstacles_back = PolyCollection([], zorder=2)
        ax.add_collection(self._obstacles_back)
        (self._path,) = ax.plot([], [], "--", color=TRAIL_COLOR, lw=1.2, alpha=0.45, zorder=3)
        (self._trail,) = ax.plot([], [], "-", color=TRAIL_COLOR, lw=2.0, alpha=0.9, zorder=3)
        self._waypoints = LineCollection([], linewidths=1.8, zorder=4)
        ax.add_collection(self._waypoints)
        (self._dense_waypoints,) = ax.plot([], [], ":", color=WAYPOINT_COLOR, lw=2.0, zorder=4)
        (self._dense_now,) = ax.plot([], [], "-", color=WAYPOINT_COLOR, lw=2.0, zorder=4)
        self._waypoint_labels: list = []
        (self._target,) = ax.plot([], [], "-", color=TARGET_COLOR, lw=2.5, zorder=4)
        (self._shadow,) = ax.plot([], [], "-", color="black", alpha=0.16, solid_capstyle="round", zorder=5)
        line_kw = {"solid_capstyle": "round", "solid_joinstyle": "round"}
        (self._spine,) = ax.plot([], [], "-", color=SPINE_COLOR, zorder=7, **line_kw)
        (self._left,) = ax.plot([], [], "-", color=LEFT_COLOR, zorder=6, **line_kw)
        (self._right,) = ax.plot([], [], "-", color=RIGHT_COLOR, zorder=8, **line_kw)
        (self._head,) = ax.plot([], [], "o", color=SPINE_COLOR, zorder=7)
        self._obstacles_front = PolyCollection([], zorder=9)
        ax.add_collection(self._obstacles_front)
        self._border = Rectangle(
            (0, 0), 1, 1, transform=ax.transAxes, fill=False, lw=6, ec=HIGHLIGHT_COLOR, zorder=20
        )
        ax.add_patch(self._border)
        text_kw = {"transform": ax.transAxes, "zorder": 21, "fontsize": self._font}
        self._title = ax.text(0.5, 0.975, "", ha="center", va="top", color="#212529", **text_kw)
        self._label = ax.text(0.015, 0.02, "", ha="left", va="bottom", color="#343a40", **text_kw)
        self._flag = ax.text(0.985, 0.02, "", ha="right", va="bottom", color=HIGHLIGHT_COLOR, **text_kw)
        self._flag.set_fontweight("bold")
        self._inset = Inset(self.figure, self._basis, self._aspect, self._font)
        # Blitting: the background, the title and the map's frame are drawn once into a cached
        # buffer (redrawn only when they change); per frame only the "animated" artists are drawn
        # over it. Text rendering alone would otherwise cost several ms per frame.
        static = {self._title, *ax.collections[:1]}
        self._dynamic = [a for a in (*ax.lines, *ax.collections, *ax.patches, *ax.texts) if a not in static]
        for artist in self._dynamic + self._inset.dynamic:
            artist.set_animated(True)
        self._static_key: tuple | None = None
        self._static_buffer = None

    def _background(self, horizon: float) -> PolyCollection:
        """Sky above the horizon and floor below, as horizontal bands of a vertical gradient.

        Bands of flat colour draw several times faster than an image that Agg resamples every
        frame, and 1/255 steps between neighbours do not show.
        """
        edges = np.linspace(1.0, -1.0, 97)
        mid = (edges[:-1] + edges[1:]) / 2
        sky = np.clip((mid - horizon) / max(1.0 - horizon, 1e-3), 0, 1)[:, None]
        floor = (np.clip((horizon - mid) / (horizon + 1.0), 0, 1) ** 0.7)[:, None]
        colors = np.where(
            mid[:, None] > horizon,
            _SKY_HORIZON + sky * (_SKY_TOP - _SKY_HORIZON),
            _FLOOR_FAR + floor * (_FLOOR_NEAR - _FLOOR_FAR),
        )
        a = self._aspect * 1.01
        bands = [[(-a, top), (a, top), (a, bot), (-a, bot)] for top, bot in zip(edges[:-1], edges[1:])]
        # The band that holds the horizon is split so that the horizon stays a sharp line.
        k = int(np.searchsorted(-edges, -horizon)) - 1
        if 0 <= k < len(bands):
            top, bot = edges[k], edges[k + 1]
            bands[k] = [(-a, top), (a, top), (a, horizon), (-a, horizon)]
            bands.append([(-a, horizon), (a, horizon), (a, bot), (-a, bot)])
            colors = np.concatenate([colors, [_FLOOR_FAR]])
        return PolyCollection(bands, facecolors=colors, edgecolors="none", antialiaseds=False, zorder=0)

    def _project(self, points: np.ndarray, eye: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World (..., 3) -> screen (..., 2) and depth (...); points behind the camera are NaN."""
        cam = (points - eye) @ self._basis.T
        depth = cam[..., 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            screen = self.camera.focal * cam[..., :2] / depth[..., None]
        screen[depth < _NEAR] = np.nan
        return screen, depth

    def draw(
        self,
        joints: np.ndarray,
        *,
        center: np.ndarray | Sequence[float] | None = None,
        trail: np.ndarray | None = None,
        path: np.ndarray | None = None,
        waypoints: np.ndarray | None = None,
        target: np.ndarray | Sequence[float] | None = None,
        obstacles: np.ndarray | None = None,
        frame: int | None = None,
        fps: float = 20.0,
        title: str | None = None,
        label: str | None = None,
        highlight: bool = False,
        flag: str | None = None,
        inset: bool | None = None,
        inset_bounds: np.ndarray | None = None,
    ) -> np.ndarray:
        """Draw one frame and return it as an (height, width, 3) uint8 RGB array.

        Args:
            joints: (22, 3) world joint positions.
            center: (2,) floor point x, z the camera looks at; default: the pelvis.
            trail: (N, 2) x, z (or an (N, 3) root path x, z, heading) already walked: solid line.
            path: (N, 2) / (N, 3) the whole route: faint dashed line.
            waypoints: (K, 2) / (K, 3) with times in frames; numbered rings on the floor; with
                `frame` given, timed waypoints whose time has passed are drawn grey.
            target: (2,) x, z of the current goal, drawn as a large ring with a pole.
            obstacles: (N, 3) circles x, z, radius, drawn as cylinders.
            frame: the frame index this picture shows (only used for waypoint state).
            fps: frame rate of the motion; timed waypoints are labelled with their frame and that
                time in seconds (``"2: f40 (2.0 s)"``).
            title: caption shown at the top (wrapped).
            label: small text at the bottom-left (a frame counter).
            highlight: draw the skeleton red with a red border.
            flag: text shown at the bottom-right when `highlight` is set.
            inset: top-down map in the top-right corner; None = whenever a path, trail,
                waypoints, a target or obstacles are given.
            inset_bounds: (4,) xmin, xmax, zmin, zmax of the map; default: fit the scene.
        """
        joints = as_joints(joints)
        trail_xz, path_xz = as_xz(trail, "trail"), as_xz(path, "path")
        wps, obs = as_waypoints(waypoints), as_obstacles(obstacles)
        target_xz = None if target is None else as_xz(np.reshape(target, (1, -1))[:, :2], "target")[0]
        center_xz = (
            joints[0, [0, 2]] if center is None else as_xz(np.reshape(center, (1, -1))[:, :2], "center")[0]
        )
        eye = self.camera.eye(center_xz)
        pelvis_depth = float((joints[0] - eye) @ self._basis[2])
        # Line widths shrink with distance (a far camera frames the whole path, thin lines).
        scale = float(np.clip(_REFERENCE_DISTANCE / max(pelvis_depth, 0.1), 0.3, 2.0))

        self._draw_grid(center_xz, eye)
        self._draw_floor_lines(trail_xz, path_xz, eye)
        self._draw_waypoints(wps, target_xz, frame, fps, eye)
        self._draw_obstacles(obs, pelvis_depth, eye)
        self._draw_skeleton(joints, eye, scale, highlight)

        self._border.set_visible(bool(highlight))
        self._title.set_text("\n".join(textwrap.wrap(title, 70)[:2]) if title else "")
        self._label.set_text(label or "")
        self._label.set_color(HIGHLIGHT_COLOR if highlight else "#343a40")
        self._flag.set_text(flag if (highlight and flag) else "")

        scene = [p for p in (trail_xz, path_xz) if p is not None]
        if wps is not None:
            scene.append(wps[:, :2])
        if target_xz is not None:
            scene.append(target_xz[None])
        if obs is not None:
            scene.append(obstacle_extent(obs))
        if inset is None:
            inset = bool(scene)
        self._inset.update(bool(inset), joints, scene, trail_xz, path_xz, wps, target_xz, obs, inset_bounds)
        return self._blit(bool(inset))

    def _blit(self, inset: bool) -> np.ndarray:
        key = (self._title.get_text(), inset)
        if key != self._static_key:
            self._canvas.draw()  # animated artists are skipped: this is the static layer
            self._static_buffer = self._canvas.copy_from_bbox(self.figure.bbox)
            self._static_key = key
        else:
            self._canvas.restore_region(self._static_buffer)
        artists = self._dynamic + (self._inset.dynamic if inset else [])
        for artist in sorted(artists, key=lambda a: a.get_zorder()):
            artist.axes.draw_artist(artist)
        return np.asarray(self._canvas.buffer_rgba())[..., :3].copy()

    def _draw_grid(self, center_xz: np.ndarray, eye: np.ndarray) -> None:
        # 1 m grid in 1 m pieces so that each piece can fade with its distance from the target.
        lo = np.floor(center_xz - _GRID_RADIUS)
        ticks_x = np.arange(lo[0], lo[0] + 2 * _GRID_RADIUS + 1)
        ticks_z = np.arange(lo[1], lo[1] + 2 * _GRID_RADIUS + 1)
        gx, gz = np.meshgrid(ticks_x, ticks_z[:-1], indexing="ij")
        along_z = np.stack([np.stack([gx, gz], -1), np.stack([gx, gz + 1], -1)], -2)
        gx, gz = np.meshgrid(ticks_x[:-1], ticks_z, indexing="ij")
        along_x = np.stack([np.stack([gx, gz], -1), np.stack([gx + 1, gz], -1)], -2)
        seg = np.concatenate([along_z.reshape(-1, 2, 2), along_x.reshape(-1, 2, 2)])  # (S, 2, xz)
        dist = np.linalg.norm(seg.mean(1) - center_xz, axis=-1)
        level = np.minimum((dist / _GRID_RADIUS * len(_GRID_ALPHAS)).astype(int), len(_GRID_ALPHAS))
        world = np.stack([seg[..., 0], np.zeros(seg.shape[:2]), seg[..., 1]], -1)
        screen, _ = self._project(world, eye)
        screen = np.concatenate([screen, np.full((len(seg), 1, 2), np.nan)], axis=1)  # NaN breaks
        for k, line in enumerate(self._grid):
            line.set_data(*screen[level == k].reshape(-1, 2).T)

    def _floor_line(self, xz: np.ndarray | None, eye: np.ndarray, y: float = 0.005) -> np.ndarray:
        if xz is None or len(xz) == 0:
            return np.empty((0, 2))
        pts = np.stack([xz[:, 0], np.full(len(xz), y), xz[:, 1]], -1)
        return self._project(pts, eye)[0]

    def _draw_floor_lines(self, trail: np.ndarray | None, path: np.ndarray | None, eye: np.ndarray) -> None:
        self._trail.set_data(*self._floor_line(trail, eye).T)
        self._path.set_data(*self._floor_line(path, eye).T)

    def _draw_waypoints(
        self,
        wps: np.ndarray | None,
        target: np.ndarray | None,
        frame: int | None,
        fps: float,
        eye: np.ndarray,
    ) -> None:
        for t in self._waypoint_labels:
            t.set_visible(False)
        self._dense_waypoints.set_data([], [])
        self._dense_now.set_data([], [])
        self._waypoints.set_segments([])
        if wps is not None and len(wps) > MAX_LABELLED_WAYPOINTS:
            self._dense_waypoints.set_data(*self._floor_line(wps[:, :2], eye, 0.01).T)
            timed = ~np.isnan(wps[:, 2])
            if frame is not None and timed.any():
                # A dense timed trajectory: ring the point where the pelvis should be now.
                k = np.flatnonzero(timed)[np.argmin(np.abs(wps[timed, 2] - frame))]
                self._dense_now.set_data(*self._project(floor_ring(wps[k, :2], 0.15, 0.01), eye)[0].T)
        elif wps is not None:
            segments, colors = [], []
            for k, (x, z, t) in enumerate(wps):
                passed = frame is not None and not np.isnan(t) and t < frame
                color = PASSED_COLOR if passed else WAYPOINT_COLOR
                ring = self._project(floor_ring(np.array([x, z]), 0.15, 0.01), eye)[0]
                pole = self._project(np.array([[x, 0.0, z], [x, 0.45, z]]), eye)[0]
                for piece in (ring, pole):
                    if np.isfinite(piece).all():
                        segments.append(piece)
                        colors.append(color)
                if np.isfinite(pole[1]).all():
                    self._label_at(k, pole[1], _waypoint_label(k, t, fps), color)
            self._waypoints.set_segments(segments)
            self._waypoints.set_color(colors)
        if target is None:
            self._target.set_data([], [])
        else:
            ring = self._project(floor_ring(target, 0.3, 0.01), eye)[0]
            pole = self._project(np.array([[target[0], 0.0, target[1]], [target[0], 0.9, target[1]]]), eye)[0]
            self._target.set_data(*with_breaks([ring, pole]).T)

    def _label_at(self, k: int, xy: np.ndarray, text: str, color: str) -> None:
        while len(self._waypoint_labels) <= k:
            self._waypoint_labels.append(
                self._ax.text(
                    0, 0, "", ha="center", va="bottom", zorder=10, fontsize=self._font * 0.85,
                    clip_on=True, animated=True,
                )
            )  # fmt: skip
            self._dynamic.append(self._waypoint_labels[-1])
        label = self._waypoint_labels[k]
        label.set_position(xy)
        label.set_text(text)
        label.set_color(color)
        label.set_visible(True)

    def _draw_obstacles(self, obs: np.ndarray | None, pelvis_depth: float, eye: np.ndarray) -> None:
        back, front = [], []
        for x, z, r in obs if obs is not None else ():
            pts = np.concatenate(
                [floor_ring(np.array([x, z]), r, 0.0), floor_ring(np.array([x, z]), r, _OBSTACLE_HEIGHT)]
            )
            screen, depth = self._project(pts, eye)
            screen = screen[np.isfinite(screen).all(-1)]
            if len(screen) < 3:
                continue
            hull = convex_hull(screen)
            # An obstacle nearer to the camera than the character is drawn over it.
            center_depth = float((np.array([x, 0.0, z]) - eye) @ self._basis[2])
            (front if center_depth < pelvis_depth else back).append(hull)
        for coll, polys in ((self._obstacles_back, back), (self._obstacles_front, front)):
            coll.set_verts(polys)
            coll.set_facecolor((*hex_rgb(OBSTACLE_COLOR), 0.55))
            coll.set_edgecolor((*(hex_rgb(OBSTACLE_COLOR) * 0.6), 0.9))
            coll.set_linewidth(1.0)

    def _draw_skeleton(self, joints: np.ndarray, eye: np.ndarray, scale: float, highlight: bool) -> None:
        screen, depth = self._project(joints, eye)
        shadow = joints.copy()
        shadow[:, 1] = 0.0
        all_chains = _LEFT_CHAINS + _RIGHT_CHAINS + _SPINE_CHAINS
        self._shadow.set_data(*self._project(_chains(shadow, all_chains), eye)[0].T)
        self._shadow.set_linewidth(5.0 * scale)
        lw = 4.0 * scale
        groups = (
            (self._left, _LEFT_CHAINS, LEFT_COLOR),
            (self._right, _RIGHT_CHAINS, RIGHT_COLOR),
            (self._spine, _SPINE_CHAINS, SPINE_COLOR),
        )
        for line, chains, color in groups:
            line.set_data(*_chains(screen, chains).T)
            line.set_linewidth(lw)
            line.set_color(HIGHLIGHT_COLOR if highlight else color)
        # The limb group nearer to the camera is drawn over the spine, the farther one under it.
        left_depth = np.mean([depth[list(c)].mean() for c in _LEFT_CHAINS])
        right_depth = np.mean([depth[list(c)].mean() for c in _RIGHT_CHAINS])
        self._left.set_zorder(8 if left_depth < right_depth else 6)
        self._right.set_zorder(6 if left_depth < right_depth else 8)
        self._head.set_data([screen[_HEAD, 0]], [screen[_HEAD, 1]])
        self._head.set_markersize(13.0 * scale * self.height / 480)
        self._head.set_color(HIGHLIGHT_COLOR if highlight else SPINE_COLOR)
