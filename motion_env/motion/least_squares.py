"""Least squares over a clip's frames whose rows each read three consecutive frames (a second
difference, an acceleration), solved banded in O(frames): the closed-form finish's smoothing of a
correction (:func:`motion_env.generation.closed_form.smooth_field`) and the whole clips' balance
(:func:`motion_env.generation.balance.balance_shift`)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import solveh_banded

__all__ = ["three_point_least_squares"]

_BANDED_BATCH = 4  # up to this many problems of a batch are solved one by one (30 us each, banded)


def three_point_least_squares(
    coef: np.ndarray, rhs: np.ndarray, weight: np.ndarray, target: np.ndarray
) -> np.ndarray:
    """argmin over x (T, D) of
    sum_i |coef[i] . x[i : i + 3] - rhs[i]|^2 + sum_t weight[t] |x[t] - target[t]|^2.

    Args:
        coef: (T - 2, 3) each row's coefficients on frames i, i + 1, i + 2.
        rhs: (T - 2, D) each row's right-hand side.
        weight: (T,) > 0 the pull of each frame towards `target` (it makes the system definite).
        target: (T, D).

    With a leading batch axis on every argument ((B, T - 2, 3) ...), B problems of a few dozen
    frames at once (the stream's balance): (B, T, D), by dense solves of the normal equations
    (one banded solve each for a batch of a few).

    Returns:
        (T, D) float64, by a banded Cholesky solve of the normal equations.
    """
    coef = np.asarray(coef, dtype=np.float64)
    if coef.ndim == 3 and len(coef) > _BANDED_BATCH:
        return _batched(coef, np.asarray(rhs, np.float64), np.asarray(weight, np.float64), target)
    if coef.ndim == 3:  # a few problems: one banded solve each is cheaper than the dense set-up
        return np.stack([three_point_least_squares(*row) for row in zip(coef, rhs, weight, target)])
    t_len = len(weight)
    band = np.zeros((3, t_len))  # the normal matrix's upper band: entry (i, j) at band[2 + i - j, j]
    for a in range(3):
        for b in range(a, 3):
            band[2 - (b - a), b : t_len - 2 + b] += coef[:, a] * coef[:, b]
    band[2] += weight
    normal_rhs = np.asarray(weight, np.float64)[:, None] * np.asarray(target, np.float64)
    for a in range(3):
        normal_rhs[a : t_len - 2 + a] += coef[:, a, None] * np.asarray(rhs, np.float64)
    return solveh_banded(band, normal_rhs)


def _batched(coef: np.ndarray, rhs: np.ndarray, weight: np.ndarray, target: np.ndarray) -> np.ndarray:
    """:func:`three_point_least_squares` of a batch of short problems, dense."""
    batch, t_len = weight.shape
    rows = np.arange(t_len - 2)
    normal = np.zeros((batch, t_len, t_len))
    normal_rhs = weight[..., None] * np.asarray(target, np.float64)
    for a in range(3):
        normal_rhs[:, rows + a] += coef[:, :, a, None] * rhs
        for b in range(3):
            normal[:, rows + a, rows + b] += coef[:, :, a] * coef[:, :, b]
    normal[:, np.arange(t_len), np.arange(t_len)] += weight
    return np.linalg.solve(normal, normal_rhs)
