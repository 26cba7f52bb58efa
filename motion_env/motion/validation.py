"""Checks shared across the package: array shapes and values, and the fields of config dataclasses
(their bounds written in their annotations, checked by :class:`CheckedConfig`).

Each raises ValueError naming the argument or the field (``VQVAEConfig.width must be ...``).
"""

from __future__ import annotations

import functools
import typing
from collections.abc import Collection
from dataclasses import fields
from typing import Annotated, Any

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
# Fields of config dataclasses: each field's annotation carries its bounds (``Annotated``), and
# :class:`CheckedConfig` checks them when the config is made.
# ----------------------------------------------------------------------------------------------

PositiveInt = Annotated[int, ">= 1"]
NonNegativeInt = Annotated[int, ">= 0"]
PositiveFloat = Annotated[float, "> 0"]
NonNegativeFloat = Annotated[float, ">= 0"]
Fraction = Annotated[float, "[0, 1]"]


class CheckedConfig:
    """Base of the config dataclasses whose fields carry their bounds in their annotation.

    A field annotated ``Annotated[type, bounds]`` (or one of the aliases above: ``PositiveInt``,
    ``NonNegativeFloat``, ``Fraction``, ...) is checked by ``__post_init__``; `bounds` is
    ``">= 1"``, ``"> 0"``, an interval written as in maths (``"(0, 1]"`` leaves 0 out and takes
    1 in; ``"(0, inf)"`` is a finite positive number) or a collection of the allowed values. An
    ``int`` field must also hold an int (not a bool). A ValueError names the class, the field and
    the value (``VQVAEConfig.width must be >= 1, got 0``). A config with checks of its own (two
    fields together, a list of labels) calls ``super().__post_init__()`` first::

        @dataclass
        class Settings(CheckedConfig):
            steps: PositiveInt = 24
            rate: Annotated[float, "(0, 1]"] = 0.5
            mode: Annotated[str, ("fast", "exact")] = "fast"
    """

    def __post_init__(self) -> None:
        for name, kind, bounds in _declared_bounds(type(self)):
            _check_bounds(self, name, bounds, integer=kind is int)


@functools.cache
def _declared_bounds(cls: type) -> tuple[tuple[str, Any, Any], ...]:
    """(field, type, bounds) of each field of the dataclass `cls` annotated with bounds."""
    hints = typing.get_type_hints(cls, include_extras=True)
    return tuple(
        (f.name, *typing.get_args(hints[f.name])[:2])
        for f in fields(cls)
        if typing.get_origin(hints[f.name]) is Annotated
    )


def _check_bounds(config: Any, name: str, bounds: str | Collection[Any], integer: bool = False) -> None:
    """ValueError unless the field `name` of `config` lies in `bounds` (as in :class:`CheckedConfig`)
    and, with `integer`, is an int."""
    value = getattr(config, name)
    if isinstance(bounds, str):
        whole = isinstance(value, int) and not isinstance(value, bool)
        ok = _within(value, bounds) and (whole or not integer)
        expected = bounds if bounds[0] == ">" else f"in {bounds}"
        expected = f"an integer {expected}" if integer and not whole else expected
    else:
        ok, expected = value in bounds, f"one of {tuple(bounds)}"
    if not ok:
        raise ValueError(f"{type(config).__name__}.{name} must be {expected}, got {value!r}")


def _within(value: Any, bounds: str) -> bool:
    """Whether `value` is within `bounds` (``">= 1"``, ``"> 0"`` or an interval like ``"[0, 1)"``)."""
    try:
        if bounds.startswith(">="):
            return bool(value >= float(bounds[2:]))
        if bounds.startswith(">"):
            return bool(value > float(bounds[1:]))
        low, high = (float(bound) for bound in bounds[1:-1].split(","))
        above = value > low if bounds[0] == "(" else value >= low
        below = value < high if bounds[-1] == ")" else value <= high
        return bool(above and below)
    except TypeError:  # None, a string, ...: not a number at all
        return False
