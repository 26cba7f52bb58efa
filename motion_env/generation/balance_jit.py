"""The balance compiled (numba): the floor's push (what :func:`~motion_env.generation.balance._wanted_push`
does with numpy's operations, frame by frame) and the stream's equations around it
(``StreamBalance._equations``: the centre of mass of the window, its acceleration, the floor's
stiffness and push, the rows, pulls and targets of the least squares, whose banded solve stays
LAPACK's).

On numpy a stream token's push is some fifty operations on the support polygon of its frames
(every segment between the four sole points, every triangle of them), and its equations some
forty more on arrays of a few numbers: about 0.5 ms of one env's token, raw, nearly all dispatch.
Compiled, a frame is its arithmetic. The operations are numpy's, in its order, on float64 (NaN
where numpy's would give NaN: a stream's first token reads frames not emitted yet, whose
equations the balance then drops): the same numbers to the bit (``tests/generation/test_balance.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.generation.ground_jit import centre
from motion_env.models.jit_math import clip

__all__ = ["stream_equations", "wanted_push"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _side(p0x, p0y, p1x, p1y, rx, ry):
    """balance._in_triangle's side of r against the line p0 -> p1."""
    return (p1x - p0x) * (ry - p0y) - (p1y - p0y) * (rx - p0x)


