"""Horizontal physics for whole clips: the root path shifted so that the floor's push passes
through the centre of mass.

The physics stage (:mod:`motion_env.generation.physics`) makes the vertical motion obey gravity
and leaves horizontal positions alone. But the floor pushes a standing body along the line from
the push's starting point (the centre of pressure) to its centre of mass (it cannot twist the
body), so in stance the horizontal acceleration of the centre of mass must be that line's share
of the vertical push, ``(c - p) * (a_y + g) / c_y`` (c: centre of mass, p: the centre of
pressure, both horizontal; c_y: its height), and in flight it is zero. The centre of pressure can
be anywhere in the support polygon, the convex hull of the sole points on the floor (the ankles
and toes the decoder flags in contact): p is the point of it nearest to where the body's own
acceleration puts it (:func:`_wanted_push`), so only a body whose push would have to start outside
its feet is corrected. A generated run misses that by about twice what a real run does, and the
MuJoCo replay then needs a torque at the root that the floor cannot give (the model card's
Naturalness, session 18). (Until session 25 p was the middle of one standing foot, the lower of
two: a still body standing between its feet was pushed about, its pelvis shaken at 1-3 m/s^2.)

:func:`balance_shift` finds a horizontal shift d(t) of the root path (the feet stage then keeps
the planted feet where they are, so the shift moves the centre of mass against them) that makes
the shifted body's horizontal acceleration as close to that as it can while the shift stays
small (:data:`BALANCE_WEIGHT`) and is zero at the start and at the route's waypoints, which the
clip keeps passing exactly: banded least squares over the frames, O(frames).

:class:`StreamBalance` is the same balance for the stream, causal: each token's frames get their
shift from the same least squares over a short window, which begins at the two frames already
emitted (their shift kept) and looks :data:`STREAM_HORIZON` frames past the token. The body of
those frames is not decoded yet: there the window asks only that the shift's velocity hold and
the shift stay small, which keeps the token from ending on a shift that runs away (as a whole
clip's later frames do; without it a long run's shift grows). Test runs streamed: plausible 21
-> 24 of 28 (seeds 0-3); the horizon's length (2-32 frames) and what it assumes of the stance
change one clip at most.
"""

from __future__ import annotations

import numpy as np

from motion_env.generation.height_plan import GRAVITY
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.least_squares import three_point_least_squares
from motion_env.motion.mass import COM_WEIGHTS, centre_of_mass
from motion_env.motion.skeleton import FPS, LEGS

__all__ = ["BALANCE_WEIGHT", "STREAM_HORIZON", "StreamBalance", "balance_shift"]

BALANCE_WEIGHT = 100.0
"""(m/s^2 per metre) What a shift of the path costs against a miss of the wanted horizontal
acceleration: 1 cm of shift as much as 1 m/s^2 of miss. Test and val, seeds 0-3: runs plausible
89 -> 100 % and 93 -> 100 %, the largest shift 12 cm."""
STREAM_HORIZON = 16
"""Frames past a streamed token that its balance looks at (the body there not yet decoded)."""
_MIN_HEIGHT = 0.3  # metres: a centre of mass lower than this is taken at this height (a crouch)
_ANCHOR = 1e10  # weight of a frame whose shift is held at zero
# The sole points' segments (a point with itself: the point) and triangles, by index (_support's order).
_PAIRS = np.array([(a, b) for a in range(4) for b in range(a, 4)])
_TRIANGLES = np.array([(a, b, c) for a in range(4) for b in range(a + 1, 4) for c in range(b + 1, 4)])
_LEGS = np.asarray(LEGS, np.int64)  # hip, knee, ankle, toe of each leg, for the compiled pass


