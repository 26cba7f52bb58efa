"""The body GPT's token step compiled (numba): one new token for a few rows, what
:class:`~motion_env.models.gpt_numpy.NumpyStep` does on numpy's operations, as one loop.

On numpy a one-row step is some seventy operations on vectors of 192 to 1,024 numbers; their
dispatch is about half of the step, the matrix products (reading the 8 MB of weights) the other
half. Compiled, the step is its products and a few loops: the LayerNorms, the attention of one
query over the cached keys and values (written into the window buffers in place, as the numpy step
does), the GELU.

The same arithmetic as the numpy step on float32 numbers (LayerNorms folded into the products after
them, the attention's scale into the query's rows: the weights it prepares), summed in another
order: the logits agree to float32 rounding (``tests/models/test_gpt_numpy.py``).

Compiled once per machine on first use (a few seconds; numba's cache, beside this file, keeps it
for later processes).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.models.jit_math import gelu

__all__ = ["step"]


@njit(cache=True, nogil=True, error_model="numpy")
def _normed(x: np.ndarray, eps: np.float32) -> np.ndarray:
    """(R, C) -> zero mean, unit variance over C (a LayerNorm without its affine part)."""
    rows, width = x.shape
    out = np.empty_like(x)
    scale = np.float32(1.0 / width)
    for r in range(rows):
        total = np.float32(0.0)
        for j in range(width):
            total += x[r, j]
        mean = total * scale
        square = np.float32(0.0)
        for j in range(width):
            d = x[r, j] - mean
            out[r, j] = d
            square += d * d
        norm = np.float32(math.sqrt(square * scale + eps))
        for j in range(width):
            out[r, j] = out[r, j] / norm
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def step(  # noqa: PLR0913 (one compiled step: the parameters are its arrays)
    x, mask, qkv, qkv_b, proj, proj_b, fc, fc_b, out, out_b, head, head_b, eps, keys, values, start, n_head
):  # fmt: skip
    """Logits (R, V) of one new input per row after `start` cached columns.

    Args:
        x: (R, C) the new inputs, embedded.
        mask: (R, start + 1) additive: 0 where a row's query sees a column, -inf where not.
        qkv ... out_b: each layer's weights stacked (n_layer, in, out) and biases (n_layer, out),
            as :func:`motion_env.models.gpt_numpy._prepare` folds them; head, head_b: the output's.
        eps: the LayerNorms' epsilon.
        keys, values: each layer's window buffers (R, n_head, block, head size): the new column is
            written at `start`, the attention reads columns 0..start.
        n_head: attention heads.
    """
    rows, width = x.shape
    hd = width // n_head
    end = start + 1
    scores = np.empty(end, np.float32)
    for i in range(qkv.shape[0]):
        qkv_i = _normed(x, eps) @ qkv[i] + qkv_b[i]  # (R, 3C): queries (scaled), keys, values
        k_buf, v_buf = keys[i], values[i]
        y = np.empty((rows, width), np.float32)
        for r in range(rows):
            for h in range(n_head):
                for d in range(hd):
                    k_buf[r, h, start, d] = qkv_i[r, width + h * hd + d]
                    v_buf[r, h, start, d] = qkv_i[r, 2 * width + h * hd + d]
                top = -np.inf
                for j in range(end):
                    acc = np.float32(0.0)
                    for d in range(hd):
                        acc += qkv_i[r, h * hd + d] * k_buf[r, h, j, d]
                    scores[j] = acc + mask[r, j]
                    top = max(top, scores[j])
                total = np.float32(0.0)
                for j in range(end):
                    scores[j] = np.float32(math.exp(scores[j] - top))
                    total += scores[j]
                for d in range(hd):
                    acc = np.float32(0.0)
                    for j in range(end):
                        acc += scores[j] * v_buf[r, h, j, d]
                    y[r, h * hd + d] = acc / total
        x = x + (y @ proj[i] + proj_b[i])
        x = x + (gelu(_normed(x, eps) @ fc[i] + fc_b[i]) @ out[i] + out_b[i])
    return _normed(x, eps) @ head + head_b
