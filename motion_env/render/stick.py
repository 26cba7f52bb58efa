"""Pictures of motions: stick-figure videos, single RGB frames and top-down path plots.

The 3-D view is our own perspective projection drawn with plain 2-D matplotlib artists on one
reused Agg figure: each frame only updates line data and redraws the moving artists over a cached
background, which is many times faster than rebuilding matplotlib's 3-D axes (about 7 ms of CPU
for a 640x480 frame).

World conventions (see :mod:`motion_env.skeleton`): metres, Y up, floor at y = 0, the character
faces +Z at heading 0 and its left is +X.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Rectangle

from motion_env.motion.kinematics import heading_from_joints
from motion_env.motion.skeleton import CHAINS, NUM_JOINTS
from motion_env.motion.types import Motion

VIDEO_SUFFIXES = (".mp4", ".gif")

# Left limbs blue, right limbs orange (a colour-blind-safe pair); red is reserved for
# highlighted frames so that it never means "right side".
LEFT_COLOR = "#1f6fd1"
RIGHT_COLOR = "#f08c1a"
SPINE_COLOR = "#3b4252"
HIGHLIGHT_COLOR = "#e03131"
TRAIL_COLOR = "#5c7cfa"
WAYPOINT_COLOR = "#9c36b5"
TARGET_COLOR = "#d6336c"
OBSTACLE_COLOR = "#868e96"
PASSED_COLOR = "#adb5bd"
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
_MAX_LABELLED_WAYPOINTS = 30  # more waypoints than this are a dense trajectory: draw a line
_RING_SEGMENTS = 24
_MAP_EXTENT = 4.0  # metres: videos of routes wider than this get a top-down map
_GRID_ALPHAS = (0.55, 0.42, 0.3, 0.2, 0.11, 0.05)  # grid opacity from the target outwards
_REFERENCE_DISTANCE = 4.8  # metres at which the skeleton is drawn with its nominal line width


@dataclass(frozen=True)
class Camera:
    """A perspective camera looking at a target point from a fixed direction.

    Attributes:
        azimuth_deg: direction from the target to the eye, degrees from +Z towards +X (a
            character facing +Z is seen from its front-left for values in (0, 90)).
        elevation_deg: how far the eye is above the target, degrees above the horizon.
        distance: eye-to-target distance in metres.
        focal: projection scale; the image half-height spans 1 / focal of the depth
            (vertical field of view = 2 atan(1 / focal)).
        look_height: height in metres of the point the camera looks at.
    """

    azimuth_deg: float = 55.0
    elevation_deg: float = 18.0
    distance: float = 4.8
    focal: float = 2.4
    look_height: float = 0.8

    def __post_init__(self) -> None:
        if not (self.distance > 0 and self.focal > 0):
            raise ValueError(f"Camera distance and focal must be positive, got {self}")
        if not -89.0 < self.elevation_deg < 89.0:
            raise ValueError(f"Camera elevation_deg must be in (-89, 89), got {self.elevation_deg}")

    def basis(self) -> np.ndarray:
        """(3, 3) rows: the camera's right, up and forward unit vectors in world coordinates."""
        az, el = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        to_eye = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
        forward = -to_eye
        right = np.cross(forward, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return np.stack([right, up, forward])

    def eye(self, center_xz: np.ndarray) -> np.ndarray:
        """(3,) eye position when looking at the floor point `center_xz` (2,) at `look_height`."""
        target = np.array([center_xz[0], self.look_height, center_xz[1]])
        return target - self.distance * self.basis()[2]


def _as_joints(joints: np.ndarray, what: str = "joints") -> np.ndarray:
    arr = np.asarray(joints, dtype=np.float64)
    if arr.shape != (NUM_JOINTS, 3):
        raise ValueError(f"{what} must have shape ({NUM_JOINTS}, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} has NaN or infinite values")
    return arr


def _as_xz(points: np.ndarray | Sequence | None, what: str) -> np.ndarray | None:
    """(N, 2) or (N, 3) points -> (N, 2) float x, z (a third column is a heading or a time)."""
    if points is None:
        return None
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"{what} must have shape (N, 2) or (N, 3), got {arr.shape}")
    if not np.isfinite(arr[:, :2]).all():
        raise ValueError(f"{what} has NaN or infinite coordinates")
    return arr[:, :2]


