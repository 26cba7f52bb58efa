"""The foot pinner's frame loop compiled (numba): what :meth:`FootPinner._pin
<motion_env.generation.feet.FootPinner._pin>` does frame by frame on numpy's operations, for the
frames where no pin is cut to its ankle's room (every frame of a clip but a jump's crouch).

On numpy a frame is some fifteen operations on each character's two legs: about 15 ms for a
200-frame clip, a seventh of it; compiled, the loop is its arithmetic. The same float64 operations
in the same order, so the same numbers to the bit (``tests/generation/test_feet.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["pin_frames"]


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
