"""The foot pinner compiled (numba): what :class:`FootPinner
<motion_env.generation.feet.FootPinner>` does with numpy's operations, for the frames where no pin
is cut to its ankle's room (every frame of a clip but a jump's crouch): ``_pin``'s frame loop
(:func:`pin_frames`), the same with what it reads before the loop and keeps after it
(:func:`pin_rows`), and the legs' re-solve (``_re_solve``: :func:`re_solve_rows`, which the cut
frames use too).

On numpy the frame loop is some fifteen operations a frame on each character's two legs (about
15 ms for a 200-frame clip, a seventh of it), and a stream's token adds some sixty around it on
arrays of a few numbers (about 0.9 ms of one env's token, raw); compiled, they are their
arithmetic. The same float64 operations in the same order, so the same numbers to the bit
(``tests/generation/test_feet.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.generation.ik_jit import dot, norm, solve

__all__ = ["pin_frames", "pin_rows", "re_solve_rows"]


@njit(cache=True, nogil=True, error_model="numpy")
def pin_frames(  # noqa: PLR0913 (one compiled loop: the parameters are its arrays and constants)
    held, fresh, shown, fresh_glide, pin, glide, offset, released, since,
    glide_rate, creep_rate, creep_max, max_offset, blend,
):  # fmt: skip
    """Each leg's horizontal ankle correction over the frames (R, n, legs, 2), and the carried
    state updated in place: `pin`, `glide`, `offset`, `released` (R, legs, 2) and `since`
    (R, legs). held, fresh: (R, n, legs) bool; shown, fresh_glide: (R, n, legs, 2); the constants
    FOOT_GLIDE, FOOT_CREEP_RATE, FOOT_CREEP, FOOT_MAX_OFFSET and FOOT_BLEND."""
    rows, frames, legs = held.shape
    offsets = np.zeros((rows, frames, legs, 2))
    for r in range(rows):
        for leg in range(legs):
            for t in range(frames):
                if not held[r, t, leg]:  # a free leg: its correction fades out (release_fade)
                    since[r, leg] += 1
                    s = min(max(since[r, leg] / (blend + 1), 0.0), 1.0)
                    fade = 1.0 - s * s * (3.0 - 2.0 * s)
                    pin[r, leg, 0] = pin[r, leg, 1] = np.nan
                    for k in range(2):
                        offset[r, leg, k] = offsets[r, t, leg, k] = released[r, leg, k] * fade
                    continue
                since[r, leg] = 0
                first = fresh[r, t, leg]
                x, z = shown[r, t, leg, 0], shown[r, t, leg, 1]
                if first:  # where its foot is shown now, with the correction the leg had
                    mx, mz = (x + offset[r, leg, 0]) - x, (z + offset[r, leg, 1]) - z
                    glide[r, leg, 0], glide[r, leg, 1] = fresh_glide[r, t, leg, 0], fresh_glide[r, t, leg, 1]
                else:  # on by the glide it has (which then halves)
                    mx = (pin[r, leg, 0] + glide[r, leg, 0]) - x
                    mz = (pin[r, leg, 1] + glide[r, leg, 1]) - z
                    for k in range(2):
                        glide[r, leg, k] = glide[r, leg, k] * glide_rate
                dist = math.sqrt(mx * mx + mz * mz)
                creep = 0.0 if first else min(creep_rate * dist, creep_max)
                keep = 1.0 - creep / max(dist, 1e-12)
                mx, mz = mx * keep, mz * keep
                norm = math.sqrt(mx * mx + mz * mz)
                far = max_offset / max(norm, 1e-12) if norm > max_offset else 1.0
                mx, mz = mx * far, mz * far
                pin[r, leg, 0], pin[r, leg, 1] = x + mx, z + mz
                released[r, leg, 0], released[r, leg, 1] = mx, mz
                offset[r, leg, 0], offset[r, leg, 1] = mx, mz
                offsets[r, t, leg, 0], offsets[r, t, leg, 1] = mx, mz
    return offsets


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _finite(x):
    """``np.nan_to_num`` of one number: NaN is 0, an infinity the largest float of its sign."""
    if math.isnan(x):
        return 0.0
    if math.isinf(x):
        return 1.7976931348623157e308 if x > 0 else -1.7976931348623157e308
    return x


@njit(cache=True, nogil=True, error_model="numpy")
def pin_rows(  # noqa: PLR0913 (one compiled pass: the pinner's arrays and constants)
    joints, flags, pins, shown_last, glide, offset, released, since, legs,
    glide_rate, glide_step, creep_rate, creep_max, max_offset, blend,
):  # fmt: skip
    """``FootPinner._pin`` of R characters where no pin is cut to its ankle's room: (R, n, 22, 3)
    float64 `joints`, (R, n, 4) bool `flags`; the characters' state (R, ...) updated in place:
    `pins` (R, legs, 2 kinds, 2), `shown_last` (R, legs, 2 joints, 2), `glide`, `offset`,
    `released` (R, legs, 2), `since` (R, legs). Returns the corrections (R, n, legs, 2)."""
    count, n, sides = joints.shape[0], joints.shape[1], legs.shape[0]
    kinds = np.empty((count, n, sides), np.int64)
    held, fresh = np.empty((count, n, sides), np.bool_), np.empty((count, n, sides), np.bool_)
    shown, fresh_glide = np.empty((count, n, sides, 2)), np.empty((count, n, sides, 2))
    pin = np.empty((count, sides, 2))
    for r in range(count):
        for leg in range(sides):
            ankle, toe = legs[leg, 2], legs[leg, 3]
            for t in range(n):
                # The ankle's flag wins; the toe alone is pinned while the heel lifts.
                kind = 0 if flags[r, t, 2 * leg] else (1 if flags[r, t, 2 * leg + 1] else -1)
                kinds[r, t, leg], held[r, t, leg] = kind, kind >= 0
                joint, side = (ankle, 0) if kind == 0 else (toe, 1)
                x, z = joints[r, t, joint, 0], joints[r, t, joint, 2]
                shown[r, t, leg, 0], shown[r, t, leg, 1] = x, z
                if t == 0:
                    px, pz = shown_last[r, leg, side, 0], shown_last[r, leg, side, 1]
                else:
                    px, pz = joints[r, t - 1, joint, 0], joints[r, t - 1, joint, 2]
                sx, sz = glide_rate * _finite(x - px), glide_rate * _finite(z - pz)
                size = math.sqrt(sx * sx + sz * sz)
                share = min(size, glide_step) / max(size, 1e-12)
                fresh_glide[r, t, leg, 0], fresh_glide[r, t, leg, 1] = sx * share, sz * share
                fresh[r, t, leg] = held[r, t, leg] and (t == 0 or kind != kinds[r, t - 1, leg])
            first = max(kinds[r, 0, leg], 0)  # the pin of the first frame's kind
            fresh[r, 0, leg] = fresh[r, 0, leg] and math.isnan(pins[r, leg, first, 0])
            for k in range(2):
                pin[r, leg, k] = pins[r, leg, first, k] if held[r, 0, leg] else np.nan
    offsets = pin_frames(
        held, fresh, shown, fresh_glide, pin, glide, offset, released, since,
        glide_rate, creep_rate, creep_max, max_offset, blend,
    )  # fmt: skip
    for r in range(count):
        for leg in range(sides):
            last = kinds[r, n - 1, leg]  # the pin of the last frame's kind is kept, the other is none
            for kind in range(2):
                for k in range(2):
                    pins[r, leg, kind, k] = pin[r, leg, k] if last == kind else np.nan
            for side in range(2):
                joint = legs[leg, 2 + side]
                shown_last[r, leg, side, 0] = joints[r, n - 1, joint, 0]
                shown_last[r, leg, side, 1] = joints[r, n - 1, joint, 2]
    return offsets


@njit(cache=True, nogil=True, error_model="numpy")
def _shin_foot_angle(k0, k1, k2, a0, a1, a2, t0, t1, t2):
    """``feet._shin_foot_angle`` of one leg: the angle (degrees) between shin and foot."""
    u0, u1, u2, v0, v1, v2 = k0 - a0, k1 - a1, k2 - a2, t0 - a0, t1 - a1, t2 - a2
    cos = dot(u0, u1, u2, v0, v1, v2) / max(norm(u0, u1, u2) * norm(v0, v1, v2), 1e-12)
    return math.acos(min(max(cos, -1.0), 1.0)) * (180.0 / math.pi)


@njit(cache=True, nogil=True, error_model="numpy")
def re_solve_rows(  # noqa: PLR0913 (one compiled pass: the legs' arrays and constants)
    out, decoded, offsets, legs, stretch, softness, hint_weight, hint_length, min_angle, tolerance,
):  # fmt: skip
    """``feet._re_solve``: the legs of `out` (R, n, 22, 3) re-solved for their ankles moved by
    `offsets` (R, n, legs, 2) from `decoded`, in place; returns (R, n, legs) the frames whose
    shin-foot angle ended too narrow, and the frame on each side."""
    count, n, sides = out.shape[0], out.shape[1], legs.shape[0]
    bent = np.zeros((count, n, sides), np.bool_)
    for r in range(count):
        for t in range(n):
            for leg in range(sides):
                for j in range(4):
                    joint = legs[leg, j]
                    out[r, t, joint, 0] = decoded[r, t, joint, 0]
                    out[r, t, joint, 1] = decoded[r, t, joint, 1]
                    out[r, t, joint, 2] = decoded[r, t, joint, 2]
                ox, oz = offsets[r, t, leg, 0], offsets[r, t, leg, 1]
                if not (ox != 0.0 or oz != 0.0):
                    continue
                hip, knee, ankle, toe = legs[leg, 0], legs[leg, 1], legs[leg, 2], legs[leg, 3]
                h0, h1, h2 = decoded[r, t, hip, 0], decoded[r, t, hip, 1], decoded[r, t, hip, 2]
                k0, k1, k2 = decoded[r, t, knee, 0], decoded[r, t, knee, 1], decoded[r, t, knee, 2]
                a0, a1, a2 = decoded[r, t, ankle, 0], decoded[r, t, ankle, 1], decoded[r, t, ankle, 2]
                f0, f1, f2 = decoded[r, t, toe, 0], decoded[r, t, toe, 1], decoded[r, t, toe, 2]
                # The goal within the leg's soft reach (feet.soft_reach).
                length = norm(k0 - h0, k1 - h1, k2 - h2) + norm(a0 - k0, a1 - k1, a2 - k2)
                band = softness * length
                reach = min(max(stretch * length, norm(a0 - h0, a1 - h1, a2 - h2) + band), length)
                start = reach - band
                v0, v1, v2 = (a0 + ox) - h0, a1 - h1, (a2 + oz) - h2
                d = norm(v0, v1, v2)
                if d > start:
                    excess = min(max((d - start) / max(band, 1e-9), 0.0), 50.0)
                    limited = start + band * (1.0 - math.exp(-excess))
                else:
                    limited = d
                scale = limited / max(d, 1e-9)
                g0, g1, g2 = h0 + v0 * scale, h1 + v1 * scale, h2 + v2 * scale
                nk0, nk1, nk2, na0, na1, na2 = solve(
                    h0, h1, h2, k0, k1, k2, a0, a1, a2, g0, g1, g2, f0 - a0, 0.0, f2 - a2,
                    True, hint_weight, hint_length, 0.0,
                )  # fmt: skip
                nt0, nt1, nt2 = (f0 + na0) - a0, (f1 + na1) - a1, (f2 + na2) - a2
                out[r, t, knee, 0], out[r, t, knee, 1], out[r, t, knee, 2] = nk0, nk1, nk2
                out[r, t, ankle, 0], out[r, t, ankle, 1], out[r, t, ankle, 2] = na0, na1, na2
                out[r, t, toe, 0], out[r, t, toe, 1], out[r, t, toe, 2] = nt0, nt1, nt2
                floor = min(_shin_foot_angle(k0, k1, k2, a0, a1, a2, f0, f1, f2), min_angle)
                angle = _shin_foot_angle(nk0, nk1, nk2, na0, na1, na2, nt0, nt1, nt2)
                bent[r, t, leg] = angle < floor - tolerance
        for leg in range(sides):  # the frame on each side too, as numpy's two shifted ors
            before = bent[r, :, leg].copy()
            for t in range(1, n):
                bent[r, t, leg] = before[t] or before[t - 1]
            before = bent[r, :, leg].copy()
            for t in range(n - 1):
                bent[r, t, leg] = before[t] or before[t + 1]
    return bent