def _as_waypoints(waypoints: np.ndarray | Sequence | None) -> np.ndarray | None:
    """(K, 2) / (K, 3) -> (K, 3) with the time column NaN for untimed waypoints."""
    if waypoints is None:
        return None
    arr = np.asarray(waypoints, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"waypoints must have shape (K, 2) or (K, 3), got {arr.shape}")
    if not np.isfinite(arr[:, :2]).all():
        raise ValueError("waypoints have NaN or infinite coordinates")
    if arr.shape[1] == 2:
        arr = np.concatenate([arr, np.full((len(arr), 1), np.nan)], axis=1)
    return arr


def _as_obstacles(obstacles: np.ndarray | Sequence | None) -> np.ndarray | None:
    """(N, 3) circles x, z, radius."""
    if obstacles is None:
        return None
    arr = np.asarray(obstacles, dtype=np.float64)
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"obstacles must have shape (N, 3) as (x, z, radius), got {arr.shape}")
    if not np.isfinite(arr).all() or (arr[:, 2] <= 0).any():
        raise ValueError("obstacles need finite coordinates and positive radii")
    return arr


def _with_breaks(pieces: Iterable[np.ndarray]) -> np.ndarray:
    """Join (n_i, D) polylines into one (N, D) array separated by NaN rows (one artist)."""
    out = []
    for p in pieces:
        out.append(p)
        out.append(np.full((1, p.shape[1]), np.nan))
    return np.concatenate(out[:-1]) if out else np.empty((0, 2))


def _chains(joints: np.ndarray, chains: Sequence[Sequence[int]]) -> np.ndarray:
    return _with_breaks(joints[list(c)] for c in chains)


def _ring(center_xz: np.ndarray, radius: float, y: float = 0.0) -> np.ndarray:
    """(_RING_SEGMENTS + 1, 3) closed circle on the horizontal plane at height y."""
    a = np.linspace(0.0, 2 * np.pi, _RING_SEGMENTS + 1)
    return np.stack(
        [center_xz[0] + radius * np.sin(a), np.full_like(a, y), center_xz[1] + radius * np.cos(a)], -1
    )


def _waypoint_label(index: int, time_frames: float, fps: float) -> str:
    if np.isnan(time_frames):
        return str(index + 1)
    return f"{index + 1} @{time_frames / fps:.1f}s"


