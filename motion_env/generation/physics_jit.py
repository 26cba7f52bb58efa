"""The physics stage's frame loops compiled (numba): what :class:`PhysicsFilter
<motion_env.generation.physics.PhysicsFilter>` reads from a token's frames before it plans their
heights (``_measure``: the flat foot's ankle, the soles, the feet's steps, which feet are dragged,
how far each leg reaches, the centre of mass, the flights and the free feet's clearance, the
heights wanted) and how far a foot let go of the floor is still pulled down (``_release``).

On numpy ``_measure`` is some 150 operations on arrays of a few numbers, whose dispatch was half
of the stage's time in a stream (about 1.2 of 2.2 ms a token, raw); here it is one pass over the
frames. The height plan itself (:func:`~motion_env.generation.height_plan.plan_heights`: LAPACK's
solves) and the legs' re-solve (:mod:`~motion_env.generation.ground_jit`) are not in it. The same
float64 operations in the same order, sums as numpy sums them (``jit_math.pairwise_sum``): the same
numbers to the bit (``tests/generation/test_physics.py``).

Each takes the arrays of the new frames (R, n, ...) and the state the last frame left (B, ...) or
(R, ...), updated in place.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.generation.ground_jit import centre, leg_reach, sole_height
from motion_env.models.jit_math import clip, pairwise_sum

__all__ = ["measure_frames", "release_frames", "remember_frames", "replan_frames"]


@njit(cache=True, nogil=True, error_model="numpy")
def release_frames(down, planted, soles, last, fade_rate, at_once):
    """(R, n, 2) how far down each foot is pulled (``_release``): on the floor, its sole's height
    above it; let go, the pull of the frame before times `fade_rate`, or none."""
    out = np.zeros(soles.shape)
    for r in range(soles.shape[0]):
        for leg in range(soles.shape[2]):
            pull = last[r, leg]
            for t in range(soles.shape[1]):
                if down[r, t, leg]:
                    pull = max(soles[r, t, leg], 0.0)
                else:
                    pull = fade_rate * pull if planted[r, t, leg] or pull > at_once else 0.0
                out[r, t, leg] = pull
            last[r, leg] = pull
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _min(a, b):
    """``np.minimum`` of two numbers (a NaN wins)."""
    return a if a < b or math.isnan(a) else b


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _max(a, b):
    """``np.maximum`` of two numbers (a NaN wins)."""
    return a if a > b or math.isnan(a) else b


@njit(cache=True, nogil=True, error_model="numpy")
def _cap(air, n, airborne, longest, before, after, out):
    """``physics._cap_flights`` of one row's frames in the air `air` (n,) into `out` (n,): the
    stretches no longer than `longest` frames, the one before these frames (`airborne` frames
    long) continued; `before`, `after` (n,) int scratch."""
    ground = -1
    for t in range(n):
        ground = ground if air[t] else t
        before[t] = ground
    ground = n
    for t in range(n - 1, -1, -1):
        ground = ground if air[t] else t
        after[t] = ground
    for t in range(n):
        length = after[t] - before[t] - 1 + (airborne if before[t] < 0 else 0)
        out[t] = air[t] and length <= longest


@njit(cache=True, nogil=True, error_model="numpy")
def _flat_ankle(i, b, joints, flags, flat, legs, line, prior_height, prior, low, high):
    """``_flat_ankle`` of row i (character b): the frames so far with both contacts of a foot on."""
    n = joints.shape[1]
    for leg in range(2):
        ankle, toe, flat_frames = legs[leg, 2], legs[leg, 3], 0
        for t in range(n):
            both = flags[i, t, 2 * leg] and flags[i, t, 2 * leg + 1]
            line[t] = joints[i, t, ankle, 1] - joints[i, t, toe, 1] if both else 0.0
            flat_frames += 1 if both else 0
        flat[b, 0] += pairwise_sum(line, n)
        flat[b, 1] += flat_frames
    return clip((flat[b, 0] + prior_height) / (flat[b, 1] + prior), low, high)


@njit(cache=True, nogil=True, error_model="numpy")
def _steps(i, b, joints, soles, feet, last_soles, seen, foot_joints, steps, descent):
    """``_steps`` of row i (character b) into `steps` (n, 4) and `descent` (n, 2): how far each
    foot joint moved and each sole went down into each frame; the last frame's kept."""
    n = joints.shape[1]
    for t in range(n):
        for q in range(4):
            j = foot_joints[q]
            if t == 0:
                px, pz = feet[b, q, 0], feet[b, q, 1]
            else:
                px, pz = joints[i, t - 1, j, 0], joints[i, t - 1, j, 2]
            dx, dz = joints[i, t, j, 0] - px, joints[i, t, j, 2] - pz
            steps[t, q] = 0.0 if t == 0 and seen[b] == 0 else math.sqrt(dx * dx + dz * dz)
        for leg in range(2):
            last = last_soles[b, leg] if t == 0 else soles[i, t - 1, leg]
            descent[t, leg] = 0.0 if t == 0 and seen[b] == 0 else -(soles[i, t, leg] - last)
    for q in range(4):
        j = foot_joints[q]
        feet[b, q, 0], feet[b, q, 1] = joints[i, n - 1, j, 0], joints[i, n - 1, j, 2]
    last_soles[b, 0], last_soles[b, 1] = soles[i, n - 1, 0], soles[i, n - 1, 1]


