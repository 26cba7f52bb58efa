"""The body placed on the floor, compiled (numba): what :func:`place_body
<motion_env.generation.ground.place_body>` does with numpy's operations, frame by frame.

On numpy the placement is a few shift-then-ground passes over the frames not placed yet, each some
sixty operations on a handful of vectors (the soles, how far each leg reaches, the legs'
re-solve, the centre of mass): about 1 ms of a stream's token (quiet-machine equivalent: the
physics stage 2.2 -> 1.1 ms) and 2.4 ms of a 160-frame clip (raw), most of it dispatch. Compiled,
a frame's passes are their arithmetic. The operations are numpy's, in its order, on float64: the
same numbers to the bit (``tests/generation/test_physics.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.generation.ik_jit import dot, norm, solve

__all__ = ["centre", "leg_reach", "place_frames", "sole_height"]


@njit(cache=True, nogil=True, error_model="numpy")
def centre(out, f, weights, axis):
    """One coordinate (`axis`: 0 x, 1 height, 2 z) of frame f's centre of mass
    (:func:`~motion_env.motion.mass.centre_of_mass`)."""
    total = 0.0
    for j in range(weights.shape[0]):
        total += weights[j] * out[f, j, axis]
    return total


@njit(cache=True, nogil=True, error_model="numpy")
def sole_height(out, f, ankle, toe, flat_ankle, heel_back, toe_front, radius):
    """:func:`~motion_env.generation.ground.sole_heights` of one foot of frame f."""
    b0 = out[f, toe, 0] - out[f, ankle, 0]
    b1 = out[f, toe, 1] - out[f, ankle, 1]
    b2 = out[f, toe, 2] - out[f, ankle, 2]
    length = norm(b0, b1, b2)
    reach = math.sqrt(max(length * length - flat_ankle * flat_ankle, 1e-6))
    turn = math.atan2(b1, math.hypot(b0, b2)) - math.atan2(-flat_ankle, reach)
    up = radius - flat_ankle
    s, c = math.sin(turn), math.cos(turn)
    lowest = min(-heel_back * s + up * c, (reach + toe_front) * s + up * c)
    return out[f, ankle, 1] + lowest - radius


@njit(cache=True, nogil=True, error_model="numpy")
def leg_reach(out, f, hip, knee, ankle, max_stretch):
    """One leg of frame f: :func:`~motion_env.generation.ground.deepest_reach` (the lowest vertical
    move of its ankle, <= 0) and how far it is stretched (hip to ankle over thigh plus shin)."""
    l0 = out[f, ankle, 0] - out[f, hip, 0]
    l1 = out[f, ankle, 1] - out[f, hip, 1]
    l2 = out[f, ankle, 2] - out[f, hip, 2]
    length = norm(
        out[f, knee, 0] - out[f, hip, 0], out[f, knee, 1] - out[f, hip, 1], out[f, knee, 2] - out[f, hip, 2]
    )
    length += norm(
        out[f, ankle, 0] - out[f, knee, 0],
        out[f, ankle, 1] - out[f, knee, 1],
        out[f, ankle, 2] - out[f, knee, 2],
    )
    squared = dot(l0, l1, l2, l0, l1, l2)
    span = math.sqrt(squared)
    reach = max(max_stretch * length, span)
    return -l1 - math.sqrt(max(l1 * l1 + reach * reach - squared, 0.0)), span / length


@njit(cache=True, nogil=True, error_model="numpy")
def _lift_leg(out, f, hip, knee, ankle, toe, lift, hint_weight, hint_length):
    """Frame f's leg re-solved for its ankle moved up by `lift` (in place), as
    :func:`~motion_env.generation.ground.ground_feet` does: the toes' horizontal direction is the
    bend hint, the foot moves with the ankle."""
    a0, a1, a2 = out[f, ankle, 0], out[f, ankle, 1], out[f, ankle, 2]
    k = solve(
        out[f, hip, 0], out[f, hip, 1], out[f, hip, 2], out[f, knee, 0], out[f, knee, 1], out[f, knee, 2],
        a0, a1, a2, a0, a1 + lift, a2, out[f, toe, 0] - a0, 0.0, out[f, toe, 2] - a2,
        True, hint_weight, hint_length, 0.0,
    )  # fmt: skip
    out[f, toe, 0] += k[3] - a0
    out[f, toe, 1] += k[4] - a1
    out[f, toe, 2] += k[5] - a2
    out[f, knee, 0], out[f, knee, 1], out[f, knee, 2] = k[0], k[1], k[2]
    out[f, ankle, 0], out[f, ankle, 1], out[f, ankle, 2] = k[3], k[4], k[5]


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
        shift = heights[f] - centre(joints, f, weights, 1)
        for _ in range(passes):
            for j in range(joints.shape[1]):  # each pass starts from the frame as it came, shifted
                out[f, j, 0], out[f, j, 2] = joints[f, j, 0], joints[f, j, 2]
                out[f, j, 1] = joints[f, j, 1] + shift
            # Every leg's lift is measured before any leg moves, as ground_feet measures them.
            for leg in range(legs.shape[0]):
                hip, knee, ankle, toe = legs[leg, 0], legs[leg, 1], legs[leg, 2], legs[leg, 3]
                sole = sole_height(out, f, ankle, toe, flat_ankle[f], heel_back, toe_front, radius)
                low = clearance[f, leg]
                on = down[f, leg]
                lift = -sole if on else max(low - sole, 0.0)
                if has_pull and not (on or pull[f, leg] <= 0.0):  # let go of the floor: down by its pull
                    lift = max(-pull[f, leg], low - sole)
                lifts[leg] = max(lift, leg_reach(out, f, hip, knee, ankle, max_stretch)[0])
            for leg in range(legs.shape[0]):
                if abs(lifts[leg]) > 1e-6:
                    hip, knee, ankle, toe = legs[leg, 0], legs[leg, 1], legs[leg, 2], legs[leg, 3]
                    _lift_leg(out, f, hip, knee, ankle, toe, lifts[leg], hint_weight, hint_length)
            error = heights[f] - centre(out, f, weights, 1)
            if not abs(error) >= tolerance:
                break
            shift += error
        sunk = 0.0  # a knee or a hand through the floor
        for j in range(joints.shape[1]):
            sunk = min(sunk, out[f, j, 1])
        for j in range(joints.shape[1]):
            out[f, j, 1] -= sunk
    return out
