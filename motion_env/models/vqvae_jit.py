"""The VQ-VAE decoder's streaming step compiled (numba): the two operations of each causal
convolution of :meth:`~motion_env.models.vqvae.DecoderStream._step_numpy`, on a few rows.

A one-row token is nine causal convolutions on 1, 2 and 4 frames and four 1x1 mixes. On numpy
each convolution concatenated its history and its taps and wrote the history back through fancy
indexing (about 30 µs of dispatch), and OpenBLAS's matrix product, given 2 to 4 rows, copies
("packs") the 0.8 MB weight before it multiplies: a 2-row product cost four times a 1-row one.
Here the taps are gathered in one loop, and a product of at most
:data:`~motion_env.models.vqvae.FEW_ROWS` rows reads each weight row once, for every input row
while it is in cache; more rows keep BLAS's product. In a stream's token the decoder's 8 MB of
weights are mostly out of cache, which its products wait for either way: there the step is about
15 % shorter (2.3 -> 2.0 ms raw, one environment at the learning default), in isolation 3x.

The same arithmetic on float32 numbers, summed in another order: the frames agree with numpy's to
float32 rounding (``tests/models/test_vqvae.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["causal_taps", "few_rows_linear"]


@njit(cache=True, nogil=True, error_model="numpy")
def causal_taps(
    cache: np.ndarray, x: np.ndarray, index: np.ndarray, dilation: int, kernel: int
) -> np.ndarray:
    """The inputs of a causal convolution for new frames `x` (N, t, C) of rows `index` (N,) after
    their history `cache` (B, lookback, C), as (N * t, kernel * C) rows (tap j of frame s: the
    input j * dilation frames after the window's start); each row's history moves on in place."""
    rows, t, c = x.shape
    lookback = cache.shape[1]
    taps = np.empty((rows * t, kernel * c), np.float32)
    full = np.empty((lookback + t, c), np.float32)
    for n in range(rows):
        i = index[n]
        full[:lookback] = cache[i]
        full[lookback:] = x[n]
        for s in range(t):
            for j in range(kernel):
                taps[n * t + s, j * c : (j + 1) * c] = full[s + j * dilation]
        cache[i] = full[t:]
    return taps


@njit(cache=True, nogil=True, error_model="numpy")
def few_rows_linear(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x @ w + b for a few rows x (M, K) and w (K, N): four weight rows at a time, each added to
    every output row while it is in cache (the sums run over K in order)."""
    m, k = x.shape
    n = w.shape[1]
    out = np.empty((m, n), np.float32)
    for r in range(m):
        out[r] = b
    whole = k - k % 4
    for kk in range(0, whole, 4):
        for r in range(m):
            a0, a1, a2, a3 = x[r, kk], x[r, kk + 1], x[r, kk + 2], x[r, kk + 3]
            for j in range(n):
                out[r, j] = (
                    out[r, j] + a0 * w[kk, j] + a1 * w[kk + 1, j] + a2 * w[kk + 2, j] + a3 * w[kk + 3, j]
                )
    for kk in range(whole, k):
        for r in range(m):
            a = x[r, kk]
            for j in range(n):
                out[r, j] += a * w[kk, j]
    return out