@njit(cache=True, nogil=True, error_model="numpy")
def _feet(i, b, frames, flags, soles, steps, descent, moving, free, lift, legs, constants, out):
    """``_planted``, the legs' reach, ``_clearance``, ``_settle`` and ``_lifting_off`` of row i
    (character b), frame by frame, into `out` = (flagged, still, lowest, clearance, planted)."""
    drag_step, max_stretch, straight, speed_low, speed_span, top, rise_rate, landing, fps = constants
    flagged, still, lowest, clearance, planted = out
    n = soles.shape[1]
    for leg in range(2):
        hip, knee, ankle = legs[leg, 0], legs[leg, 1], legs[leg, 2]
        was_moving, off, up = moving[b, leg], free[b, leg], lift[b, leg]
        for t in range(n):
            # Flagged feet, and those not dragged (both joints past drag_step, two frames running).
            on = flags[i, t, 2 * leg] or flags[i, t, 2 * leg + 1]
            moves = on and _min(steps[t, 2 * leg], steps[t, 2 * leg + 1]) > drag_step
            flagged[i, t, leg], still[i, t, leg] = on, on and not (moves and was_moving)
            was_moving = moves
            reach, stretch = leg_reach(frames, i * n + t, hip, knee, ankle, max_stretch)
            lowest[i, t, leg] = soles[i, t, leg] - (-reach)
            # A free foot's clearance, then a dragged foot let down before it is stood on.
            down = math.inf if stretch > straight else descent[t, leg]
            speed = _max(steps[t, 2 * leg], steps[t, 2 * leg + 1]) * fps
            off = 0.0 if still[i, t, leg] else min(off + 1, 100.0)
            rise = _min(top * clip((speed - speed_low) / speed_span, 0.0, 1.0), rise_rate * off)
            clear = 0.0 if down > landing else rise
            stands = still[i, t, leg]
            dragged, settling = on and not stands, stands and up > 0.0
            if settling:
                clear = max(up - rise_rate, 0.0)
                stands = not clear > 0.0
            up = clear if dragged or settling else 0.0
            clearance[i, t, leg], planted[i, t, leg] = clear, stands
        moving[b, leg], free[b, leg], lift[b, leg] = was_moving, off, up
    for t in range(n - 1):  # the last frame of a contact seen to end lifts off
        for leg in range(2):
            planted[i, t, leg] = planted[i, t, leg] and planted[i, t + 1, leg]


