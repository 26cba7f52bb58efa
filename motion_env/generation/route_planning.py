"""The route the path controller is given: a checked request route, planned so it can be followed.

Two rules, both closed form and both leaving routes the controller was trained on unchanged
(:func:`plan_route`), a third that needs the caption's pace (:func:`pace_route`) and a fourth that
needs its heading and what the caption asks (:func:`turn_round`):

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
- **A walk turns round on an arc to a waypoint behind it**: the controller learned its heading
  from real takes, whose next waypoint lies ahead of a forward walk and behind a backward one, so
  it walked backwards to an untimed waypoint more than :data:`TURN_BEARING` round from the way it
  was going (its heading at the start, the leg it came by after a waypoint: every moving frame,
  ``scripts/walk_direction.py``). For a caption read as a forward walk (:func:`walks_forward`),
  untimed waypoints on a half circle of :data:`TURN_RADIUS` towards the waypoint's side (every
  :data:`ARC_STEP` of the turn, until the waypoint lies within 60° of the way the arc goes) are
  put before it (:func:`turn_round`), so the controller walks a U-turn as the takes' turns go and
  then on forwards. A waypoint nearer than :data:`TURN_MIN_DISTANCE` is stepped back to; runs
  and jogs are left as they were (turned on such an arc, their bodies need more push from the
  floor than it gives: the replay's root force).

The waypoints a user gave stay where they are (and in :attr:`Motion.waypoints`); only the
controller and the snapping see the planned route.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from motion_env.motion.skeleton import FPS

__all__ = [
    "ARC_STEP",
    "BACKWARD",
    "MAX_UNTIMED_LEG",
    "MIN_PACE",
    "SPLIT_LEG",
    "START_ACCELERATION",
    "TURN_BEARING",
    "TURN_MIN_DISTANCE",
    "TURN_RADIUS",
    "WALKS",
    "needs_pace",
    "pace_route",
    "plan_route",
    "turn_round",
    "walks_forward",
]

MAX_UNTIMED_LEG = 6.0  # metres: longer untimed legs are split (routes used in training: 1-4 m legs)
SPLIT_LEG = 4.0  # metres: the longest piece of a split leg
MIN_PACE = 0.6  # m/s: a slower caption pace leaves untimed waypoints untimed (the slowest walks: 0.7)
# m/s^2: a character that starts its episode on a paced route (at rest) gets the time to reach the
# pace at this acceleration, pace / (2 a) seconds more (real runs reach 3 m/s in about a second).
START_ACCELERATION = 3.0
TURN_BEARING = math.radians(110.0)  # an untimed waypoint further round than this is turned to
TURN_RADIUS = 1.5  # metres: the U-turn's (tighter ones pass the replay less often: 1.0 m 38 of 48)
TURN_MIN_DISTANCE = 1.5  # metres: a nearer waypoint behind is stepped back to, as people do
ARC_STEP = math.radians(60.0)  # of the U-turn between two of its waypoints
WALKS = ("walk", "walk-turn-left", "walk-turn-right")  # the actions that turn round on an arc
BACKWARD = ("walk-back",)  # a walk that goes where its back is: never turned round


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


def walks_forward(probabilities: np.ndarray, actions: Sequence[str], unlabelled: str) -> bool:
    """Whether a caption reads as a forward walk: the caption adapter's action `probabilities`
    (A,) over `actions` (`unlabelled` among them: captions without a label) put over half of the
    labelled actions' share on :data:`WALKS` beyond what they put on a backward walk."""
    p = dict(zip(actions, np.asarray(probabilities, np.float64).tolist(), strict=True))
    labelled = 1.0 - p.get(unlabelled, 0.0)
    walks = sum(p.get(a, 0.0) for a in WALKS) - sum(p.get(a, 0.0) for a in BACKWARD)
    return labelled > 0.1 and walks / labelled > 0.5


def turn_round(route: np.ndarray | None, start: np.ndarray) -> np.ndarray | None:
    """A planned route (:func:`plan_route`) with a U-turn's untimed waypoints before each untimed
    waypoint that lies at least :data:`TURN_MIN_DISTANCE` from the point before it and more than
    :data:`TURN_BEARING` round from the way the character goes there (at the start its heading,
    after a waypoint the way the leg into it goes): module docstring. Else the route as it is.

    Args:
        route: (K, 3) planned route (NaN time = untimed), or None.
        start: (3,) x, z and heading of the character where the route starts.
    """
    if route is None or not len(route):
        return route
    x, z, heading = (float(v) for v in start[:3])
    rows, turned = [], False
    for wx, wz, t in route.tolist():  # a few waypoints: plain floats cost less than arrays here
        if math.isnan(t):
            arc = _u_turn(x, z, heading, wx, wz)
            turned |= bool(arc)
            rows += arc
            x, z = arc[-1][:2] if arc else (x, z)
        if math.hypot(wx - x, wz - z) > 1e-6:
            heading = math.atan2(wx - x, wz - z)  # the heading convention: 0 faces +Z
        rows.append([wx, wz, t])
        x, z = wx, wz
    return np.array(rows, np.float32) if turned else route


def _u_turn(x: float, z: float, heading: float, wx: float, wz: float) -> list[list[float]]:
    """The U-turn's waypoints (x, z, NaN) from (x, z) going `heading` to (wx, wz): none when the
    target is nearer than TURN_MIN_DISTANCE or within TURN_BEARING of the way ahead. Worked out in
    the heading frame (left, ahead) = ((cos, -sin), (sin, cos)), the points turned back to the world."""
    sin, cos = math.sin(heading), math.cos(heading)
    dx, dz = wx - x, wz - z
    lateral, forward = dx * cos - dz * sin, dx * sin + dz * cos
    if math.hypot(forward, lateral) < TURN_MIN_DISTANCE or abs(math.atan2(lateral, forward)) <= TURN_BEARING:
        return []
    side = 1.0 if lateral > -0.01 else -1.0  # towards the target's side (straight behind: left)
    arc = []
    for k in range(1, math.ceil(math.pi / ARC_STEP) + 1):
        turned = k * ARC_STEP
        across, along = TURN_RADIUS * side * (1.0 - math.cos(turned)), TURN_RADIUS * math.sin(turned)
        arc.append([x + across * cos + along * sin, z - across * sin + along * cos, math.nan])
        to_across, to_along = lateral - across, forward - along  # the target from the point
        going = side * math.sin(turned) * to_across + math.cos(turned) * to_along
        if going > math.cos(math.radians(60.0)) * math.hypot(to_across, to_along):
            break
    return arc