@njit(cache=True, nogil=True, error_model="numpy")
def _pressure_point(wx, wy, points, bearing, pairs, triangles):
    """balance._pressure_point of one frame: the point of the support polygon nearest to (wx, wy)."""
    any_bearing = False
    for s in range(points.shape[0]):
        any_bearing = any_bearing or bearing[s]
    if not any_bearing:
        return wx, wy
    for n in range(triangles.shape[0]):
        a, b, c = triangles[n, 0], triangles[n, 1], triangles[n, 2]
        if not (bearing[a] and bearing[b] and bearing[c]):
            continue
        ax, ay, bx, by = points[a, 0], points[a, 1], points[b, 0], points[b, 1]
        cx, cy = points[c, 0], points[c, 1]
        area = _side(ax, ay, bx, by, cx, cy)
        s1 = _side(ax, ay, bx, by, wx, wy) * area
        s2 = _side(bx, by, cx, cy, wx, wy) * area
        s3 = _side(cx, cy, ax, ay, wx, wy) * area
        if abs(area) > 1e-8 and s1 >= 0 and s2 >= 0 and s3 >= 0:
            return wx, wy
    best, best_x, best_y = np.inf, 0.0, 0.0
    found = False
    for n in range(pairs.shape[0]):
        a, b = pairs[n, 0], pairs[n, 1]
        abx, aby = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1]
        along = ((wx - points[a, 0]) * abx + (wy - points[a, 1]) * aby) / max(abx * abx + aby * aby, 1e-12)
        t = clip(along, 0.0, 1.0)
        nx, ny = points[a, 0] + t * abx, points[a, 1] + t * aby
        d = (nx - wx) ** 2 + (ny - wy) ** 2 if bearing[a] and bearing[b] else np.inf
        # np.argmin: the first NaN, else the first smallest (segment 0 where every one is inf)
        if not found and (math.isnan(d) or d < best or n == 0):
            best, best_x, best_y = d, nx, ny
            found = math.isnan(d)
    return best_x, best_y


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _push(cx, cz, ax, az, k, points, bearing, pairs, triangles):
    """balance._wanted_push of one frame: the floor's push (x, z) on the centre of mass (cx, cz)."""
    safe = k if k > 0.0 else 1.0
    px, pz = _pressure_point(cx - ax / safe, cz - az / safe, points, bearing, pairs, triangles)
    if k > 0.0:
        return k * (cx - px), k * (cz - pz)
    return 0.0, 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def wanted_push(c, accel, k, points, bearing, pairs, triangles):
    """balance._wanted_push of M frames: centre of mass `c` (M, 3), acceleration `accel` (M, 3),
    stiffness `k` (M,), sole points (M, 4, 2) and which bear weight (M, 4) -> (M, 2)."""
    out = np.empty((c.shape[0], 2))
    for m in range(c.shape[0]):
        out[m, 0], out[m, 1] = _push(
            c[m, 0], c[m, 2], accel[m, 0], accel[m, 2], k[m], points[m], bearing[m], pairs, triangles
        )
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def stream_equations(  # noqa: PLR0913 (one compiled pass: the balance's arrays and constants)
    rows, joints, flags, shift, com, points, bearing, weights, legs, pairs, triangles, constants,
):  # fmt: skip
    """What ``StreamBalance.shift_rows`` hands the least squares for the new token of characters
    `rows` ((N, R, 22, 3) float64 `joints`, (N, R, 4) bool contact `flags`), before the anchors
    ahead: (N, S - 2, 3) coefficients, (N, S - 2, 2) right-hand sides, (N, S) pulls, (N, S, 2)
    targets and (N,) first tokens, S the window's frames (two emitted, the token, the horizon).
    The state of the last frames (`com` (B, 2, 3), `points` (B, 4, 2), `bearing` (B, 4)) moves
    on in place; `shift` (B, 2, 2) is read."""
    f2, gravity, min_height, pull_weight, anchor, horizon = constants
    n, rate = joints.shape[0], joints.shape[1]
    span = 2 + rate + horizon
    coef = np.empty((n, span - 2, 3))
    rhs = np.zeros((n, span - 2, 2))
    pull = np.full((n, span), pull_weight)
    target = np.zeros((n, span, 2))
    first = np.empty(n, np.bool_)
    frames = joints.reshape((n * rate, joints.shape[2], 3))
    window = np.empty((rate + 2, 3))  # the centre of mass of frames -2 .. rate - 1
    on, bears = np.empty((rate, 4, 2)), np.empty((rate, 4), np.bool_)  # frames -1 .. rate - 2
    for i in range(n):
        b = rows[i]
        for f in range(2):
            for d in range(3):
                window[f, d] = com[b, f, d]
        for t in range(rate):
            for d in range(3):
                window[t + 2, d] = centre(frames, i * rate + t, weights, d)
        for s in range(4):  # the sole points of frame -1, then of the token's frames but its last
            on[0, s, 0], on[0, s, 1], bears[0, s] = points[b, s, 0], points[b, s, 1], bearing[b, s]
        for t in range(1, rate):
            for s in range(4):
                joint = legs[s // 2, 2 + s % 2]
                on[t, s, 0], on[t, s, 1] = joints[i, t - 1, joint, 0], joints[i, t - 1, joint, 2]
                bears[t, s] = flags[i, t - 1, s]
        for t in range(rate):  # the equation centred on frame t - 1
            ax = (window[t + 2, 0] - 2.0 * window[t + 1, 0] + window[t, 0]) * f2
            ay = (window[t + 2, 1] - 2.0 * window[t + 1, 1] + window[t, 1]) * f2
            az = (window[t + 2, 2] - 2.0 * window[t + 1, 2] + window[t, 2]) * f2
            stance = bears[t, 0] or bears[t, 1] or bears[t, 2] or bears[t, 3]
            k = (ay + gravity) / max(window[t + 1, 1], min_height) if stance else 0.0
            known = math.isfinite(ax) and math.isfinite(ay) and math.isfinite(az)
            if not known:  # on frames not emitted yet (a first token's): the equation drops out
                ax, ay, az = 0.0, 0.0, 0.0
            px, pz = _push(window[t + 1, 0], window[t + 1, 2], ax, az, k, on[t], bears[t], pairs, triangles)
            kept = 1.0 if known else 0.0
            k = k if known else 0.0
            coef[i, t, 0], coef[i, t, 1], coef[i, t, 2] = f2 * kept, (-2.0 * f2 - k) * kept, f2 * kept
            if known:
                rhs[i, t, 0], rhs[i, t, 1] = px - ax, pz - az
        for t in range(rate, span - 2):  # the horizon's: the shift's velocity holds
            coef[i, t, 0], coef[i, t, 1], coef[i, t, 2] = f2, -2.0 * f2, f2
        pull[i, 0] += anchor  # the emitted frames keep their shift
        pull[i, 1] += anchor
        first[i] = math.isnan(com[b, 1, 0])
        if first[i]:
            pull[i, 2] += anchor  # a first frame is not shifted
        for f in range(2):
            target[i, f, 0], target[i, f, 1] = shift[b, f, 0], shift[b, f, 1]
        for f in range(2):
            for d in range(3):
                com[b, f, d] = window[rate + f, d]
        for s in range(4):
            joint = legs[s // 2, 2 + s % 2]
            points[b, s, 0], points[b, s, 1] = joints[i, rate - 1, joint, 0], joints[i, rate - 1, joint, 2]
            bearing[b, s] = flags[i, rate - 1, s]
    return coef, rhs, pull, target, first
