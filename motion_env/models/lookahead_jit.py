"""The look-ahead head's MLP compiled (numba): what
:meth:`~motion_env.models.lookahead.LookaheadHead._forward_numpy` does with numpy's operations.

A stream's token asks the head for one prediction of a few rows: four products of a 295- to
384-wide layer and three GELUs. On numpy those are a dozen operations on a few hundred numbers,
each a few microseconds of dispatch, and numpy's erf (scipy's ufunc) costs as much as a product;
compiled, the MLP is its products and one loop per GELU: a one-row prediction 0.40 -> 0.34 ms on
the development CPU (its inputs, the controller's step inputs, are the rest).

The same arithmetic on float32 numbers (libm's erf for scipy's): the predictions agree to float32
rounding (``tests/models/test_lookahead.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from motion_env.models.jit_math import gelu

__all__ = ["mlp"]


@njit(cache=True, nogil=True, error_model="numpy")
def mlp(
    x: np.ndarray,
    mean: np.ndarray,
    std: np.ndarray,
    weights: tuple[np.ndarray, ...],
    biases: tuple[np.ndarray, ...],
    scale: np.ndarray,
) -> np.ndarray:
    """(B, out) the head's outputs: inputs x (B, D) normalised by `mean` and `std`, each hidden
    layer (weights held transposed, (in, out)) and its GELU, the last layer, times `scale` (out,)."""
    h = (x - mean) / std
    for i in range(len(weights) - 1):
        h = gelu(h @ weights[i] + biases[i])
    return (h @ weights[-1] + biases[-1]) * scale
