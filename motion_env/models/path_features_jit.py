"""The stream's next-token path features compiled (numba): what
:func:`~motion_env.models.path_features.first_token_path_features` does with numpy's operations.

On numpy a token's features are some forty operations on a character's look-ahead path (its
heading unwrapped, the mean motion over the token and over the next second turned into the
heading frame): 0.15 ms of a stream's token as a quiet-machine equivalent, nearly all dispatch.
The operations are numpy's, in its order, on float64: the same numbers to the bit
(``tests/models/test_path_features.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.models.jit_math import unwrap

__all__ = ["first_token_features"]


@njit(cache=True, nogil=True, error_model="numpy")
def _mean_motion(path, heading, end, fps, out, at):
    """_average_motion from frame 0 to `end` into out[at: at + 3]: lateral and forward velocity,
    turn rate."""
    frames = np.float64(max(end, 1))
    dx, dz = path[end, 0] - path[0, 0], path[end, 1] - path[0, 1]
    c, s = math.cos(heading[0]), math.sin(heading[0])
    out[at] = np.float32((dx * c - dz * s) / frames * fps)
    out[at + 1] = np.float32((dx * s + dz * c) / frames * fps)
    out[at + 2] = np.float32((heading[end] - heading[0]) / frames * fps)


@njit(cache=True, nogil=True, error_model="numpy")
def first_token_features(paths, rate, horizon, fps):
    """(N, T, 3) float64 paths (float32 numbers) -> (N, 6) float32: each path's first token's mean
    motion over `rate` frames, then over `horizon` (both clamped at its last frame)."""
    count, frames = paths.shape[0], paths.shape[1]
    out = np.empty((count, 6), np.float32)
    heading = np.empty(frames)
    for n in range(count):
        unwrap(paths[n, :, 2], heading)
        _mean_motion(paths[n], heading, min(rate, frames - 1), fps, out[n], 0)
        _mean_motion(paths[n], heading, min(horizon, frames - 1), fps, out[n], 3)
    return out
