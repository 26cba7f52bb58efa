"""The route the path controller is given: a checked request route, planned so it can be followed.

Two rules, both closed form and both leaving routes the controller was trained on unchanged:

- **Untimed waypoints before a timed one get times**, spread along the route at one pace from the
  previous timed waypoint (or the start): without them the controller walks the untimed part at
  the caption's pace and then has to rush (or dawdle) to be on time at the timed one.
- **Long untimed legs are split**: an untimed waypoint more than ``MAX_UNTIMED_LEG`` metres after
  the point before it gets evenly spaced untimed waypoints in between (at most ``SPLIT_LEG``
  apart). The controller learned the pace of a caption from waypoints a few metres apart; one
  50 m away reads as "hurry" and a walk would jog at 3-4 m/s.

The waypoints a user gave stay where they are (and in :attr:`Motion.waypoints`); only the
controller and the snapping see the planned route.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["MAX_UNTIMED_LEG", "SPLIT_LEG", "plan_route"]

MAX_UNTIMED_LEG = 6.0  # metres: longer untimed legs are split (routes used in training: 1-4 m legs)
SPLIT_LEG = 4.0  # metres: the longest piece of a split leg


def plan_route(route: np.ndarray | None, start_xz: np.ndarray, first_frame: int = 0) -> np.ndarray | None:
    """(K, 3) checked route (NaN time = untimed) -> the route the controller follows (M >= K rows).

    Args:
        route: the waypoints ahead, in order (or None).
        start_xz: (2,) where the pelvis is at `first_frame`.
        first_frame: the episode frame of `start_xz`; timed waypoints before it are left alone.
    """
    if route is None:
        return None
    route = np.asarray(route, np.float64)
    points = np.concatenate([np.asarray(start_xz, np.float64)[None, :2], route[:, :2]])
    legs = np.linalg.norm(np.diff(points, axis=0), axis=1)  # (K,) leg ending at each waypoint
    times = route[:, 2].copy()
    anchor_t, pending = float(first_frame), []  # untimed rows since the last timed anchor
    for k, t in enumerate(route[:, 2]):
        if np.isnan(t):
            pending.append(k)
            continue
        if t < first_frame:  # already passed: neither an anchor nor a deadline
            pending = []
            continue
        if pending:
            span = np.cumsum(legs[pending[0] : k + 1])  # distance from the anchor to each row
            times[pending] = anchor_t + (t - anchor_t) * span[:-1] / max(span[-1], 1e-9)
        anchor_t, pending = float(t), []
    rows = []
    for k in range(len(route)):
        if np.isnan(times[k]) and legs[k] > MAX_UNTIMED_LEG:
            pieces = math.ceil(legs[k] / SPLIT_LEG)
            for f in np.arange(1, pieces) / pieces:
                rows.append([*(points[k] + f * (points[k + 1] - points[k])), np.nan])
        rows.append([*route[k, :2], times[k]])
    return np.array(rows, np.float32)
