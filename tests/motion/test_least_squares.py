"""The banded three-point least squares (motion/least_squares.py) against a dense solve."""

from __future__ import annotations

import numpy as np

from motion_env.motion.least_squares import three_point_least_squares


def test_banded_solve_equals_the_dense_least_squares() -> None:
    rng = np.random.default_rng(0)
    t_len, dims = 30, 2
    coef = rng.normal(size=(t_len - 2, 3))
    rhs = rng.normal(size=(t_len - 2, dims))
    weight = rng.uniform(0.1, 2.0, t_len)
    target = rng.normal(size=(t_len, dims))
    rows = np.zeros((t_len - 2 + t_len, t_len))
    for i in range(t_len - 2):
        rows[i, i : i + 3] = coef[i]
    rows[t_len - 2 :] = np.diag(np.sqrt(weight))
    b = np.concatenate([rhs, np.sqrt(weight)[:, None] * target])
    dense = np.linalg.lstsq(rows, b, rcond=None)[0]
    np.testing.assert_allclose(three_point_least_squares(coef, rhs, weight, target), dense, atol=1e-10)
