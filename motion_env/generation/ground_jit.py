"""The body placed on the floor, compiled (numba): what :func:`place_body
<motion_env.generation.ground.place_body>` does with numpy's operations, frame by frame.

On numpy the placement is a few shift-then-ground passes over the frames not placed yet, each some
sixty operations on a handful of vectors (the soles, how far each leg reaches, the legs'
re-solve, the centre of mass): about 3 ms of a stream's token and 4 ms of a 200-frame clip, most
of it dispatch. Compiled, a frame's passes are their arithmetic. The operations are numpy's, in
its order, on float64: the same numbers to the bit (``tests/generation/test_physics.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["place_frames"]

_EPS = 1e-8  # motion_env.motion.validation.EPS (qbetween's floor)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _dot(a0, a1, a2, b0, b1, b2):
    return a0 * b0 + a1 * b1 + a2 * b2


@njit(cache=True, nogil=True, error_model="numpy")
def _centre_height(out, f, weights):
    """The centre of mass's height of frame f (:func:`~motion_env.motion.mass.centre_of_mass`)."""
    total = 0.0
    for j in range(weights.shape[0]):
        total += weights[j] * out[f, j, 1]
    return total


@njit(cache=True, nogil=True, error_model="numpy")
def _sole(out, f, ankle, toe, flat_ankle, heel_back, toe_front, radius):
    """:func:`~motion_env.generation.ground.sole_heights` of one foot of frame f."""
    b0 = out[f, toe, 0] - out[f, ankle, 0]
    b1 = out[f, toe, 1] - out[f, ankle, 1]
    b2 = out[f, toe, 2] - out[f, ankle, 2]
    length = math.sqrt(_dot(b0, b1, b2, b0, b1, b2))
    reach = math.sqrt(max(length * length - flat_ankle * flat_ankle, 1e-6))
    turn = math.atan2(b1, math.hypot(b0, b2)) - math.atan2(-flat_ankle, reach)
    up = radius - flat_ankle
    s, c = math.sin(turn), math.cos(turn)
    lowest = min(-heel_back * s + up * c, (reach + toe_front) * s + up * c)
    return out[f, ankle, 1] + lowest - radius


@njit(cache=True, nogil=True, error_model="numpy")
def _deepest_reach(out, f, hip, knee, ankle, max_stretch):
    """:func:`~motion_env.generation.ground.deepest_reach` of one leg of frame f."""
    l0 = out[f, ankle, 0] - out[f, hip, 0]
    l1 = out[f, ankle, 1] - out[f, hip, 1]
    l2 = out[f, ankle, 2] - out[f, hip, 2]
    t0 = out[f, knee, 0] - out[f, hip, 0]
    t1 = out[f, knee, 1] - out[f, hip, 1]
    t2 = out[f, knee, 2] - out[f, hip, 2]
    s0 = out[f, ankle, 0] - out[f, knee, 0]
    s1 = out[f, ankle, 1] - out[f, knee, 1]
    s2 = out[f, ankle, 2] - out[f, knee, 2]
    length = math.sqrt(_dot(t0, t1, t2, t0, t1, t2)) + math.sqrt(_dot(s0, s1, s2, s0, s1, s2))
    squared = _dot(l0, l1, l2, l0, l1, l2)
    reach = max(max_stretch * length, math.sqrt(squared))
    return -l1 - math.sqrt(max(l1 * l1 + reach * reach - squared, 0.0))