@njit(cache=True, nogil=True, error_model="numpy")
def _wanted(i, b, soles, com, flagged, floating, plant_reach, float_rate, sink_tolerance, raw, support):
    """``_wanted`` of row i (character b) into `raw` and `support`: the body on its planted feet,
    their gap to the floor followed slowly, raised out of the floor; `floating` moves on."""
    value = floating[b]
    for t in range(soles.shape[1]):
        v0 = soles[i, t, 0] if flagged[i, t, 0] else math.inf
        v1 = soles[i, t, 1] if flagged[i, t, 1] else math.inf
        low = _min(v0, v1)
        some, every = flagged[i, t, 0] or flagged[i, t, 1], flagged[i, t, 0] and flagged[i, t, 1]
        gap = low if some and (abs(low) <= plant_reach or every) else math.nan
        if not math.isnan(gap):
            value = gap if math.isnan(value) else value + float_rate * (gap - value)
        held = 0.0 if math.isnan(value) else value
        sunk = held - _min(soles[i, t, 0], soles[i, t, 1]) - sink_tolerance
        raw[i, t] = com[i, t] - held + _max(sunk, 0.0)
        support[i, t, 0] = flagged[i, t, 0] if some else True
        support[i, t, 1] = flagged[i, t, 1] if some else True
    floating[b] = value


@njit(cache=True, nogil=True, error_model="numpy")
def measure_frames(  # noqa: PLR0913 (one compiled pass: the stage's arrays and constants)
    rows, joints, flags, flat, feet, last_soles, seen, moving, free, lift, floating, airborne,
    legs, foot_joints, com_weights, constants,
):  # fmt: skip
    """What :class:`PhysicsFilter <motion_env.generation.physics.PhysicsFilter>`'s ``_measure``
    reads from the new frames of characters `rows` before their heights are planned: (R, n, 22, 3)
    float64 `joints`, (R, n, 4) bool contact `flags`; the state arrays (B, ...) updated in place
    (flat feet, foot joints and soles of the last frame, dragged feet, free frames, let-down lifts,
    floating). Returns its ten arrays in its order."""
    (prior_height, prior, ankle_low, ankle_high, heel_back, toe_front, radius, drag_step, max_stretch,
     flight_clearance, straight, speed_low, speed_span, top, rise_rate, landing, fps,
     plant_reach, float_rate, sink_tolerance, max_flight) = constants  # fmt: skip
    feet_constants = (drag_step, max_stretch, straight, speed_low, speed_span, top, rise_rate, landing, fps)
    count, n = joints.shape[0], joints.shape[1]
    frames = joints.reshape((count * n, joints.shape[2], 3))
    flat_ankle, com, raw = np.empty(count), np.empty((count, n)), np.empty((count, n))
    soles, lowest, clearance = np.empty((count, n, 2)), np.empty((count, n, 2)), np.empty((count, n, 2))
    flagged, still = np.empty((count, n, 2), np.bool_), np.empty((count, n, 2), np.bool_)
    planted, support = np.empty((count, n, 2), np.bool_), np.empty((count, n, 2), np.bool_)
    flights = np.empty((count, n), np.bool_)
    steps, descent, line = np.empty((n, 4)), np.empty((n, 2)), np.empty(n)
    air, before, after = np.empty(n, np.bool_), np.empty(n, np.int64), np.empty(n, np.int64)
    for i in range(count):
        b = rows[i]
        ankle_height = _flat_ankle(
            i, b, joints, flags, flat, legs, line, prior_height, prior, ankle_low, ankle_high
        )
        flat_ankle[i] = ankle_height
        for t in range(n):  # the soles, the centre of mass, the frames in the air
            f = i * n + t
            for leg in range(2):
                soles[i, t, leg] = sole_height(
                    frames, f, legs[leg, 2], legs[leg, 3], ankle_height, heel_back, toe_front, radius
                )
            com[i, t] = centre(frames, f, com_weights, 1)
            touch = flags[i, t, 0] or flags[i, t, 1] or flags[i, t, 2] or flags[i, t, 3]
            air[t] = not touch and _min(soles[i, t, 0], soles[i, t, 1]) > flight_clearance
        _steps(i, b, joints, soles, feet, last_soles, seen, foot_joints, steps, descent)
        out = (flagged, still, lowest, clearance, planted)
        _feet(i, b, frames, flags, soles, steps, descent, moving, free, lift, legs, feet_constants, out)
        _wanted(i, b, soles, com, flagged, floating, plant_reach, float_rate, sink_tolerance, raw, support)
        _cap(air, n, airborne[b], max_flight, before, after, flights[i])
    return flat_ankle, soles, com, lowest, still, planted, clearance, flights, raw, support


