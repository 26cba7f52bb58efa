"""The physics stage's frame loops compiled (numba): what :class:`PhysicsFilter
<motion_env.generation.physics.PhysicsFilter>`'s ``_release``, ``_float``, ``_clearance`` and
``_settle`` carry from frame to frame, on numpy's operations a few per frame (about 5 ms of a
200-frame clip for the four), here their arithmetic. The same float64 operations in the same
order: the same numbers to the bit (``tests/generation/test_physics.py``).

Each takes the arrays of the new frames (R, n, ...) and the state the last frame left (R, ...),
updated in place, and returns what the numpy loop fills frame by frame.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["clearance_frames", "float_frames", "release_frames", "settle_frames"]


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


@njit(cache=True, nogil=True, error_model="numpy")
def float_frames(gap, last, rate):
    """(R, n) the support gap followed from its first value (``_float``; NaN: not known yet)."""
    out = np.zeros(gap.shape)
    for r in range(gap.shape[0]):
        value = last[r]
        for t in range(gap.shape[1]):
            g = gap[r, t]
            if not math.isnan(g):
                value = g if math.isnan(value) else value + rate * (g - value)
            out[r, t] = value
        last[r] = value
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def clearance_frames(planted, last):
    """(R, n, 2) frames each foot has been free (``_clearance``), counted up to 100."""
    out = np.zeros(planted.shape)
    for r in range(planted.shape[0]):
        for leg in range(planted.shape[2]):
            free = last[r, leg]
            for t in range(planted.shape[1]):
                free = 0.0 if planted[r, t, leg] else min(free + 1, 100.0)
                out[r, t, leg] = free
            last[r, leg] = free
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def settle_frames(flagged, planted, clearance, lift, rise):
    """``_settle``'s loop on copies of `planted` and `clearance` (R, n, 2), changed in place: a
    foot no longer dragged but still flagged is let down by `rise` a frame before it is stood on."""
    for r in range(planted.shape[0]):
        for leg in range(planted.shape[2]):
            up = lift[r, leg]
            for t in range(planted.shape[1]):
                dragged = flagged[r, t, leg] and not planted[r, t, leg]
                settling = planted[r, t, leg] and up > 0.0
                if settling:
                    clearance[r, t, leg] = max(up - rise, 0.0)
                    if clearance[r, t, leg] > 0.0:
                        planted[r, t, leg] = False
                up = clearance[r, t, leg] if dragged or settling else 0.0
            lift[r, leg] = up
    return planted, clearance