@njit(cache=True, nogil=True, error_model="numpy")
def _lift_leg(out, f, hip, knee, ankle, toe, lift, hint_weight, hint_length):
    """Frame f's leg re-solved for its ankle moved up by `lift` (in place): the
    :func:`~motion_env.generation.feet.two_bone_ik` of :func:`~motion_env.generation.ground.ground_feet`,
    the toes' horizontal direction as the bend hint."""
    h0, h1, h2 = out[f, hip, 0], out[f, hip, 1], out[f, hip, 2]
    k0, k1, k2 = out[f, knee, 0], out[f, knee, 1], out[f, knee, 2]
    a0, a1, a2 = out[f, ankle, 0], out[f, ankle, 1], out[f, ankle, 2]
    hint0, hint2 = out[f, toe, 0] - a0, out[f, toe, 2] - a2  # the hint's height is 0
    th0, th1, th2 = k0 - h0, k1 - h1, k2 - h2  # thigh
    sh0, sh1, sh2 = a0 - k0, a1 - k1, a2 - k2  # shin
    l1 = math.sqrt(_dot(th0, th1, th2, th0, th1, th2))
    l2 = math.sqrt(_dot(sh0, sh1, sh2, sh0, sh1, sh2))
    to0, to1, to2 = a0 - h0, (a1 + lift) - h1, a2 - h2
    d = math.sqrt(_dot(to0, to1, to2, to0, to1, to2))
    dc = min(max(d, abs(l1 - l2) + 1e-4), l1 + l2 - 1e-4)
    du = max(d, 1e-9)
    u0, u1, u2 = to0 / du, to1 / du, to2 / du
    g0, g1, g2 = a0 - h0, a1 - h1, a2 - h2  # the leg's original axis
    gn = max(math.sqrt(_dot(g0, g1, g2, g0, g1, g2)), 1e-9)
    x0, x1, x2 = g0 / gn, g1 / gn, g2 / gn
    along = _dot(th0, th1, th2, x0, x1, x2)
    b0, b1, b2 = th0 - along * x0, th1 - along * x1, th2 - along * x2
    a = (l1 * l1 - l2 * l2 + dc * dc) / (2 * dc)
    h = math.sqrt(max(l1 * l1 - a * a, 0.0))
    hn = max(math.sqrt(_dot(hint0, 0.0, hint2, hint0, 0.0, hint2)), max(hint_length, 1e-9))
    b0, b1, b2 = b0 + hint_weight * hint0 / hn, b1 + hint_weight * 0.0 / hn, b2 + hint_weight * hint2 / hn
    # qbetween(axis, u), then qrot of the bend by it
    s0, s1 = _dot(x0, x1, x2, x0, x1, x2), _dot(u0, u1, u2, u0, u1, u2)
    w = math.sqrt(s0 * s1) + _dot(x0, x1, x2, u0, u1, u2)
    q1, q2, q3 = x1 * u2 - x2 * u1, x2 * u0 - x0 * u2, x0 * u1 - x1 * u0
    norm = math.sqrt(((w * w + q1 * q1) + q2 * q2) + q3 * q3)
    if norm < 1e-6 * max(math.sqrt(s0 * s1), _EPS):  # opposite directions: a half turn
        m0, m1, m2 = abs(x0), abs(x1), abs(x2)
        e0, e1, e2 = 0.0, 0.0, 0.0
        if m0 <= m1 and m0 <= m2:
            e0 = 1.0
        elif m1 <= m2:
            e1 = 1.0
        else:
            e2 = 1.0
        q1, q2, q3 = x1 * e2 - x2 * e1, x2 * e0 - x0 * e2, x0 * e1 - x1 * e0
        qn = max(math.sqrt(_dot(q1, q2, q3, q1, q2, q3)), _EPS)
        w, q1, q2, q3 = 0.0, q1 / qn, q2 / qn, q3 / qn
        norm = math.sqrt(((w * w + q1 * q1) + q2 * q2) + q3 * q3)
    norm = max(norm, _EPS)
    w, q1, q2, q3 = w / norm, q1 / norm, q2 / norm, q3 / norm
    c0, c1, c2 = q2 * b2 - q3 * b1, q3 * b0 - q1 * b2, q1 * b1 - q2 * b0  # uv
    e0, e1, e2 = q2 * c2 - q3 * c1, q3 * c0 - q1 * c2, q1 * c1 - q2 * c0  # uuv
    p0, p1, p2 = b0 + 2.0 * (w * c0 + e0), b1 + 2.0 * (w * c1 + e1), b2 + 2.0 * (w * c2 + e2)
    along = _dot(p0, p1, p2, u0, u1, u2)
    p0, p1, p2 = p0 - along * u0, p1 - along * u1, p2 - along * u2
    pn = math.sqrt(_dot(p0, p1, p2, p0, p1, p2))
    if pn > 1e-6:
        pm = max(pn, 1e-9)
        p0, p1, p2 = p0 / pm, p1 / pm, p2 / pm
    else:  # a straight leg with no hint: bend along the original shin
        along = _dot(sh0, sh1, sh2, u0, u1, u2)
        p0, p1, p2 = sh0 - along * u0, sh1 - along * u1, sh2 - along * u2
    pm = max(math.sqrt(_dot(p0, p1, p2, p0, p1, p2)), 1e-9)
    p0, p1, p2 = p0 / pm, p1 / pm, p2 / pm
    n0, n1, n2 = h0 + dc * u0, h1 + dc * u1, h2 + dc * u2  # the new ankle
    out[f, toe, 0] += n0 - a0
    out[f, toe, 1] += n1 - a1
    out[f, toe, 2] += n2 - a2
    out[f, knee, 0] = h0 + a * u0 + h * p0
    out[f, knee, 1] = h1 + a * u1 + h * p1
    out[f, knee, 2] = h2 + a * u2 + h * p2
    out[f, ankle, 0], out[f, ankle, 1], out[f, ankle, 2] = n0, n1, n2


