"""The stream's root path ahead (:class:`~motion_env.generation.streaming.MotionStream`'s stage 2).

A token covering frames ``f .. f + rate - 1`` needs the root path up to ``f + path_horizon``: the
controller is rolled back to the last decoded frame after a change (:meth:`StreamPaths._restore`),
rolled out (or, with a look-ahead head, rolled out for the token and predicted beyond it), and
the controller's path is continued from the committed one and bent through the waypoints ahead
(:meth:`StreamPaths._snap_ahead`). :func:`~motion_env.models.path_features.first_token_path_features`
turns the paths of a batch into the GPT's path features of each row's next token at once.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from motion_env.generation.pipeline import PATH_SMOOTHING
from motion_env.generation.recompose import route_anchors, smooth_path, spread_residuals
from motion_env.generation.route_planning import plan_route, turn_round

__all__ = ["CATCH_UP_TOKENS", "StreamPaths"]

# After a predicted look-ahead the roll-out advances by up to this many tokens' frames per token
# until it is a horizon ahead again (a token's cost stays bounded while it catches up).
CATCH_UP_TOKENS = 2
# Past frames of the controller's path that its smoothing (PATH_SMOOTHING, as whole clips') reads
# before the anchor: the Gaussian's reach, so a committed frame is smoothed as in the whole path.
_SMOOTH_PAST = int(4 * PATH_SMOOTHING) + 1


class StreamPaths:
    """The look-ahead half of :class:`~motion_env.generation.streaming.MotionStream` (its state is
    the stream's: the controller's front and state ring, the routes and the changes waiting)."""

    _pipe: Any
    _front: Any
    _states: Any
    _control: Any
    _head: Any
    _routes: list[np.ndarray | None]
    _anchor_frames: list[np.ndarray]
    _pending: dict[int, tuple[np.ndarray | None, np.ndarray, int]]
    _texts: list[str]
    _decoded: np.ndarray
    _snapped: np.ndarray
    _dirty: np.ndarray
    _predicted: np.ndarray
    _ring: int
    _rate: int
    _horizon: int
    _lookahead: str
    batch_size: int

    def _restore(self, rows: np.ndarray) -> None:
        """Roll the controller of `rows` back to their last decoded frame (after a caption/route change)."""
        g = self._pipe
        anchors = np.maximum(self._decoded[rows] - 1, 0)
        rows_t = torch.as_tensor(rows, device=g.device)
        self._front = self._states.restore(self._front, rows_t, torch.as_tensor(anchors, device=g.device))
        changed = np.array([int(i) in self._pending for i in rows], bool)  # a new route waits
        if changed.any():
            moved = rows[changed]
            for i in moved:
                route, where, frame = self._pending.pop(int(i))
                self._routes[i] = self._planned(int(i), route, where, frame)
            # planned routes (plan_route: checked (K, 3) float32) need no second check
            self._front = g.controller.set_routes(
                self._front, moved, [self._routes[i] for i in moved], checked=True
            )
            moved_t = torch.as_tensor(moved, device=g.device)
            frames = torch.as_tensor(anchors[changed], device=g.device)
            self._states.set_queue(moved_t, frames, self._front.queue[moved_t])
        self._dirty[rows] = False

    def _planned(
        self, i: int, route: np.ndarray | None, where: np.ndarray, frame: int = 0
    ) -> np.ndarray | None:
        """Character i's checked `route` from `where` (x, z, heading) at `frame`, planned
        (:func:`~motion_env.generation.route_planning.plan_route`), with a U-turn before a waypoint
        behind a forward walk (:func:`~motion_env.generation.route_planning.turn_round`; its
        caption read as the pipeline caches it)."""
        planned = plan_route(route, where[:2], frame)
        return turn_round(planned, where) if self._pipe.walks_forward([self._texts[i]])[0] else planned

    def _advance(self, rows: np.ndarray, targets: np.ndarray) -> None:
        """Step the controller of `rows` until each reaches its target frame, recording every frame."""
        g = self._pipe
        frames = self._front.frame.cpu().numpy()[rows]
        need = targets - frames
        for n in np.unique(need[need > 0]):
            members = rows[need == n]
            group = torch.as_tensor(members, device=g.device)
            whole = len(members) == self.batch_size  # every row, in order (rows are sorted)
            sub = self._front if whole else self._front.take(group)
            first = sub.frame
            sub, trace = g.controller.run(sub, int(n), trace=True)
            self._states.record_trace(group, first, trace)
            self._front = sub if whole else self._front.put(group, sub)

    def _advance_with_head(
        self, rows: np.ndarray, first: np.ndarray, last: np.ndarray, changed: np.ndarray
    ) -> None:
        """The look-ahead of `rows` up to frames `last`: rows `changed` roll out the token's frames,
        rows catching up CATCH_UP_TOKENS tokens' frames, the others all; the head predicts the rest."""
        front = self._front.frame.cpu().numpy()[rows]
        end = first + self._rate - 1  # the token's last frame
        behind = self._predicted[rows] & ~changed
        target = np.where(behind, np.minimum(last, front + CATCH_UP_TOKENS * self._rate), last)
        target = np.where(changed, end, np.maximum(target, end))
        self._advance(rows, target)
        short = target < last
        self._predicted[rows] = short
        if not short.any():
            return
        ahead = rows[short]
        # Every row, in order (rows are sorted): the front itself, whose caption projection the
        # controller has cached (a taken copy would be projected again, and evict it).
        whole = len(ahead) == self.batch_size
        sub = self._front if whole else self._front.take(torch.as_tensor(ahead, device=self._pipe.device))
        roots = self._head.predict(self._pipe.controller, sub).cpu().numpy()  # (N, H, 3)
        self._states.record_roots(rows[short], target[short], roots, (last - target)[short])

    def _smooth(self, rows: np.ndarray, anchor: np.ndarray, count: np.ndarray, raw: np.ndarray) -> None:
        """Smooth in place the controller paths `raw` (N, L, 3) over frames anchor.. (the first
        `count` of each row) of the rows with a route, as a whole clip's path is
        (:data:`~motion_env.generation.pipeline.PATH_SMOOTHING`), reading the frames before the
        anchor: each frame a token commits is the one the whole path smoothed gives. The
        controller brakes and surges where it passes a timed waypoint (a streamed run's root
        2.7 -> 1.7 -> 2.5 m/s in two frames, which the replay's root force rejects). Rows alike
        (past frames, length) in one call."""
        routed = np.array([self._routes[i] is not None for i in rows], bool)
        back = np.minimum(anchor, _SMOOTH_PAST)  # the episode's frame 0 is reflected, as whole clips'
        for b, c in {(int(b), int(c)) for b, c in zip(back[routed], count[routed], strict=True)}:
            sel = np.nonzero(routed & (back == b) & (count == c))[0]
            past = (anchor[sel, None] - b + np.arange(b)) % self._ring
            whole = np.concatenate(
                [self._states.roots[rows[sel, None], past].astype(np.float64), raw[sel, :c]], 1
            )
            raw[sel, :c] = smooth_path(whole, PATH_SMOOTHING)[:, b:]

    def _snap_ahead(
        self, i: int, anchor: int, path: np.ndarray, queue: int, steered: np.ndarray
    ) -> np.ndarray:
        """Character i's root path over frames anchor..anchor + len(path) - 1, continuing its
        committed path: `path` (float64), the controller's smoothed and shifted so that the anchor
        frame sits where it was emitted, bent (:func:`~motion_env.generation.recompose.spread_residuals`)
        through the waypoints ahead (from route index `queue` on) that fall inside the window:
        timed ones after the anchor, untimed ones that the controller's own path (`steered`,
        shifted alike) passes within SNAP_RADIUS (:func:`~motion_env.generation.recompose.route_anchors`).
        """
        route = self._routes[i]
        last = anchor + len(path) - 1
        pelvis = self._control.pelvis_anchors(i, anchor, last) if self._control.active(i) else None
        self._anchor_frames[i] = np.zeros(0, np.int64)
        if route is None and pelvis is None:
            return path.astype(np.float32)
        anchors = np.zeros((0, 3), np.float32)
        if route is not None:
            anchors = route_anchors(path, route[queue:], first=anchor, open_end=True, steered=steered)
        if pelvis is not None and len(pelvis):  # pelvis targets bend the path like timed waypoints
            anchors = anchors[~np.isin(anchors[:, 2], pelvis[:, 2])]
            anchors = np.concatenate([anchors, pelvis])
            anchors = anchors[np.argsort(anchors[:, 2], kind="stable")]
        self._anchor_frames[i] = anchor + anchors[:, 2].astype(np.int64)  # the balance keeps them put
        return spread_residuals(path, anchors).astype(np.float32)

    def _plan_paths(self, rows: np.ndarray, first: np.ndarray) -> list[np.ndarray]:
        """Each row's root path over frames first..first+horizon: committed up to the anchor (one
        frame before the token), the controller's look-ahead snapped beyond it."""
        changed = self._dirty[rows].copy()
        if changed.any():
            self._restore(rows[changed])
        last = first + self._horizon
        if self._lookahead == "head":
            self._advance_with_head(rows, first, last, changed)
        else:
            self._advance(rows, last)
            self._predicted[rows] = False
        # The controller's paths from each anchor (one frame before the token; frame 0 at the
        # start) to the token's last frame, shifted onto the committed path, for every row at once.
        anchor = np.maximum(first - 1, 0)
        count = first + self._horizon - anchor + 1  # frames anchor..first + horizon
        slots = (anchor[:, None] + np.arange(int(count.max()))) % self._ring
        raw = self._states.roots[rows[:, None], slots].astype(np.float64)  # (N, L, 3)
        steered = raw.copy()  # where untimed waypoints are looked for (route_anchors)
        self._smooth(rows, anchor, count, raw)
        committed = self._snapped[rows, anchor % self._ring, :2]
        paths = raw.copy()
        paths[..., :2] += (committed - raw[:, 0, :2])[:, None]
        steered[..., :2] += (committed - steered[:, 0, :2])[:, None]
        queue = self._states.queue_at(rows, anchor)
        return [
            self._snap_ahead(int(i), int(anchor[n]), paths[n, : count[n]], queue[n], steered[n, : count[n]])[
                first[n] - anchor[n] :
            ]
            for n, i in enumerate(rows)
        ]