def _support(joints: np.ndarray, contacts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre of mass (..., 3), the horizontal (x, z) positions of the four sole points (..., 4,
    2: left ankle, left toe, right ankle, right toe) and which of them bear weight (..., 4) bool,
    of (..., 22, 3) joints with (..., 4) contact channels (> 0.5 = on the floor)."""
    c = centre_of_mass(joints)
    points = np.stack(
        [joints[..., j, :][..., [0, 2]] for _, _, ankle, toe in LEGS for j in (ankle, toe)], axis=-2
    )
    return c, points, np.asarray(contacts) > 0.5


def _pressure_point(wanted: np.ndarray, points: np.ndarray, bearing: np.ndarray) -> np.ndarray:
    """(..., 2) the point of the support polygon (the convex hull of the bearing sole points)
    nearest to `wanted` (..., 2): where the floor's push can start. Inside the polygon it is
    `wanted` itself; outside, the nearest point of the segments between bearing points (the
    polygon's edges are among them, its inner segments are never nearer). Frames without a bearing
    point return `wanted` (they are in flight, where the push is zero anyway)."""
    w = wanted[..., None, :]
    pa, pb = points[..., _PAIRS[:, 0], :], points[..., _PAIRS[:, 1], :]  # (..., 10, 2): every segment
    ab = pb - pa
    t = np.clip(((w - pa) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    near = pa + t[..., None] * ab
    d = np.where(bearing[..., _PAIRS].all(-1), ((near - w) ** 2).sum(-1), np.inf)
    best = np.take_along_axis(near, d.argmin(-1)[..., None, None], axis=-2)[..., 0, :]
    corners = points[..., _TRIANGLES, :]  # (..., 4, 3, 2): the hull is the union of these triangles
    inside = bearing[..., _TRIANGLES].all(-1) & _in_triangle(w, *(corners[..., k, :] for k in range(3)))
    return np.where((inside.any(-1) | ~bearing.any(-1))[..., None], wanted, best)


def _in_triangle(q: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """(...) bool: q inside (or on) the triangle a, b, c (all (..., 2)); never for a flat one (its
    three points on a line: the segments between them stand for it)."""

    def side(p0: np.ndarray, p1: np.ndarray, r: np.ndarray) -> np.ndarray:
        return (p1[..., 0] - p0[..., 0]) * (r[..., 1] - p0[..., 1]) - (p1[..., 1] - p0[..., 1]) * (
            r[..., 0] - p0[..., 0]
        )

    area = side(a, b, c)
    s1, s2, s3 = side(a, b, q) * area, side(b, c, q) * area, side(c, a, q) * area
    return (np.abs(area) > 1e-8) & (s1 >= 0) & (s2 >= 0) & (s3 >= 0)


def _wanted_push(
    c: np.ndarray, accel: np.ndarray, k: np.ndarray, points: np.ndarray, bearing: np.ndarray
) -> np.ndarray:
    """(..., 2) the horizontal acceleration (x, z) the floor's push gives the centre of mass `c`
    (..., 3) with stiffness `k` (...): k (c - p), p the point of the support polygon nearest to
    where the body's own acceleration `accel` (..., 3) would put it (c - accel / k). A body whose
    push can start anywhere under its feet needs no correction; one whose push would have to start
    outside them is pulled back to their edge. 0 in flight (k = 0). Compiled
    (:mod:`motion_env.generation.balance_jit`) where numba runs, the same numbers."""
    if jit_enabled():
        from motion_env.generation.balance_jit import wanted_push

        note_first_compile(wanted_push, "the floor's push")
        f64 = np.float64  # contiguous arrays of one layout: numba compiles one version
        out = wanted_push(
            np.ascontiguousarray(c, f64).reshape(-1, 3),
            np.ascontiguousarray(accel, f64).reshape(-1, 3),
            np.ascontiguousarray(k, f64).reshape(-1),
            np.ascontiguousarray(points, f64).reshape(-1, 4, 2),
            np.ascontiguousarray(bearing, bool).reshape(-1, 4),
            _PAIRS,
            _TRIANGLES,
        )
        return out.reshape(*np.shape(k), 2)
    ch, ah = c[..., [0, 2]], accel[..., [0, 2]]
    safe = np.where(k > 0.0, k, 1.0)[..., None]
    p = _pressure_point(ch - ah / safe, points, bearing)
    return np.where((k > 0.0)[..., None], k[..., None] * (ch - p), 0.0)


def _stiffness(accel_y: np.ndarray, com_y: np.ndarray, stance: np.ndarray) -> np.ndarray:
    """k = (a_y + g) / c_y in stance, 0 in flight: the horizontal acceleration the floor's push
    gives per metre between the centre of pressure and the centre of mass."""
    return np.where(stance, (accel_y + GRAVITY) / np.maximum(com_y, _MIN_HEIGHT), 0.0)


def balance_shift(joints: np.ndarray, contacts: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """(T, 2) float64 horizontal shift (x, z) of a clip's root path.

    Args:
        joints: (T, 22, 3) the composed body on its root path (before the feet stage).
        contacts: (T, 4) the decoded contact channels (left ankle, left toe, right ankle, right
            toe; > 0.5 = in contact): a frame with a flagged point is in stance, the push
            starting within the convex hull of the flagged points.
        anchors: frames whose shift is zero (the start, the waypoints' frames).
    """
    j = np.asarray(joints, dtype=np.float64)
    t_len = len(j)
    if t_len < 3:
        return np.zeros((t_len, 2))
    c, points, bearing = _support(j, np.asarray(contacts))
    accel = np.zeros_like(c)
    accel[1:-1] = (c[2:] - 2.0 * c[1:-1] + c[:-2]) * FPS**2
    k = _stiffness(accel[:, 1], c[:, 1], bearing.any(axis=-1))
    # Each frame t in 1..T-2: FPS^2 (d[t-1] - 2 d[t] + d[t+1]) - k d[t] = k (c - p) - a (horizontal).
    rhs = _wanted_push(c, accel, k, points, bearing) - accel[:, [0, 2]]
    f2 = float(FPS**2)
    coef = np.stack([np.full(t_len, f2), -2.0 * f2 - k, np.full(t_len, f2)], axis=1)[1:-1]  # (T-2, 3)
    held = np.asarray(anchors, dtype=np.int64)
    held = held[(held >= 0) & (held < t_len)]
    weight = np.full(t_len, BALANCE_WEIGHT**2)
    weight[held] += _ANCHOR
    shift = three_point_least_squares(coef, rhs[1:-1], weight, np.zeros((t_len, 2)))
    shift[held] = 0.0  # within 1e-6 m of it already
    return shift


class StreamBalance:
    """:func:`balance_shift` for the stream, one token at a time (module docstring).

    Per character it keeps what the next token's first equations read of the frames already
    emitted: the shift and the (unshifted) centre of mass of the last two, the sole points and
    which of them bear weight of the last.
    """

    def __init__(self, batch_size: int) -> None:
        self._shift = np.zeros((batch_size, 2, 2))
        self._com = np.full((batch_size, 2, 3), np.nan)  # nan: no frame emitted yet
        self._points = np.zeros((batch_size, 4, 2))
        self._bearing = np.zeros((batch_size, 4), bool)

    def reset(self, i: int) -> None:
        """Character i starts again (its first frame's shift is zero, as a whole clip's)."""
        self._shift[i], self._com[i] = 0.0, np.nan

    def shift_rows(
        self,
        rows: np.ndarray,
        joints: np.ndarray,
        contacts: np.ndarray,
        anchors: list[np.ndarray],
        held: np.ndarray | None = None,
    ) -> np.ndarray:
        """(N, R, 2) horizontal shift (x, z) of the token just composed for each of `rows`.

        Args:
            rows: (N,) the characters.
            joints: (N, R, 22, 3) their token's frames, composed on the root path.
            contacts: (N, R, 4) its decoded contact channels.
            anchors: per row, the frames (counted from the token's first) whose shift is zero:
                waypoints within the token and the horizon after it.
            held: (N,) bool, rows not shifted (joint control: as whole clips, not balanced).
        """
        joints = np.asarray(joints, np.float64)
        flags = np.asarray(contacts) > 0.5
        rate = joints.shape[1]
        span = 2 + rate + STREAM_HORIZON  # the window: 2 frames emitted, the token, the horizon
        if jit_enabled() and rate >= 2:  # (a one-frame token keeps numpy's broadcast of it)
            equations = self._equations_compiled(rows, joints, flags)
        else:
            equations = self._equations(rows, joints, flags)
        coef, rows_rhs, pull, target, first = equations
        ahead = [np.asarray(f, np.int64) for f in anchors]
        ahead = [f[(f >= 0) & (f < span - 2)] for f in ahead]  # the window's frames after the emitted
        for r, frames in enumerate(ahead):
            pull[r, frames + 2] += _ANCHOR
        shift = three_point_least_squares(coef, rows_rhs, pull, target)[:, 2 : 2 + rate]
        shift[first, 0] = 0.0
        for r, frames in enumerate(ahead):
            shift[r, frames[frames < rate]] = 0.0  # within 1e-6 m of it already
        if held is not None:
            shift[held] = 0.0
        self._shift[rows] = shift[:, -2:]
        return shift

    def _equations(
        self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The least squares of the new token of characters `rows` ((N, R, 22, 3) float64 joints,
        (N, R, 4) bool contacts) before the anchors ahead: (N, S - 2, 3) coefficients, (N, S - 2, 2)
        right-hand sides, (N, S) pulls, (N, S, 2) targets, (N,) first tokens, S the window's
        frames; the state of the last frames moves on. Compiled twin:
        :func:`motion_env.generation.balance_jit.stream_equations`."""
        n, rate = joints.shape[:2]
        span = 2 + rate + STREAM_HORIZON  # the window: 2 frames emitted, the token, the horizon
        c, points, bearing = _support(joints, flags)
        # The equations centred on the token's frames -1 .. rate - 2 read frames -2 .. rate - 1.
        com = np.concatenate([self._com[rows], c], axis=1)
        accel = (com[:, 2:] - 2.0 * com[:, 1:-1] + com[:, :-2]) * FPS**2
        on = np.concatenate([self._points[rows, None], points[:, :-1]], axis=1)
        bears = np.concatenate([self._bearing[rows, None], bearing[:, :-1]], axis=1)
        k = _stiffness(accel[..., 1], com[:, 1:-1, 1], bears.any(axis=-1))
        known = np.isfinite(accel).all(axis=-1)  # not on a first token, before its first frame
        known_accel = np.where(known[..., None], accel, 0.0)
        rhs = _wanted_push(com[:, 1:-1], known_accel, k, on, bears) - known_accel[..., [0, 2]]
        f2 = float(FPS**2)
        # The horizon's equations (k 0, rhs 0): the shift's velocity holds.
        k_all = np.concatenate([np.where(known, k, 0.0), np.zeros((n, span - 2 - rate))], axis=1)
        coef = np.stack([np.full_like(k_all, f2), -2.0 * f2 - k_all, np.full_like(k_all, f2)], -1)
        coef[:, :rate] *= known[..., None]  # an equation on frames not emitted drops out
        rows_rhs = np.zeros((n, span - 2, 2))
        rows_rhs[:, :rate] = np.where(known[..., None], rhs, 0.0)
        pull = np.full((n, span), BALANCE_WEIGHT**2)
        pull[:, :2] += _ANCHOR  # the emitted frames keep their shift
        first = np.isnan(self._com[rows, 1, 0])
        pull[first, 2] += _ANCHOR  # a first frame is not shifted
        target = np.zeros((n, span, 2))
        target[:, :2] = self._shift[rows]
        self._com[rows], self._points[rows], self._bearing[rows] = c[:, -2:], points[:, -1], bearing[:, -1]
        return coef, rows_rhs, pull, target, first

    def _equations_compiled(
        self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_equations` as one compiled pass (:mod:`~motion_env.generation.balance_jit`)."""
        from motion_env.generation.balance_jit import stream_equations

        note_first_compile(stream_equations, "the stream's balance")
        constants = (float(FPS**2), GRAVITY, _MIN_HEIGHT, BALANCE_WEIGHT**2, _ANCHOR, STREAM_HORIZON)
        state = (self._shift, self._com, self._points, self._bearing)
        return stream_equations(
            np.asarray(rows, np.int64), np.ascontiguousarray(joints), np.ascontiguousarray(flags), *state,
            COM_WEIGHTS, _LEGS, _PAIRS, _TRIANGLES, constants,
        )  # fmt: skip
