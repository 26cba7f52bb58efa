"""The two-bone IK compiled (numba): :func:`~motion_env.generation.feet.two_bone_ik`'s arithmetic
for one limb, and over rows of limbs.

On numpy the solve is some sixty whole-array operations, whatever the number of limbs: for the few
legs and arms of a stream's token (the feet's pins, the arms' bone lengths, the body's placement)
that is dispatch, about 0.3 ms a call. Compiled, a limb is its arithmetic. The operations are
numpy's, in its order, on float64: the same numbers to the bit (``tests/generation/test_recompose.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["dot", "norm", "solve", "solve_rows"]

_EPS = 1e-8  # motion_env.motion.validation.EPS (qbetween's floor)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def dot(a0, a1, a2, b0, b1, b2):
    """(a0, a1, a2) . (b0, b1, b2), summed in numpy's order for a last axis of three."""
    return a0 * b0 + a1 * b1 + a2 * b2


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def norm(v0, v1, v2):
    """``np.linalg.norm`` of one 3-vector, summed in numpy's order."""
    return math.sqrt(dot(v0, v1, v2, v0, v1, v2))


@njit(cache=True, nogil=True, error_model="numpy")
def solve(  # noqa: PLR0913 (one limb's numbers: the three joints, the target and the hint)
    h0, h1, h2, k0, k1, k2, a0, a1, a2, t0, t1, t2, n0, n1, n2, has_hint, hint_weight, hint_length, hint_fill
):  # fmt: skip
    """One limb of :func:`~motion_env.generation.feet.two_bone_ik`: the root (h), middle (k) and end
    (a) joints, the target (t) and the bend hint (n, read when `has_hint`) -> the new middle and
    end joints (six numbers)."""
    th0, th1, th2 = k0 - h0, k1 - h1, k2 - h2  # the upper bone
    sh0, sh1, sh2 = a0 - k0, a1 - k1, a2 - k2  # the lower bone
    l1 = math.sqrt(dot(th0, th1, th2, th0, th1, th2))
    l2 = math.sqrt(dot(sh0, sh1, sh2, sh0, sh1, sh2))
    to0, to1, to2 = t0 - h0, t1 - h1, t2 - h2
    d = math.sqrt(dot(to0, to1, to2, to0, to1, to2))
    dc = min(max(d, abs(l1 - l2) + 1e-4), l1 + l2 - 1e-4)
    du = max(d, 1e-9)
    u0, u1, u2 = to0 / du, to1 / du, to2 / du
    g0, g1, g2 = a0 - h0, a1 - h1, a2 - h2  # the limb's original axis
    gn = max(math.sqrt(dot(g0, g1, g2, g0, g1, g2)), 1e-9)
    x0, x1, x2 = g0 / gn, g1 / gn, g2 / gn
    along = dot(th0, th1, th2, x0, x1, x2)
    b0, b1, b2 = th0 - along * x0, th1 - along * x1, th2 - along * x2  # the bend
    a = (l1 * l1 - l2 * l2 + dc * dc) / (2 * dc)
    h = math.sqrt(max(l1 * l1 - a * a, 0.0))
    if has_hint:
        weight = hint_weight
        if hint_fill:
            missing = min(max(1.0 - math.sqrt(dot(b0, b1, b2, b0, b1, b2)) / max(h, 1e-9), 0.0), 1.0)
            weight = hint_weight + hint_fill * h * (missing * missing)
        hn = max(math.sqrt(dot(n0, n1, n2, n0, n1, n2)), max(hint_length, 1e-9))
        b0, b1, b2 = b0 + weight * n0 / hn, b1 + weight * n1 / hn, b2 + weight * n2 / hn
    # qbetween(axis, u), then the bend rotated by it (qrot)
    s0, s1 = dot(x0, x1, x2, x0, x1, x2), dot(u0, u1, u2, u0, u1, u2)
    w = math.sqrt(s0 * s1) + dot(x0, x1, x2, u0, u1, u2)
    q1, q2, q3 = x1 * u2 - x2 * u1, x2 * u0 - x0 * u2, x0 * u1 - x1 * u0
    norm = math.sqrt(((w * w + q1 * q1) + q2 * q2) + q3 * q3)
    if norm < 1e-6 * max(math.sqrt(s0 * s1), _EPS):  # opposite directions: a half turn
        m0, m1, m2 = abs(x0), abs(x1), abs(x2)
        e0 = 1.0 if m0 <= m1 and m0 <= m2 else 0.0  # the axis least aligned (argmin's first)
        e1 = 1.0 if e0 == 0.0 and m1 <= m2 else 0.0
        e2 = 1.0 if e0 == 0.0 and e1 == 0.0 else 0.0
        q1, q2, q3 = x1 * e2 - x2 * e1, x2 * e0 - x0 * e2, x0 * e1 - x1 * e0
        qn = max(math.sqrt(dot(q1, q2, q3, q1, q2, q3)), _EPS)
        w, q1, q2, q3 = 0.0, q1 / qn, q2 / qn, q3 / qn
        norm = math.sqrt(((w * w + q1 * q1) + q2 * q2) + q3 * q3)
    norm = max(norm, _EPS)
    w, q1, q2, q3 = w / norm, q1 / norm, q2 / norm, q3 / norm
    c0, c1, c2 = q2 * b2 - q3 * b1, q3 * b0 - q1 * b2, q1 * b1 - q2 * b0
    e0, e1, e2 = q2 * c2 - q3 * c1, q3 * c0 - q1 * c2, q1 * c1 - q2 * c0
    p0, p1, p2 = b0 + 2.0 * (w * c0 + e0), b1 + 2.0 * (w * c1 + e1), b2 + 2.0 * (w * c2 + e2)
    along = dot(p0, p1, p2, u0, u1, u2)
    p0, p1, p2 = p0 - along * u0, p1 - along * u1, p2 - along * u2
    pn = math.sqrt(dot(p0, p1, p2, p0, p1, p2))
    if pn > 1e-6:
        pm = max(pn, 1e-9)
        p0, p1, p2 = p0 / pm, p1 / pm, p2 / pm
    else:  # a straight limb with no hint has no bend plane: bend along the original lower bone
        along = dot(sh0, sh1, sh2, u0, u1, u2)
        p0, p1, p2 = sh0 - along * u0, sh1 - along * u1, sh2 - along * u2
    pm = max(math.sqrt(dot(p0, p1, p2, p0, p1, p2)), 1e-9)
    p0, p1, p2 = p0 / pm, p1 / pm, p2 / pm
    return (
        h0 + a * u0 + h * p0, h1 + a * u1 + h * p1, h2 + a * u2 + h * p2,
        h0 + dc * u0, h1 + dc * u1, h2 + dc * u2,
    )  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def solve_rows(hip, knee, ankle, target, hint, has_hint, hint_weight, hint_length, hint_fill):
    """:func:`solve` for each of (M, 3) float64 rows: -> (M, 3) new middle joints, (M, 3) new ends."""
    new_knee, new_ankle = np.empty_like(knee), np.empty_like(ankle)
    for m in range(hip.shape[0]):
        n0 = hint[m, 0] if has_hint else 0.0
        n1 = hint[m, 1] if has_hint else 0.0
        n2 = hint[m, 2] if has_hint else 0.0
        k = solve(
            hip[m, 0], hip[m, 1], hip[m, 2], knee[m, 0], knee[m, 1], knee[m, 2],
            ankle[m, 0], ankle[m, 1], ankle[m, 2], target[m, 0], target[m, 1], target[m, 2],
            n0, n1, n2, has_hint, hint_weight, hint_length, hint_fill,
        )  # fmt: skip
        new_knee[m, 0], new_knee[m, 1], new_knee[m, 2] = k[0], k[1], k[2]
        new_ankle[m, 0], new_ankle[m, 1], new_ankle[m, 2] = k[3], k[4], k[5]
    return new_knee, new_ankle