class SkeletonRenderer:
    """Draws frames of the 22-joint skeleton into RGB arrays, reusing one matplotlib figure.

    Build one per image size and call :meth:`draw` for every frame; :func:`render_frame` keeps a
    cached instance per size for callers that do not want to hold one.

    Args:
        width, height: image size in pixels.
        camera: the :class:`Camera` (orientation, distance, lens); it follows `center`.
    """

    def __init__(self, width: int = 640, height: int = 480, camera: Camera | None = None) -> None:
        if width < 64 or height < 64:
            raise ValueError(f"image size must be at least 64x64 pixels, got {width}x{height}")
        self.width, self.height = int(width), int(height)
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
        self._inset = _Inset(self.figure, self._basis, self._aspect, self._font)
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
            fps: frame rate used to print waypoint times in seconds.
            title: caption shown at the top (wrapped).
            label: small text at the bottom-left (a frame counter).
            highlight: draw the skeleton red with a red border.
            flag: text shown at the bottom-right when `highlight` is set.
            inset: top-down map in the top-right corner; None = whenever a path, trail,
                waypoints, a target or obstacles are given.
            inset_bounds: (4,) xmin, xmax, zmin, zmax of the map; default: fit the scene.
        """
        joints = _as_joints(joints)
        trail_xz, path_xz = _as_xz(trail, "trail"), _as_xz(path, "path")
        wps, obs = _as_waypoints(waypoints), _as_obstacles(obstacles)
        target_xz = None if target is None else _as_xz(np.reshape(target, (1, -1))[:, :2], "target")[0]
        center_xz = joints[0, [0, 2]] if center is None else np.asarray(center, dtype=np.float64)[:2]
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
            scene.append(np.concatenate([obs[:, :2] - obs[:, 2:], obs[:, :2] + obs[:, 2:]]))
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
        if wps is not None and len(wps) > _MAX_LABELLED_WAYPOINTS:
            self._dense_waypoints.set_data(*self._floor_line(wps[:, :2], eye, 0.01).T)
            timed = ~np.isnan(wps[:, 2])
            if frame is not None and timed.any():
                # A dense timed trajectory: ring the point where the pelvis should be now.
                k = np.flatnonzero(timed)[np.argmin(np.abs(wps[timed, 2] - frame))]
                self._dense_now.set_data(*self._project(_ring(wps[k, :2], 0.15, 0.01), eye)[0].T)
        elif wps is not None:
            segments, colors = [], []
            for k, (x, z, t) in enumerate(wps):
                passed = frame is not None and not np.isnan(t) and t < frame
                color = PASSED_COLOR if passed else WAYPOINT_COLOR
                ring = self._project(_ring(np.array([x, z]), 0.15, 0.01), eye)[0]
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
            ring = self._project(_ring(target, 0.3, 0.01), eye)[0]
            pole = self._project(np.array([[target[0], 0.0, target[1]], [target[0], 0.9, target[1]]]), eye)[0]
            self._target.set_data(*_with_breaks([ring, pole]).T)

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
                [_ring(np.array([x, z]), r, 0.0), _ring(np.array([x, z]), r, _OBSTACLE_HEIGHT)]
            )
            screen, depth = self._project(pts, eye)
            screen = screen[np.isfinite(screen).all(-1)]
            if len(screen) < 3:
                continue
            hull = _convex_hull(screen)
            # An obstacle nearer to the camera than the character is drawn over it.
            center_depth = float((np.array([x, 0.0, z]) - eye) @ self._basis[2])
            (front if center_depth < pelvis_depth else back).append(hull)
        for coll, polys in ((self._obstacles_back, back), (self._obstacles_front, front)):
            coll.set_verts(polys)
            coll.set_facecolor((*_hex_rgb(OBSTACLE_COLOR), 0.55))
            coll.set_edgecolor((*(_hex_rgb(OBSTACLE_COLOR) * 0.6), 0.9))
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


class _Inset:
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
        self._obstacles = PolyCollection([], facecolor=(*_hex_rgb(OBSTACLE_COLOR), 0.6), edgecolor="none")
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
        dense = wps is not None and len(wps) > _MAX_LABELLED_WAYPOINTS
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
        circles = [] if obs is None else [_ring(o[:2], o[2])[:, [0, 2]] @ self._rot for o in obs]
        self._obstacles.set_verts(circles)


def _hex_rgb(color: str) -> np.ndarray:
    return np.array([int(color[i : i + 2], 16) / 255 for i in (1, 3, 5)])


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """(N, 2) -> (M, 2) convex hull, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(map(tuple, points))
    if len(pts) < 3:
        return np.asarray(pts)

    def half(seq: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
        out: list[tuple[float, float]] = []
        for p in seq:
            while len(out) >= 2:
                (ax, ay), (bx, by) = out[-2], out[-1]
                if (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(reversed(pts))
    return np.asarray(lower[:-1] + upper[:-1])


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
    """
    key = (int(width), int(height), camera or Camera())
    renderer = _RENDERERS.get(key)
    if renderer is None:
        if len(_RENDERERS) >= 8:  # a figure per size is a few MB: keep only recent sizes
            del _RENDERERS[next(iter(_RENDERERS))]
        renderer = _RENDERERS[key] = SkeletonRenderer(key[0], key[1], key[2])
    return renderer.draw(
        joints,
        center=center,
        trail=path,
        waypoints=waypoints,
        target=target,
        obstacles=obstacles,
        title=title,
        label=label,
        highlight=highlight,
        inset=inset,
    )


def _follow_centers(root_xz: np.ndarray, fps: float, window_s: float = 1.5) -> np.ndarray:
    """(T, 2) camera targets: the pelvis path smoothed by a centred moving average.

    Following the raw pelvis would shake the whole picture with every step's sway.
    """
    n = max(1, int(round(window_s * fps)) | 1)
    pad = n // 2
    padded = np.concatenate([np.repeat(root_xz[:1], pad, 0), root_xz, np.repeat(root_xz[-1:], pad, 0)])
    csum = np.cumsum(np.concatenate([np.zeros((1, 2)), padded]), axis=0)
    return (csum[n:] - csum[:-n]) / n


def _framing_camera(points: np.ndarray, camera: Camera, aspect: float) -> tuple[Camera, np.ndarray]:
    """A camera (same direction) and floor centre (2,) that keep all (N, 3) points in view."""
    lo, hi = points.min(0), points.max(0)
    center = (lo[[0, 2]] + hi[[0, 2]]) / 2
    camera = replace(camera, look_height=float((lo[1] + hi[1]) / 2))
    basis = camera.basis()

    def fits(distance: float) -> bool:
        eye = np.array([center[0], camera.look_height, center[1]]) - distance * basis[2]
        cam = (points - eye) @ basis.T
        if (cam[:, 2] < 0.5).any():
            return False
        screen = camera.focal * cam[:, :2] / cam[:, 2:]
        # Leave room for the title at the top and the frame counter at the bottom.
        return bool((np.abs(screen[:, 0]) < 0.92 * aspect).all() and (np.abs(screen[:, 1]) < 0.8).all())

    near, far = 0.5, 1.0
    while not fits(far) and far < 1e4:
        far *= 2
    for _ in range(30):  # bisection: the smallest distance that still frames everything
        mid = (near + far) / 2
        near, far = (near, mid) if fits(mid) else (mid, far)
    return replace(camera, distance=far), center


def _frame_indices(num_frames: int, src_fps: float, fps: float) -> np.ndarray:
    """Source frame shown at each output frame when the video is written at `fps`."""
    count = max(1, int(np.floor(num_frames * fps / src_fps + 0.5)))
    return np.minimum((np.arange(count) * src_fps / fps + 1e-6).astype(int), num_frames - 1)


class _VideoWriter:
    """Streams RGB frames to an .mp4 (ffmpeg, H.264) or a .gif (Pillow, a palette per frame)."""

    def __init__(self, path: Path, fps: float) -> None:
        self.path, self.fps = path, fps
        self._gif: list = []
        self._mp4 = None
        if path.suffix.lower() == ".mp4":
            import imageio.v2 as imageio

            # macro_block_size=2: yuv420p needs even sizes; imageio's default 16 would rescale.
            self._mp4 = imageio.get_writer(
                path, format="FFMPEG", fps=fps, codec="libx264", quality=7,
                pixelformat="yuv420p", macro_block_size=2,
            )  # fmt: skip

    def append(self, frame: np.ndarray) -> None:
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


def _check_video_path(path: str | Path) -> Path:
    path = Path(path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"{path}: unknown video type {path.suffix!r} (expected one of {VIDEO_SUFFIXES})")
    return path


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
    """
    path = _check_video_path(path)
    if camera not in ("follow", "fixed"):
        raise ValueError(f"camera must be 'follow' or 'fixed', got {camera!r}")
    if path.suffix.lower() == ".mp4" and (width % 2 or height % 2):
        raise ValueError(f"an .mp4 needs an even frame size, got {width}x{height}")
    fps = float(fps) if fps is not None else motion.fps
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    wps = _as_waypoints(motion.waypoints if waypoints is None else waypoints)
    obs = _as_obstacles(obstacles)
    title = motion.text if title is None else title
    joints = motion.joints.astype(np.float64)
    root_xz = joints[:, 0, [0, 2]]
    highlighted = np.zeros(motion.num_frames + 1, dtype=bool)
    for f in highlight_frames or ():
        if not 0 <= int(f) < motion.num_frames:
            raise ValueError(f"highlight frame {f} is outside the motion's {motion.num_frames} frames")
        highlighted[int(f)] = True

    scene = [root_xz]
    if wps is not None:
        scene.append(wps[:, :2])
    if obs is not None:
        scene.append(np.concatenate([obs[:, :2] - obs[:, 2:], obs[:, :2] + obs[:, 2:]]))
    scene_xz = np.concatenate(scene)
    bounds = np.array(
        [scene_xz[:, 0].min(), scene_xz[:, 0].max(), scene_xz[:, 1].min(), scene_xz[:, 1].max()]
    )
    if camera == "fixed":
        body = joints.reshape(-1, 3)
        floor = np.stack([scene_xz[:, 0], np.zeros(len(scene_xz)), scene_xz[:, 1]], -1)
        cam, fixed_center = _framing_camera(np.concatenate([body, floor]), Camera(), width / height)
        centers = np.repeat(fixed_center[None], motion.num_frames, 0)
        inset = False
    else:
        cam, centers = Camera(), _follow_centers(root_xz, motion.fps)
        # The map is only worth its corner when the route does not fit in the follow view.
        inset = bool((bounds[1::2] - bounds[::2]).max() > _MAP_EXTENT)
    renderer = SkeletonRenderer(width, height, cam)

    path.parent.mkdir(parents=True, exist_ok=True)
    indices = _frame_indices(motion.num_frames, motion.fps, fps)
    writer = _VideoWriter(path, fps)
    try:
        for i, src in enumerate(indices):
            # An output frame stands for every source frame until the next one: flag it if any is.
            stop = indices[i + 1] if i + 1 < len(indices) else motion.num_frames
            flagged = bool(highlighted[src : max(stop, src + 1)].any())
            frame = renderer.draw(
                joints[src],
                center=centers[src],
                trail=root_xz[: src + 1],
                path=root_xz,
                waypoints=wps,
                obstacles=obs,
                frame=int(src),
                fps=motion.fps,
                title=title,
                label=f"frame {src + 1}/{motion.num_frames}   {src / motion.fps:5.2f} s",
                highlight=flagged,
                flag=highlight_label,
                inset=inset,
                inset_bounds=bounds,
            )
            writer.append(frame)
    except BaseException:
        writer.abort()
        raise
    writer.close()
    return path


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
    their time, and a dotted line joins each to where the pelvis was at that time).

    Args:
        motion_or_motions: one :class:`Motion` or several (drawn in different colours).
        path: output `.png`.
        waypoints: (K, 2) / (K, 3) (third column: frame index); default: the first motion's.
        obstacles: (N, 3) circles x, z, radius.
        title: default: the caption of a single motion.

    Returns:
        The path written.
    """
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: plot_path writes a .png, got suffix {path.suffix!r}")
    motions = [motion_or_motions] if isinstance(motion_or_motions, Motion) else list(motion_or_motions)
    if not motions:
        raise ValueError("plot_path needs at least one motion")
    if waypoints is None:
        waypoints = next((m.waypoints for m in motions if m.waypoints is not None), None)
    wps, obs = _as_waypoints(waypoints), _as_obstacles(obstacles)
    if title is None and len(motions) == 1:
        title = motions[0].text

    fig = Figure(figsize=(7.0, 7.0), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    palette = ["#1f6fd1", "#f08c1a", "#2f9e44", "#9c36b5", "#0c8599", "#e8590c", "#5c940d", "#c2255c"]
    extent = []
    for n, m in enumerate(motions):
        color = palette[n % len(palette)]
        root = m.joints[:, 0, [0, 2]].astype(np.float64)
        extent.append(root)
        name = m.text or Path(m.meta.get("source", "")).name or f"motion {n + 1}"
        name = "root path" if len(motions) == 1 else name if len(name) <= 50 else name[:49] + "\u2026"
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
        if wps is not None and len(wps) <= _MAX_LABELLED_WAYPOINTS:
            for x, z, t in wps:
                if not np.isnan(t) and 0 <= t < m.num_frames:
                    at = root[int(round(t))]
                    ax.plot([x, at[0]], [z, at[1]], ":", color=color, lw=1.2)
    if wps is not None:
        extent.append(wps[:, :2])
        if len(wps) > _MAX_LABELLED_WAYPOINTS:
            ax.plot(wps[:, 0], wps[:, 1], ":", color=WAYPOINT_COLOR, lw=2, label="waypoints")
        else:
            ax.plot(wps[:, 0], wps[:, 1], "o", color="white", mec=WAYPOINT_COLOR, mew=2, ms=13, zorder=6,
                    label="waypoints (dotted: pelvis at that time)" if not np.isnan(wps[:, 2]).all()
                    else "waypoints")  # fmt: skip
            for k, (x, z, t) in enumerate(wps):
                ax.annotate(str(k + 1), (x, z), ha="center", va="center", fontsize=7, color=WAYPOINT_COLOR,
                            fontweight="bold", zorder=7)  # fmt: skip
                if not np.isnan(t):
                    ax.annotate(f"t={t / motions[0].fps:.1f}s", (x, z), xytext=(9, 9),
                                textcoords="offset points", fontsize=8, color=WAYPOINT_COLOR)  # fmt: skip
    if obs is not None:
        for x, z, r in obs:
            ax.add_patch(Circle((x, z), r, fc=(*_hex_rgb(OBSTACLE_COLOR), 0.5), ec=OBSTACLE_COLOR))
        extent.append(np.concatenate([obs[:, :2] - obs[:, 2:], obs[:, :2] + obs[:, 2:]]))
    pts = np.concatenate(extent)
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
    if title:
        ax.set_title("\n".join(textwrap.wrap(title, 70)), fontsize=11)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    return path
