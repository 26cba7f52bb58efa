"""Checks shared across the package: array shapes and values, and the fields of config dataclasses.

Each raises ValueError naming the argument or the field (``VQVAEConfig.width must be ...``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from motion_env.motion.skeleton import NUM_JOINTS

EPS = 1e-8
"""Guards divisions by a norm."""


def check_last(x: np.ndarray, size: int, name: str) -> np.ndarray:
    x = np.asarray(x)
    if x.ndim < 1 or x.shape[-1] != size:
        raise ValueError(f"{name} must have shape (..., {size}), got {x.shape}")
    return x


def check_joints(
    joints: np.ndarray, name: str = "joints", min_frames: int = 1, batched: bool = False
) -> np.ndarray:
    """Validate a (T, 22, 3) array (with `batched`, also (B, T, 22, 3)) and return it as float64."""
    joints = np.asarray(joints)
    ndim_ok = joints.ndim == 3 or (batched and joints.ndim == 4)
    if not ndim_ok or joints.shape[-2:] != (NUM_JOINTS, 3) or joints.shape[-3] < min_frames:
        shape = f"(T, {NUM_JOINTS}, 3)" + (f" or (B, T, {NUM_JOINTS}, 3)" if batched else "")
        raise ValueError(f"{name} must have shape {shape} with T >= {min_frames}, got {joints.shape}")
    check_finite(joints.reshape(-1, NUM_JOINTS, 3) if batched else joints, name, "frames")
    return joints.astype(np.float64)


def check_finite(values: np.ndarray, name: str, index: str = "rows") -> None:
    """ValueError naming the first rows (`index`: "rows", "frames", ...) with NaN or infinite values."""
    if not np.isfinite(values).all():
        bad = np.unique(np.nonzero(~np.isfinite(values))[0])
        raise ValueError(f"{name} has NaN or infinite values at {index} {bad[:10].tolist()}")


def check_positive(value: Any, name: str, unit: str = "") -> float:
    """`value` as a float if it is a finite number > 0 (a rate, a mass, ...), else ValueError naming
    `name` (`unit` is appended to the expectation, e.g. " of kg")."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive finite number{unit}, got {value!r}") from None
    if not (np.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be a positive finite number{unit}, got {value!r}")
    return number


# ----------------------------------------------------------------------------------------------
# Fields of config dataclasses (called from their __post_init__)
# ----------------------------------------------------------------------------------------------


def check_positive_ints(config: Any, *names: str) -> None:
    """ValueError unless each named field of `config` is an int >= 1."""
    for name in names:
        value = getattr(config, name)
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"{type(config).__name__}.{name} must be a positive int, got {value!r}")


def check_at_least(config: Any, low: float, *names: str) -> None:
    """ValueError unless each named field of `config` is >= `low`."""
    for name in names:
        value = getattr(config, name)
        if not value >= low:
            raise ValueError(f"{type(config).__name__}.{name} must be >= {low}, got {value!r}")


def check_above(config: Any, low: float, *names: str) -> None:
    """ValueError unless each named field of `config` is > `low`."""
    for name in names:
        value = getattr(config, name)
        if not value > low:
            raise ValueError(f"{type(config).__name__}.{name} must be > {low}, got {value!r}")


def check_interval(config: Any, interval: str, *names: str) -> None:
    """ValueError unless each named field of `config` lies in `interval`, written as in maths:
    ``"(0, 1]"`` leaves 0 out and takes 1 in, ``"[0, 1)"`` the other way round."""
    low, high = (float(bound) for bound in interval[1:-1].split(","))
    for name in names:
        value = getattr(config, name)
        above = value > low if interval[0] == "(" else value >= low
        below = value < high if interval[-1] == ")" else value <= high
        if not (above and below):
            raise ValueError(f"{type(config).__name__}.{name} must be in {interval}, got {value!r}")


def check_fraction(config: Any, *names: str) -> None:
    """ValueError unless each named field of `config` is in [0, 1]."""
    check_interval(config, "[0, 1]", *names)
