"""Quality metrics, as ``docs/metrics.md`` defines them (numpy; one implementation each).

- root error: :func:`motion_env.motion.trajectory.waypoint_errors` (pure path math, used by the
  trainers too) averaged over waypoints;
- foot skating: :func:`foot_skating_ratio`;
- foot contacts of a clip without contact labels: :func:`detect_foot_contacts`;
- route following over many clips: :func:`route_summary` (root, location and trajectory error);
- caption steering: :func:`speed_and_cadence`, :func:`wrist_heights`, :func:`heading_change`;
- smoothness: :func:`joint_acceleration`, :func:`joint_jerk`;
- distributions of clip features: :func:`frechet_distance`, :func:`diversity`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motion_env.motion.skeleton import FOOT_JOINTS, FPS, JOINT_INDEX
from motion_env.motion.trajectory import root_path_from_joints
from motion_env.motion.validation import check_joints

__all__ = [
    "check_settings",
    "MISS",
    "SKATE_HEIGHT",
    "SKATE_STEP",
    "detect_foot_contacts",
    "diversity",
    "foot_skating_ratio",
    "frechet_distance",
    "heading_change",
    "joint_acceleration",
    "joint_jerk",
    "route_summary",
    "speed_and_cadence",
    "wrist_heights",
]

MISS = 0.5  # metres: a waypoint missed by more than this counts in the location/trajectory errors
# Foot skating: a foot joint below this height (m) ...
SKATE_HEIGHT = 0.05
# ... that moves more than this (m) horizontally from the previous frame (at 20 fps).
SKATE_STEP = 0.025


def foot_skating_ratio(joints: np.ndarray, height: float = SKATE_HEIGHT, step: float = SKATE_STEP) -> float:
    """Share of frames in which a foot joint (ankle or toe) below `height` m moves more than `step` m.

    The definition of ``docs/metrics.md``: frame t (t >= 1) skates when any of the four foot joints is below
    `height` at t and its XZ moved more than `step` from t-1 (20 fps). Returns 0 for a single frame.
    """
    joints = check_joints(joints)
    if joints.shape[0] < 2:
        return 0.0
    feet = joints[:, list(FOOT_JOINTS)]  # (T, 4, 3)
    low = feet[1:, :, 1] < height
    moved = np.linalg.norm(feet[1:, :, [0, 2]] - feet[:-1, :, [0, 2]], axis=-1) > step
    return float((low & moved).any(axis=1).mean())


def detect_foot_contacts(joints: np.ndarray, margin: float = 0.03, max_speed: float = 1.0) -> np.ndarray:
    """Foot contacts from height and speed: (T, 22, 3) -> (T, 4) bool for FOOT_JOINTS.

    A foot joint is in contact when it is within `margin` m of its own resting height (the 5th
    percentile of its height over the clip, so a clip that floats or sinks still works) and moves
    slower than `max_speed` m/s; isolated single frames are dropped.
    """
    joints = check_joints(joints)
    feet = joints[:, list(FOOT_JOINTS)]
    rest = np.percentile(feet[..., 1], 5, axis=0)
    step = np.zeros(feet.shape[:2])
    if len(feet) > 1:
        d = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1)
        step[1:] = d
        step[0] = d[0]
    contact = (feet[..., 1] < rest + margin) & (step * FPS < max_speed)
    lone = contact.copy()
    lone[1:-1] &= ~contact[:-2] & ~contact[2:]
    if len(contact) > 2:
        contact[1:-1] &= ~lone[1:-1]
    return contact


def route_summary(errors: list[np.ndarray]) -> dict[str, float]:
    """Per-clip waypoint misses (m) -> root error (cm), location/trajectory error, max miss (cm)."""
    if not errors:
        return {"clips": 0}
    flat = np.concatenate(errors)
    return {
        "root_error_cm": float(flat.mean() * 100),
        "location_error": float((flat > MISS).mean()),
        "trajectory_error": float(np.mean([e.max() > MISS for e in errors])),
        "max_miss_cm": float(flat.max() * 100),
        "clips": len(errors),
        "waypoints": int(flat.size),
    }


def speed_and_cadence(joints: np.ndarray, skip: int = 20) -> tuple[float, float]:
    """Mean pelvis speed (m/s) and cadence (foot strikes per second) after the first `skip` frames."""
    j = np.asarray(joints, np.float64)[skip:]
    if len(j) < 2:
        return 0.0, 0.0
    xz = j[:, 0, [0, 2]]
    speed = float(np.linalg.norm(np.diff(xz, axis=0), axis=1).sum() / (len(j) - 1) * FPS)
    contact = detect_foot_contacts(j)  # (T, 4): left ankle, left toe, right ankle, right toe
    strikes = 0
    for foot in (contact[:, :2].any(axis=1), contact[:, 2:].any(axis=1)):
        strikes += int(np.sum(foot[1:] & ~foot[:-1]))
    return speed, strikes / ((len(j) - 1) / FPS)


def wrist_heights(joints: np.ndarray) -> dict[str, float]:
    """Mean right- and left-wrist height above the pelvis (cm) and their difference."""
    j = np.asarray(joints, np.float64)
    right = (j[:, JOINT_INDEX["right_wrist"], 1] - j[:, 0, 1]).mean() * 100
    left = (j[:, JOINT_INDEX["left_wrist"], 1] - j[:, 0, 1]).mean() * 100
    return {"right_cm": float(right), "left_cm": float(left), "right_minus_left_cm": float(right - left)}


def heading_change(joints: np.ndarray) -> float:
    """How far the body turns over a clip (degrees; positive = counterclockwise seen from above,
    a left turn for a body facing +Z with +X on its left)."""
    heading = np.unwrap(root_path_from_joints(np.asarray(joints, np.float64))[:, 2])
    return float(np.rad2deg(heading[-1] - heading[0]))


def joint_acceleration(joints: np.ndarray, fps: float = FPS) -> np.ndarray:
    """|second finite difference| x fps^2 of every joint: (T, 22, 3) -> (T-2, 22) m/s^2."""
    joints = check_joints(joints)
    return np.linalg.norm(np.diff(joints, n=2, axis=0), axis=-1) * fps**2


def joint_jerk(joints: np.ndarray, fps: float = FPS) -> np.ndarray:
    """|third finite difference| x fps^3 of every joint: (T, 22, 3) -> (T-3, 22) m/s^3."""
    joints = check_joints(joints)
    return np.linalg.norm(np.diff(joints, n=3, axis=0), axis=-1) * fps**3


def frechet_distance(a: np.ndarray, b: np.ndarray, b_weights: np.ndarray | None = None) -> float:
    """Fréchet distance between Gaussians fitted to two sets of feature vectors (as FID).

    ``|mu_a - mu_b|^2 + tr(S_a + S_b - 2 (S_a S_b)^(1/2))`` for (N, D) `a` and (M, D) `b`,
    N, M >= 2. With fewer samples than dimensions the covariances are rank-deficient and the
    distance carries a bias that shrinks with N: compare distances of sets of similar sizes.
    `b_weights` ((M,) >= 0, not all 0; None: equal) weigh b's rows in its mean and covariance
    (``np.cov``'s ``aweights``): a reference resampled to another mix of classes.
    """
    import warnings

    from scipy import linalg

    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or min(len(a), len(b)) < 2:
        raise ValueError(f"need two (N >= 2, D) feature sets of one width, got {a.shape} and {b.shape}")
    w = _check_weights(b_weights, len(b))
    mu = a.mean(0) - w @ b
    sa, sb = np.cov(a, rowvar=False), np.cov(b, rowvar=False, aweights=w)
    with warnings.catch_warnings():
        # Fewer samples than dimensions make the product singular, as the docstring says.
        warnings.simplefilter("ignore", linalg.LinAlgWarning)
        root = linalg.sqrtm(sa @ sb)
        if not np.isfinite(root).all():
            # pytorch-fid's remedy for a square root that fails: a small ridge on both.
            ridge = np.eye(len(sa)) * 1e-6
            root = linalg.sqrtm((sa + ridge) @ (sb + ridge))
    return float(mu @ mu + np.trace(sa) + np.trace(sb) - 2 * np.trace(np.real(root)))


def diversity(features: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Mean Euclidean distance between the feature vectors of every pair of clips ((N, D), N >= 2).

    The diversity of text-to-motion papers averages random pairs; with a few clips per action
    every pair is used instead. `weights` ((N,) >= 0, not all 0; None: equal): pair (i, j)
    counts ``weights[i] * weights[j]``, as in :func:`frechet_distance`.
    """
    x = np.asarray(features, np.float64)
    if x.ndim != 2 or len(x) < 2:
        raise ValueError(f"need (N >= 2, D) features, got {x.shape}")
    w = _check_weights(weights, len(x))
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    i, j = np.triu_indices(len(x), 1)
    return float(np.average(d[i, j], weights=w[i] * w[j]))


def _check_weights(weights: np.ndarray | None, n: int) -> np.ndarray:
    """(n,) weights summing to 1 (equal when None); ValueError naming the shape or the values."""
    if weights is None:
        return np.full(n, 1.0 / n)
    w = np.asarray(weights, np.float64)
    if w.shape != (n,) or not np.isfinite(w).all() or (w < 0).any() or w.sum() <= 0:
        raise ValueError(f"weights must be ({n},) finite, >= 0 and not all 0, got shape {w.shape}")
    return w / w.sum()


def check_settings(settings: Any, **minimums: int) -> None:
    """The checks every evaluation's settings share: ``data`` names a dataset folder, ``split`` a
    split, and each field of `minimums` is an integer at least its value. ValueError naming the
    settings class and the field otherwise."""
    name = type(settings).__name__
    if not str(settings.data).strip():
        raise ValueError(f"{name}.data must name a dataset folder, got {settings.data!r}")
    if not settings.split.strip():
        raise ValueError(f"{name}.split must be a split name, got {settings.split!r}")
    for attr, low in minimums.items():
        value = getattr(settings, attr)
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise ValueError(f"{name}.{attr} must be an integer >= {low}, got {value!r}")