@njit(cache=True, nogil=True, error_model="numpy")
def replan_frames(  # noqa: PLR0913 (one compiled pass: the plan's arrays and constants)
    planned, com, soles, lowest, still, support, airborne, todo, flights, settled, raw,
    unreachable, plant_reach, longest_hop,
):  # fmt: skip
    """What a height plan (R, n) of the rows still to plan (`todo` (R,)) shows (``_plan_rows``):
    landings the flags missed, take-offs, feet held up longer than a hop; `flights`, `settled`
    and `raw` (R, n) updated in place for the next plan. Returns (R,) the rows to plan again."""
    count, n = planned.shape
    again = np.zeros(count, np.bool_)
    aloft, air, capped = np.empty(n, np.bool_), np.empty(n, np.bool_), np.empty(n, np.bool_)
    before, after = np.empty(n, np.int64), np.empty(n, np.int64)
    for i in range(count):
        if not todo[i]:
            continue
        landing, lifted, stood = -1, False, False
        for t in range(n):
            shift = planned[i, t] - com[i, t]
            low = _min(soles[i, t, 0] + shift, soles[i, t, 1] + shift)
            if flights[i, t] and low < 0.0 and landing < 0:
                landing = t
            up = True
            for leg in range(2):
                away = lowest[i, t, leg] + shift > unreachable or soles[i, t, leg] + shift >= plant_reach
                up = up and (away if support[i, t, leg] else True)
            aloft[t] = not flights[i, t] and not settled[i, t] and up
        for t in range(n):
            air[t] = flights[i, t] or aloft[t]
        _cap(air, n, airborne[i], longest_hop, before, after, capped)
        for t in range(n):
            if aloft[t] and not capped[t] and (still[i, t, 0] or still[i, t, 1]):  # held up too long
                aloft[t] = False
                v0 = soles[i, t, 0] if still[i, t, 0] else math.inf
                v1 = soles[i, t, 1] if still[i, t, 1] else math.inf
                raw[i, t] = com[i, t] - _min(v0, v1)
                settled[i, t], stood = True, True
            lifted = lifted or aloft[t]
        again[i] = landing >= 0 or lifted or stood
        if landing >= 0:  # the flight it ends is on the floor from there
            t = landing
            while t < n and flights[i, t]:
                flights[i, t], settled[i, t] = False, True
                t += 1
        for t in range(n):
            flights[i, t] = flights[i, t] or aloft[t]
    return again


@njit(cache=True, nogil=True, error_model="numpy")
def remember_frames(rows, heights, raw, flight, seen, past, past_raw, past_flight, airborne):
    """The last frames of characters `rows` kept for their next plans (``_remember``): the
    histories (B, H) and their lengths, frames in the air at the end; in place."""
    size, n = past.shape[1], heights.shape[1]
    line, wanted, aloft = np.empty(size + n), np.empty(size + n), np.empty(size + n, np.bool_)
    for i in range(rows.shape[0]):
        b = rows[i]
        h = seen[b]
        for j in range(h):  # the past's last h frames, then the new ones
            line[j], wanted[j], aloft[j] = (
                past[b, size - h + j],
                past_raw[b, size - h + j],
                past_flight[b, size - h + j],
            )
        for t in range(n):
            line[h + t], wanted[h + t], aloft[h + t] = heights[i, t], raw[i, t], flight[i, t]
        kept = min(h + n, size)
        for k in range(kept):
            j = h + n - kept + k
            past[b, size - kept + k], past_raw[b, size - kept + k], past_flight[b, size - kept + k] = (
                line[j],
                wanted[j],
                aloft[j],
            )
        seen[b] = kept
        trailing = 0
        while trailing < n and flight[i, n - 1 - trailing]:
            trailing += 1
        airborne[b] = airborne[b] + trailing if trailing == n else trailing
