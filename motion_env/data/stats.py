"""The normalisation statistics of a built dataset (``Mean.npy`` / ``Std.npy``).

Mean and standard deviation are over the frames of the train split, merged clip by clip
(:class:`RunningStats`, so that worker processes can each summarise their clips); the standard
deviation is then averaged within each feature group as HumanML3D's ``cal_mean_variance`` does
(:func:`grouped_std`).
"""

from __future__ import annotations

import numpy as np

from motion_env.data.dataset import STD_GROUPS
from motion_env.motion.skeleton import FEATURE_DIM


class RunningStats:
    """Frame count, mean and sum of squared deviations, merged clip by clip (Chan et al.)."""

    def __init__(self) -> None:
        self.n = 0
        self.mean = np.zeros(FEATURE_DIM)
        self.m2 = np.zeros(FEATURE_DIM)

    def add(self, n: int, mean: np.ndarray, m2: np.ndarray) -> None:
        if n == 0:
            return
        total = self.n + n
        delta = mean - self.mean
        self.mean = self.mean + delta * (n / total)
        self.m2 = self.m2 + m2 + delta**2 * (self.n * n / total)
        self.n = total


def clip_stats(features: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """``(frames, mean, sum of squared deviations)`` of one clip's (T, 263) features, for
    :meth:`RunningStats.add`."""
    f = features.astype(np.float64)
    mean = f.mean(axis=0)
    return f.shape[0], mean, ((f - mean) ** 2).sum(axis=0)


def grouped_std(std: np.ndarray) -> np.ndarray:
    """HumanML3D's std post-processing: each feature group gets its mean standard deviation.

    std: (263,). A group whose features never vary (std 0) gets 1, so that normalising by it
    cannot divide by zero (HumanML3D has no such group; a tiny dataset can).
    """
    out = np.asarray(std, dtype=np.float64).copy()
    for group in STD_GROUPS:
        value = out[group].mean()
        out[group] = value if value > 1e-12 else 1.0
    return out
