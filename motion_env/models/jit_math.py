"""Arithmetic the compiled loops share (numba): :mod:`motion_env.models.controller_jit`,
:mod:`motion_env.models.gpt_jit`, :mod:`motion_env.models.path_features_jit` and
:mod:`motion_env.generation.compose_jit`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["clip", "gelu", "pairwise_sum", "unwrap", "wrap"]

_PI = math.pi
_TWO_PI = 2.0 * math.pi


@njit(cache=True, nogil=True, error_model="numpy")
def gelu(x: np.ndarray) -> np.ndarray:
    """torch's exact GELU, in place on a float32 (R, N) array."""
    half, one, root = np.float32(0.5), np.float32(1.0), np.float32(1.0 / math.sqrt(2.0))
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            v = x[i, j]
            x[i, j] = v * half * (one + np.float32(math.erf(v * root)))
    return x


@njit(cache=True, nogil=True, error_model="numpy")
def wrap(angle):
    """:func:`~motion_env.motion.trajectory.wrap_angle` of one angle: numpy's floored modulo."""
    mod = np.fmod(angle + _PI, _TWO_PI)
    if mod != 0.0:
        if mod < 0.0:
            mod += _TWO_PI
    else:
        mod = 0.0
    return mod - _PI


@njit(cache=True, nogil=True, error_model="numpy")
def unwrap(angles, out):
    """``np.unwrap`` of a (T,) float64 line into `out` (period 2 pi, jumps of pi or more)."""
    out[0] = angles[0]
    total = 0.0
    for t in range(1, angles.shape[0]):
        step = angles[t] - angles[t - 1]
        mod = wrap(step)
        if mod == -_PI and step > 0.0:
            mod = _PI
        correction = mod - step
        if abs(step) < _PI:
            correction = 0.0
        total += correction
        out[t] = angles[t] + total


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def clip(value, low, high):
    """``np.clip`` of one number: its max, then its min, as numpy's loop takes them (a NaN stays)."""
    if math.isnan(value):
        return value
    value = value if value > low else low
    return value if value < high else high


@njit(cache=True, nogil=True, error_model="numpy")
def pairwise_sum(values, n):
    """``values[:n].sum()`` of a float64 line as numpy sums one: sequentially under 8 numbers, in
    eight running sums up to 128 (combined in pairs, the rest added after), halved above."""
    if n < 8:
        total = 0.0
        for i in range(n):
            total += values[i]
        return total
    if n <= 128:
        r0, r1, r2, r3 = values[0], values[1], values[2], values[3]
        r4, r5, r6, r7 = values[4], values[5], values[6], values[7]
        i = 8
        while i < n - n % 8:
            r0, r1, r2, r3 = r0 + values[i], r1 + values[i + 1], r2 + values[i + 2], r3 + values[i + 3]
            r4, r5, r6, r7 = r4 + values[i + 4], r5 + values[i + 5], r6 + values[i + 6], r7 + values[i + 7]
            i += 8
        total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            total += values[i]
            i += 1
        return total
    half = n // 2
    half -= half % 8
    return pairwise_sum(values, half) + pairwise_sum(values[half:], n - half)
