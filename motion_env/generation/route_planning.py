"""The route the path controller is given: a checked request route, planned so it can be followed.

Two rules, both closed form and both leaving routes the controller was trained on unchanged
(:func:`plan_route`), and a third that needs the caption's pace (:func:`pace_route`):

- **Untimed waypoints before a timed one get times**, spread along the route at one pace from the
  previous timed waypoint (or the start): without them the controller walks the untimed part at
  the caption's pace and then has to rush (or dawdle) to be on time at the timed one.
- **Long untimed legs are split**: an untimed waypoint more than ``MAX_UNTIMED_LEG`` metres after
  the point before it gets evenly spaced untimed waypoints in between (at most ``SPLIT_LEG``
  apart). The controller learned the pace of a caption from waypoints a few metres apart; one
  50 m away reads as "hurry" and a walk would jog at 3-4 m/s.
- **Untimed waypoints after the last timed one get times at the caption's pace**
  (:func:`pace_route`; the pace from :class:`motion_env.models.pace.PaceRegressor`), the last
  waypoint excepted: on a long untimed route the controller alone drifts towards the data's mean
  speed (a run caption crossed 40 m at 2.1 m/s, the run takes go 2.8 m/s). The last waypoint
  stays untimed, so the character still arrives there at its own pace and stops; a caption
  slower than :data:`MIN_PACE` (waves, bows: not a way of travelling) leaves the route as it is.
  Only the controller sees these times: the path is snapped to the waypoints as untimed ones
  (wherever it passes them), so the timing steers and never bends the path.

The waypoints a user gave stay where they are (and in :attr:`Motion.waypoints`); only the
controller and the snapping see the planned route.
"""

from __future__ import annotations

import math

import numpy as np

from motion_env.motion.skeleton import FPS

__all__ = [
    "MAX_UNTIMED_LEG",
    "MIN_PACE",
    "SPLIT_LEG",
    "START_ACCELERATION",
    "needs_pace",
    "pace_route",
    "plan_route",
]

MAX_UNTIMED_LEG = 6.0  # metres: longer untimed legs are split (routes used in training: 1-4 m legs)
SPLIT_LEG = 4.0  # metres: the longest piece of a split leg
MIN_PACE = 0.6  # m/s: a slower caption pace leaves untimed waypoints untimed (the slowest walks: 0.7)
# m/s^2: a character that starts its episode on a paced route (at rest) gets the time to reach the
# pace at this acceleration, pace / (2 a) seconds more (real runs reach 3 m/s in about a second).
START_ACCELERATION = 3.0


def plan_route(
    route: np.ndarray | None, start_xz: np.ndarray, first_frame: int = 0, pace: float | None = None
) -> np.ndarray | None:
    """(K, 3) checked route (NaN time = untimed) -> the route the controller follows (M >= K rows).

    Args:
        route: the waypoints ahead, in order (or None).
        start_xz: (2,) where the pelvis is at `first_frame`.
        first_frame: the episode frame of `start_xz`; timed waypoints before it are left alone.
        pace: the caption's pace in m/s (:func:`pace_route`); None: untimed waypoints after the
            last timed one stay untimed (the route the snapping sees).
    """
    planned = _planned(route, start_xz, first_frame)
    return planned if pace is None else pace_route(planned, start_xz, first_frame, pace)


def pace_route(
    route: np.ndarray | None, start_xz: np.ndarray, first_frame: int = 0, pace: float | None = None
) -> np.ndarray | None:
    """A planned route (:func:`plan_route` without pace) with times at `pace` for its untimed
    waypoints after the last timed one, the last waypoint excepted (module docstring).

    The time of each is the distance along the route from the last timed waypoint ahead (or from
    `start_xz` at `first_frame`) at `pace`; a character starting its episode (`first_frame` 0, no
    timed waypoint before) gets ``pace / (2 START_ACCELERATION)`` seconds more to get going.

    Args:
        route: (M, 3) planned route, or None (returned as it is).
        start_xz: (2,) where the pelvis is at `first_frame`.
        first_frame: the episode frame of `start_xz`.
        pace: m/s; None, NaN or below :data:`MIN_PACE`: the route is returned as it is.
    """
    if pace is None or not np.isfinite(pace) or pace < MIN_PACE or not needs_pace(route):
        return route
    route = np.asarray(route, np.float32)
    times = route[:, 2].astype(np.float64)
    timed = np.nonzero(~np.isnan(times))[0]
    first = int(timed[-1]) + 1 if len(timed) else 0  # the first row paced
    if first > 0 and times[first - 1] >= first_frame:  # from the last timed waypoint ahead
        anchor_xz, anchor_t = route[first - 1, :2].astype(np.float64), float(times[first - 1])
    else:  # from where the character is (any timed waypoint is behind it)
        anchor_xz, anchor_t = np.asarray(start_xz, np.float64)[:2], float(first_frame)
        anchor_t += FPS * pace / (2.0 * START_ACCELERATION) if first_frame == 0 else 0.0
    points = np.concatenate([anchor_xz[None], route[first:-1, :2].astype(np.float64)])
    walked = np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))
    paced = route.copy()
    paced[first:-1, 2] = anchor_t + FPS * walked / float(pace)
    return paced


def needs_pace(route: np.ndarray | None) -> bool:
    """Whether :func:`pace_route` would time any waypoint of `route` (at a pace it accepts)."""
    if route is None or len(route) < 2:
        return False
    timed = np.nonzero(~np.isnan(np.asarray(route)[:, 2]))[0]
    return (int(timed[-1]) + 1 if len(timed) else 0) < len(route) - 1


def _planned(route: np.ndarray | None, start_xz: np.ndarray, first_frame: int) -> np.ndarray | None:
    """The first two rules of the module docstring."""
    if route is None:
        return None
    route = np.asarray(route, np.float64)
    points = np.concatenate([np.asarray(start_xz, np.float64)[None, :2], route[:, :2]])
    legs = np.linalg.norm(np.diff(points, axis=0), axis=1)  # (K,) leg ending at each waypoint
    if np.isnan(route[:, 2]).all() and (legs <= MAX_UNTIMED_LEG).all():
        return route.astype(np.float32)  # nothing to time or split (a learner's goal each step)
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
