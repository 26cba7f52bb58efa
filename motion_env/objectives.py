"""Objectives for the generator's test-time refinement: what a motion must do besides its caption.

Pass a list of them as ``MotionGenerator.generate(..., objectives=[...])`` (and to
``generate_batch`` and the stream). Each built-in objective is a cost of the whole clip's world
joints that is 0 when it holds, plus a closed-form finish in the generator (the path walks around
a :class:`KeepOut` circle, the body crouches under a :class:`HeightLimit`), so it holds exactly
rather than approximately:

- :class:`KeepOut`: no joint inside a vertical cylinder (a pillar, a table) of the floor;
- :class:`HeightLimit`: a joint below (``max_height``) or above (``min_height``) a height in a
  range of frames (the head under a beam, the hands above the head);
- :class:`StayInside`: every joint inside a polygon of the floor (a room, a square).

Any callable ``f(joints) -> scalar`` is an objective too: `joints` is the clip's differentiable
``torch.Tensor`` (T, 22, 3) of world positions (metres, Y up) and the refinement lowers the returned
0-d tensor by gradient steps (it has no closed-form finish, so it is met as far as the optimiser
gets). Joints are named as in :data:`motion_env.motion.skeleton.JOINT_NAMES` (``"head"``,
``"right_wrist"``, ...) or given by index. Torch is imported only when a cost is evaluated.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from motion_env.motion.skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS

if TYPE_CHECKING:
    import torch

__all__ = ["HeightLimit", "KeepOut", "StayInside", "joint_index", "joint_indices"]


def joint_index(joint: str | int, what: str = "joint") -> int:
    """A joint given by name (``"head"``) or index (15) -> its index; ValueError naming it otherwise."""
    if isinstance(joint, str):
        if joint not in JOINT_INDEX:
            close = [n for n in JOINT_NAMES if joint.lower().replace(" ", "_") in n]
            hint = (
                f" (did you mean {', '.join(close)}?)" if close else f"; joints are {', '.join(JOINT_NAMES)}"
            )
            raise ValueError(f"{what}: unknown joint name {joint!r}{hint}")
        return JOINT_INDEX[joint]
    if isinstance(joint, bool) or not isinstance(joint, int | np.integer) or not 0 <= int(joint) < NUM_JOINTS:
        raise ValueError(f"{what} must be a joint name or an index in [0, {NUM_JOINTS}), got {joint!r}")
    return int(joint)


def joint_indices(joints: Sequence[str | int] | str | int | None, what: str = "joints") -> tuple[int, ...]:
    """None (every joint), one joint or a sequence of joints -> a tuple of indices."""
    if joints is None:
        return tuple(range(NUM_JOINTS))
    if isinstance(joints, str | int | np.integer):
        return (joint_index(joints, what),)
    out = tuple(joint_index(j, f"{what}[{k}]") for k, j in enumerate(joints))
    if not out:
        raise ValueError(f"{what} is empty: give joint names, or None for every joint")
    return out


def _frame_range(frames: tuple[int, int] | None, num_frames: int) -> slice:
    """(start, stop) frames (stop exclusive, None = the whole clip) -> a slice within the clip."""
    if frames is None:
        return slice(0, num_frames)
    start, stop = frames
    return slice(max(0, int(start)), min(num_frames, int(stop)))


def _check_frames(frames: Any, what: str) -> tuple[int, int] | None:
    if frames is None:
        return None
    try:
        start, stop = (int(v) for v in frames)
        if any(float(v) != int(v) for v in frames):
            raise ValueError
    except (TypeError, ValueError):
        raise ValueError(f"{what}.frames must be (start, stop) frame indices, got {frames!r}") from None
    if not 0 <= start < stop:
        raise ValueError(f"{what}.frames must satisfy 0 <= start < stop, got {frames!r}")
    return start, stop


def _finite(value: Any, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a finite number, got {value!r}") from None
    if not np.isfinite(number):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return number


@dataclass(frozen=True)
class KeepOut:
    """No joint inside a vertical cylinder: ``center`` (x, z) world metres, ``radius`` metres.

    Args:
        center: (x, z) of the cylinder's axis.
        radius: metres (> 0).
        joints: the joints kept out (names or indices; None = all 22).
        frames: (start, stop) frames it applies to (stop exclusive; None = the whole clip).

    The generator bends the root path around the circle (by the body's reach) where it would
    pass through, and checks the finished clip.
    """

    center: tuple[float, float]
    radius: float
    joints: tuple[int, ...] | None = None
    frames: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        try:
            cx, cz = (_finite(v, "KeepOut.center") for v in self.center)
        except TypeError:
            raise ValueError(f"KeepOut.center must be (x, z), got {self.center!r}") from None
        object.__setattr__(self, "center", (cx, cz))
        radius = _finite(self.radius, "KeepOut.radius")
        if radius <= 0:
            raise ValueError(f"KeepOut.radius must be > 0 metres, got {self.radius!r}")
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "joints", joint_indices(self.joints, "KeepOut.joints"))
        object.__setattr__(self, "frames", _check_frames(self.frames, "KeepOut"))

    def __call__(self, joints: torch.Tensor) -> torch.Tensor:
        """Sum over frames and joints of the squared depth inside the cylinder (m²)."""
        j = joints[_frame_range(self.frames, joints.shape[0]), list(self.joints)]
        d = (j[..., [0, 2]] - j.new_tensor(self.center)).norm(dim=-1)
        return (self.radius - d).clamp_min(0.0).pow(2).sum()

    def violation(self, joints: np.ndarray) -> np.ndarray:
        """(T,) deepest joint inside the cylinder per frame, metres (0 where none is inside)."""
        out = np.zeros(len(joints))
        rows = _frame_range(self.frames, len(joints))
        j = np.asarray(joints, np.float64)[rows][:, list(self.joints)]
        d = np.linalg.norm(j[..., [0, 2]] - np.asarray(self.center), axis=-1)
        out[rows] = np.clip(self.radius - d, 0.0, None).max(axis=-1, initial=0.0)
        return out


@dataclass(frozen=True)
class HeightLimit:
    """A joint's height (y, metres above the floor) at most ``max_height`` and/or at least ``min_height``.

    Args:
        joint: a joint name (``"head"``) or index.
        max_height, min_height: metres; at least one of them.
        frames: (start, stop) frames it applies to (stop exclusive; None = the whole clip).

    The generator meets it in closed form where the optimiser did not: a head or pelvis limit
    moves the pelvis down (or up) with the feet kept where they are (the knees bend), a hand's
    or foot's limit re-solves that limb (two-bone IK); the change fades in and out over half a
    second around the frames.
    """

    joint: str | int
    max_height: float | None = None
    min_height: float | None = None
    frames: tuple[int, int] | None = None
    index: int = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "index", joint_index(self.joint, "HeightLimit.joint"))
        if self.max_height is None and self.min_height is None:
            raise ValueError("HeightLimit needs max_height, min_height or both")
        for name in ("max_height", "min_height"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _finite(getattr(self, name), f"HeightLimit.{name}"))
        if self.max_height is not None and self.min_height is not None and self.min_height > self.max_height:
            raise ValueError(
                f"HeightLimit.min_height {self.min_height} is above max_height {self.max_height}"
            )
        object.__setattr__(self, "frames", _check_frames(self.frames, "HeightLimit"))

    def __call__(self, joints: torch.Tensor) -> torch.Tensor:
        """Sum over the frames of the squared distance outside the limits (m²)."""
        y = joints[_frame_range(self.frames, joints.shape[0]), self.index, 1]
        cost = y.new_zeros(())
        if self.max_height is not None:
            cost = cost + (y - self.max_height).clamp_min(0.0).pow(2).sum()
        if self.min_height is not None:
            cost = cost + (self.min_height - y).clamp_min(0.0).pow(2).sum()
        return cost

    def bounds(self, num_frames: int) -> tuple[np.ndarray, np.ndarray]:
        """(T,) lowest and highest allowed height per frame (-inf / inf where free)."""
        low, high = np.full(num_frames, -np.inf), np.full(num_frames, np.inf)
        rows = _frame_range(self.frames, num_frames)
        if self.min_height is not None:
            low[rows] = self.min_height
        if self.max_height is not None:
            high[rows] = self.max_height
        return low, high

    def violation(self, joints: np.ndarray) -> np.ndarray:
        """(T,) how far the joint is outside the limits per frame, metres."""
        y = np.asarray(joints, np.float64)[:, self.index, 1]
        low, high = self.bounds(len(y))
        return np.maximum(np.clip(y - high, 0.0, None), np.clip(low - y, 0.0, None))


@dataclass(frozen=True)
class StayInside:
    """Every joint inside a polygon of the floor: ``polygon`` (K, 2) x, z corners, in order.

    Args:
        polygon: at least 3 (x, z) corners, either winding; convex polygons are met exactly,
            concave ones as far as the optimiser and the path's push get.
        joints: the joints kept inside (None = all 22).
        frames: (start, stop) frames it applies to (None = the whole clip).
    """

    polygon: Any
    joints: tuple[int, ...] | None = None
    frames: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        try:
            poly = np.asarray(self.polygon, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(
                f"StayInside.polygon must be (K, 2) x, z corners, got {self.polygon!r}"
            ) from None
        if poly.ndim != 2 or poly.shape[1] != 2 or len(poly) < 3:
            raise ValueError(f"StayInside.polygon must be (K, 2) with K >= 3 corners, got shape {poly.shape}")
        if not np.isfinite(poly).all():
            raise ValueError("StayInside.polygon has NaN or infinite corners")
        area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
        if abs(area) < 1e-6:
            raise ValueError("StayInside.polygon has no area")
        if area < 0:  # counter-clockwise in (x, z), so the inward normal is on the left of each edge
            poly = poly[::-1].copy()
        poly.setflags(write=False)
        object.__setattr__(self, "polygon", poly)
        object.__setattr__(self, "joints", joint_indices(self.joints, "StayInside.joints"))
        object.__setattr__(self, "frames", _check_frames(self.frames, "StayInside"))

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Edge start points (K, 2) and unit inward normals (K, 2)."""
        a = self.polygon
        d = np.roll(a, -1, axis=0) - a
        normal = np.stack([-d[:, 1], d[:, 0]], axis=1)
        return a, normal / np.linalg.norm(normal, axis=1, keepdims=True)

    def signed_depth(self, xz: np.ndarray) -> np.ndarray:
        """(..., 2) points -> (...) how far outside the polygon (m, > 0 outside, <= 0 inside;
        exact for convex polygons: the largest distance past an edge's line)."""
        a, n = self.edges()
        return -(((xz[..., None, :] - a) * n).sum(-1)).min(axis=-1)

    def __call__(self, joints: torch.Tensor) -> torch.Tensor:
        """Sum over frames and joints of the squared distance outside the polygon (m²)."""
        a, n = self.edges()
        j = joints[_frame_range(self.frames, joints.shape[0]), list(self.joints)][..., [0, 2]]
        inside = ((j[..., None, :] - j.new_tensor(a)) * j.new_tensor(n)).sum(-1)  # (T, J, K)
        return (-inside).clamp_min(0.0).pow(2).sum()

    def violation(self, joints: np.ndarray) -> np.ndarray:
        """(T,) farthest joint outside the polygon per frame, metres (0 where all are inside)."""
        out = np.zeros(len(joints))
        rows = _frame_range(self.frames, len(joints))
        j = np.asarray(joints, np.float64)[rows][:, list(self.joints)]
        out[rows] = np.clip(self.signed_depth(j[..., [0, 2]]), 0.0, None).max(axis=-1, initial=0.0)
        return out
