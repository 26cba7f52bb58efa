"""The settings of the motion_env environments (:class:`EnvConfig`) and the checks of what a user
hands them: actions, starts, caption pools."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np

from motion_env.generation.request import check_text
from motion_env.motion.trajectory import MAX_COORDINATE
from motion_env.motion.validation import CheckedConfig

DEFAULT_TEXT_POOL: tuple[str, ...] = (
    "a person walks forward",
    "a person walks slowly",
    "a person walks briskly",
    "a person jogs forward",
    "a person walks casually",
    "a person walks with long strides",
)


ACTION_MODES = ("normalized", "absolute", "relative")
INVALID_ACTION_MODES = ("raise", "hold")
LOOKAHEAD_MODES = ("auto", "head", "exact")
# Waypoints after the route target that the observation shows ("route_ahead").
ROUTE_AHEAD = 3
# Half-widths of the observation Boxes that are not bounded by nature (metres, m/s and rad/s, or
# the caption projection's units). Finite, so that the env checkers stay quiet; far beyond what a
# walking human produces, and observations are clipped into them.
OBS_BOUNDS = {
    "target": 4 * MAX_COORDINATE,
    "route_ahead": 4 * MAX_COORDINATE,
    "velocity": 100.0,
    "pose": 10.0,
}
OBS_BOUNDS["caption"] = 100.0


@dataclass
class EnvConfig(CheckedConfig):
    """The tunables of the motion_env environments (validated; see the env docstrings).

    The defaults are the ones measured for learning (README, "Learning"): normalised actions with
    a "follow the route" switch, four frames (one token, 0.2 s) per step, and a time cost.
    """

    action_mode: Annotated[str, ACTION_MODES] = "normalized"
    frames_per_step: int = 4
    arrive_radius: Annotated[float, "(0, inf)"] = 0.5
    terminate_on_arrival: bool = True
    arena_size: Annotated[float, "(0, inf)"] = 10.0
    snap_radius: Annotated[float, "[0, inf)"] = 0.05
    progress_weight: Annotated[float, "[0, inf)"] = 1.0
    arrival_bonus: Annotated[float, "[0, inf)"] = 1.0
    collision_penalty: Annotated[float, "[0, inf)"] = 1.0
    time_penalty: Annotated[float, "[0, inf)"] = 0.1
    reach: Annotated[float, "(0, inf)"] = 3.0
    follow_action: bool = True
    invalid_action: Annotated[str, INVALID_ACTION_MODES] = "raise"
    random_start: bool = False
    lookahead: Annotated[str, LOOKAHEAD_MODES] = "auto"
    route_length: tuple[int, int] = (2, 4)
    trail_length: int = 600

    def __post_init__(self) -> None:
        super().__post_init__()
        if int(self.frames_per_step) < 1 or int(self.frames_per_step) != self.frames_per_step:
            raise ValueError(
                f"EnvConfig.frames_per_step must be an integer >= 1, got {self.frames_per_step!r}"
            )
        self.frames_per_step = int(self.frames_per_step)
        if not isinstance(self.follow_action, (bool, np.bool_)):
            raise ValueError(f"EnvConfig.follow_action must be True or False, got {self.follow_action!r}")
        lo, hi = (int(v) for v in self.route_length)
        if not 1 <= lo <= hi:
            raise ValueError(
                f"EnvConfig.route_length must be (min, max) with 1 <= min <= max, got {self.route_length}"
            )
        self.route_length = (lo, hi)
        if int(self.trail_length) < 1:
            raise ValueError(f"EnvConfig.trail_length must be >= 1, got {self.trail_length}")

    @property
    def action_bound(self) -> float:
        """Half-width of the action Box: 1 (normalized), the arena (absolute), or (relative) any
        arena point from anywhere in it."""
        if self.action_mode == "normalized":
            return 1.0
        return self.arena_size if self.action_mode == "absolute" else 3.0 * self.arena_size

    @property
    def action_size(self) -> int:
        """2 (a point), or 3 with the normalized mode's "follow the route" switch."""
        return 3 if self.action_mode == "normalized" and self.follow_action else 2


# ----------------------------------------------------------------------------------------------
# Checking inputs
# ----------------------------------------------------------------------------------------------


def validate_start(start: Any) -> np.ndarray:
    """A start pose as (3,) float64 x, z, heading (ValueError otherwise)."""
    try:
        arr = np.array(start, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"start must be (x, z, heading): {exc}") from exc
    if arr.shape != (3,) or not np.isfinite(arr).all():
        raise ValueError(f"start must be three finite numbers (x, z, heading), got {start!r}")
    return arr


def validate_text_pool(text_pool: Sequence[str] | None) -> tuple[str, ...]:
    pool = DEFAULT_TEXT_POOL if text_pool is None else tuple(text_pool)
    if isinstance(text_pool, str) or not pool:
        raise ValueError(f"text_pool must be a non-empty sequence of captions, got {text_pool!r}")
    return tuple(check_text(t, f"text_pool[{i}]") for i, t in enumerate(pool))


def check_actions(
    actions: Any, batch: int, bound: float, invalid: str, size: int = 2
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a batch of actions.

    Args:
        actions: (B, size) (or (size,) when B = 1) numbers.
        batch: B.
        bound: the action Box's half-width; finite values beyond it are clipped.
        invalid: "raise" (ValueError for NaN/inf) or "hold" (those rows are flagged, not applied).
        size: numbers per action (2: a point; 3: a point and the follow switch).

    Returns:
        ((B, size) float64 clipped actions, (B,) bool valid rows, (B,) bool clipped rows).
    """
    what = "(x, z)" if size == 2 else "(x, z, follow)"
    try:
        raw = np.asarray(actions)
    except ValueError as exc:  # ragged nested lists
        raise ValueError(f"action must be numbers of shape ({batch}, {size}): {exc}") from None
    if raw.dtype.kind not in "biuf":  # complex parts would be dropped with only numpy's warning
        raise TypeError(f"action must be real numbers {what}, got dtype {raw.dtype}: {actions!r}")
    arr = raw.astype(np.float64)
    if batch == 1 and arr.shape == (size,):
        arr = arr[None]
    if arr.shape != (batch, size):
        expected = f"({size},)" if batch == 1 else f"({batch}, {size})"
        raise ValueError(f"action must have shape {expected} {what}, got {arr.shape}")
    valid = np.isfinite(arr).all(axis=1)
    if not valid.all() and invalid == "raise":
        rows = np.nonzero(~valid)[0].tolist()
        raise ValueError(
            f"action has NaN or infinite values (rows {rows}: {arr[~valid].tolist()}); the step was "
            "not taken and the episode can continue with a finite action (or make the env with "
            "invalid_action='hold' to keep the previous target instead)"
        )
    arr[~valid] = 0.0
    clipped = valid & (np.abs(arr) > bound).any(axis=1)
    return np.clip(arr, -bound, bound), valid, clipped
