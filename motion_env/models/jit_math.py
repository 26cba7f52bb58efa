"""Arithmetic the compiled loops share (numba): :mod:`motion_env.models.controller_jit` and
:mod:`motion_env.models.gpt_jit`."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["gelu"]


@njit(cache=True, nogil=True, error_model="numpy")
def gelu(x: np.ndarray) -> np.ndarray:
    """torch's exact GELU, in place on a float32 (R, N) array."""
    half, one, root = np.float32(0.5), np.float32(1.0), np.float32(1.0 / math.sqrt(2.0))
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            v = x[i, j]
            x[i, j] = v * half * (one + np.float32(math.erf(v * root)))
    return x
