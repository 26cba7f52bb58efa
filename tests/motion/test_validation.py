"""The bounds of config fields (motion_env.motion.validation.CheckedConfig): written once in each
field's annotation, checked when the config is made, the error naming the class, field and value."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import pytest

from motion_env.motion.validation import CheckedConfig, Fraction, NonNegativeFloat, PositiveInt


@dataclass
class _Settings(CheckedConfig):
    steps: PositiveInt = 24
    weight: NonNegativeFloat = 0.5
    share: Fraction = 0.1
    rate: Annotated[float, "(0, 1]"] = 1.0
    size: Annotated[float, "(0, inf)"] = 2.0
    mode: Annotated[str, ("fast", "exact")] = "fast"
    note: str = ""  # no bounds: not checked


@dataclass
class _Pair(_Settings):
    low: int = 0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.low > self.steps:
            raise ValueError(f"_Pair.low ({self.low}) must be at most steps ({self.steps})")


def test_values_within_their_bounds_pass() -> None:
    _Settings(steps=1, weight=0.0, share=1.0, rate=0.001, size=1e9, mode="exact", note="anything")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"steps": 0}, "_Settings.steps must be >= 1, got 0"),
        ({"steps": 2.5}, "_Settings.steps must be an integer >= 1, got 2.5"),
        ({"steps": True}, "_Settings.steps must be an integer >= 1, got True"),
        ({"weight": -0.1}, "_Settings.weight must be >= 0, got -0.1"),
        ({"weight": float("nan")}, "_Settings.weight must be >= 0, got nan"),
        ({"weight": None}, "_Settings.weight must be >= 0, got None"),
        ({"share": 1.5}, r"_Settings.share must be in \[0, 1\], got 1.5"),
        ({"rate": 0.0}, r"_Settings.rate must be in \(0, 1\], got 0.0"),
        ({"size": float("inf")}, r"_Settings.size must be in \(0, inf\), got inf"),
        ({"mode": "slow"}, r"_Settings.mode must be one of \('fast', 'exact'\), got 'slow'"),
    ],
)
def test_a_value_out_of_bounds_names_the_class_field_and_value(changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=f"^{message}$"):
        _Settings(**changes)


def test_a_subclass_keeps_the_bounds_and_adds_its_own_checks() -> None:
    with pytest.raises(ValueError, match="_Pair.steps must be >= 1"):
        _Pair(steps=0)
    with pytest.raises(ValueError, match="must be at most steps"):
        _Pair(steps=2, low=3)
    assert _Pair(steps=3, low=3).low == 3
