"""One character's route in the studio: the waypoints a user placed, and how far along it is.

The semantics are the environments' (:mod:`motion_env.envs.core`): waypoint ``next`` is the one
the character heads for; it is passed when the pelvis comes within :data:`ARRIVE_RADIUS` of it,
or when it is timed and its frame has gone by (the path controller moves on then too). The last
waypoint is never passed; coming within the radius marks it reached. Times are frame indices of
the character's episode (20 fps), so a route stays valid across a reset.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_waypoints

__all__ = ["ARRIVE_RADIUS", "Route"]

ARRIVE_RADIUS = 0.5  # metres, as the environments' default arrive_radius


class Route:
    """The waypoints of one character: (K, 3) x, z, frame (NaN = untimed), and the next one's index."""

    def __init__(self) -> None:
        self.points = np.zeros((0, 3), np.float64)
        self.next = 0
        self.reached = False  # the last waypoint has been reached
        self.version = 0  # bumped on every change, so that the page redraws only what changed

    def __len__(self) -> int:
        return len(self.points)

    def copy(self) -> Route:
        """An independent copy (to try an edit before making it)."""
        other = Route()
        other.points, other.next, other.reached = self.points.copy(), self.next, self.reached
        return other

    def _set(self, points: np.ndarray, next_index: int = 0) -> None:
        self.points = points
        self.next = min(next_index, max(len(points) - 1, 0))
        self.reached = False
        self.version += 1

    def add(self, xz: Sequence[float], frame: float | None = None) -> None:
        """Append a waypoint at `xz`, reached at episode `frame` (None: untimed).

        Raises ValueError when `frame` is not after the route's last timed waypoint (times must
        increase along a route).
        """
        timed = self.points[~np.isnan(self.points[:, 2]), 2]
        if frame is not None and len(timed) and frame <= timed[-1]:
            raise ValueError(
                f"a timed waypoint must come after the last one (at {timed[-1] / FPS:.1f} s of the "
                f"episode); this one is at {frame / FPS:.1f} s"
            )
        row = np.array([[float(xz[0]), float(xz[1]), np.nan if frame is None else float(frame)]])
        points = validate_waypoints(np.concatenate([self.points, row])).astype(np.float64)
        # A route that was finished starts again at its new waypoint.
        self._set(points, len(points) - 1 if self.reached else self.next)

    def move(self, index: int, xz: Sequence[float]) -> None:
        """Move waypoint `index` to `xz` (its time stays)."""
        if not 0 <= index < len(self.points):
            raise IndexError(f"there is no waypoint {index + 1} (the route has {len(self.points)})")
        points = self.points.copy()
        points[index, :2] = xz
        self._set(validate_waypoints(points).astype(np.float64), min(self.next, index))

    def replace(self, points: np.ndarray | Sequence | None) -> None:
        """A whole new route ((M, 2) or (M, 3); None or empty: no route), followed from its first point."""
        if points is None or len(points) == 0:
            self._set(np.zeros((0, 3), np.float64))
            return
        self._set(validate_waypoints(points).astype(np.float64))

    def restart(self) -> None:
        """Follow the route from its first waypoint again (a new episode)."""
        self._set(self.points)

    def advance(self, position_xz: np.ndarray, frame: int) -> bool:
        """Move past the waypoints the pelvis at `position_xz` has reached (or whose time is past).

        Returns True when something changed (the next waypoint, or the last one reached).
        """
        changed = False
        while self.next < len(self.points) - 1:
            x, z, t = self.points[self.next]
            near = np.hypot(position_xz[0] - x, position_xz[1] - z) < ARRIVE_RADIUS
            if not (near or (not np.isnan(t) and frame >= t)):
                break
            self.next += 1
            changed = True
        if len(self.points) and not self.reached:
            x, z, _ = self.points[-1]
            near = np.hypot(position_xz[0] - x, position_xz[1] - z) < ARRIVE_RADIUS
            if self.next == len(self.points) - 1 and near:
                self.reached = changed = True
        if changed:
            self.version += 1
        return changed

    def ahead(self, frame: int) -> np.ndarray | None:
        """The waypoints still to go, (K, 3) for the generator (None: no route).

        A timed waypoint whose frame has gone by (it was moved after its time) is sent untimed:
        the character still walks there, at the caption's pace.
        """
        if not len(self.points):
            return None
        rows = self.points[self.next :].copy()
        rows[rows[:, 2] <= frame, 2] = np.nan
        return rows.astype(np.float32)

    def target(self) -> np.ndarray | None:
        """(x, z) of the waypoint the character heads for, None without a route."""
        return self.points[self.next, :2].copy() if len(self.points) else None