@njit(cache=True, nogil=True, error_model="numpy")
def place_frames(  # noqa: PLR0913 (one compiled loop: the parameters are its arrays and constants)
    joints, heights, down, clearance, flat_ankle, pull, has_pull, weights, legs, passes, tolerance,
    sole_shape, max_stretch, hint_weight, hint_length,
):  # fmt: skip
    """:func:`~motion_env.generation.ground.place_body` of (N, 22, 3) float64 `joints`: heights
    (N,), down (N, 2) bool, clearance (N, 2), flat_ankle (N,), pull (N, 2) (read when
    `has_pull`); the COM_WEIGHTS (22,), LEGS (2, 4), the passes and their tolerance, the sole's
    (HEEL_BACK, TOE_FRONT, SOLE_RADIUS), MAX_STRETCH and the legs' bend hint (weight, length)."""
    heel_back, toe_front, radius = sole_shape[0], sole_shape[1], sole_shape[2]
    out = joints.copy()
    lifts = np.zeros(legs.shape[0])
    for f in range(joints.shape[0]):
        shift = heights[f] - _centre_height(joints, f, weights)
        for _ in range(passes):
            for j in range(joints.shape[1]):  # each pass starts from the frame as it came, shifted
                out[f, j, 0], out[f, j, 2] = joints[f, j, 0], joints[f, j, 2]
                out[f, j, 1] = joints[f, j, 1] + shift
            # Every leg's lift is measured before any leg moves, as ground_feet measures them.
            for leg in range(legs.shape[0]):
                hip, knee, ankle, toe = legs[leg, 0], legs[leg, 1], legs[leg, 2], legs[leg, 3]
                sole = _sole(out, f, ankle, toe, flat_ankle[f], heel_back, toe_front, radius)
                low = clearance[f, leg]
                on = down[f, leg]
                lift = -sole if on else max(low - sole, 0.0)
                if has_pull and not (on or pull[f, leg] <= 0.0):  # let go of the floor: down by its pull
                    lift = max(-pull[f, leg], low - sole)
                lifts[leg] = max(lift, _deepest_reach(out, f, hip, knee, ankle, max_stretch))
            for leg in range(legs.shape[0]):
                if abs(lifts[leg]) > 1e-6:
                    hip, knee, ankle, toe = legs[leg, 0], legs[leg, 1], legs[leg, 2], legs[leg, 3]
                    _lift_leg(out, f, hip, knee, ankle, toe, lifts[leg], hint_weight, hint_length)
            error = heights[f] - _centre_height(out, f, weights)
            if not abs(error) >= tolerance:
                break
            shift += error
        sunk = 0.0  # a knee or a hand through the floor
        for j in range(joints.shape[1]):
            sunk = min(sunk, out[f, j, 1])
        for j in range(joints.shape[1]):
            out[f, j, 1] -= sunk
    return out
