"""Joint targets: where given joints must be at given frames, as one sparse type.

A :class:`JointTargets` is a list of entries (frame, joint, position): the joint with index
``joint`` (:data:`motion_env.motion.skeleton.JOINT_NAMES`) must be at ``position`` (world x, y, z,
metres) at ``frame`` (a clip's frame, or a streamed character's episode frame, 20 fps). The API,
the stream, the environments, the studio and the refinement all pass this one type; the dense
``(T, 22, 3)`` array with NaN where a joint is free stays accepted at the API's boundary
(:meth:`JointTargets.from_dense`) and is what the closed-form math reads (:meth:`JointTargets.dense`).

>>> t = JointTargets.from_entries([(40, "right_wrist", (0.3, 1.6, 1.2)), (60, 0, (0.5, 0.9, 2.0))])
>>> len(t), t.frames.tolist()
(2, [40, 60])
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from motion_env.motion.skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS

__all__ = ["JointTargets"]


@dataclass(frozen=True)
class JointTargets:
    """Sparse joint targets, sorted by frame, then joint; at most one entry per (frame, joint).

    Attributes:
        frames: (N,) int64 frame of each entry (>= 0).
        joints: (N,) int64 joint index of each entry (0..21).
        positions: (N, 3) float32 world x, y, z (metres, finite).
    """

    frames: np.ndarray
    joints: np.ndarray
    positions: np.ndarray

    def __post_init__(self) -> None:
        frames = np.asarray(self.frames).reshape(-1)
        joints = np.asarray(self.joints).reshape(-1)
        positions = np.asarray(self.positions, dtype=np.float64)
        n = len(frames)
        if len(joints) != n or positions.shape != (n, 3):
            raise ValueError(
                f"JointTargets needs frames (N,), joints (N,) and positions (N, 3) of one N, got "
                f"{frames.shape}, {joints.shape} and {positions.shape}"
            )
        for name, values, high in (("frames", frames, None), ("joints", joints, NUM_JOINTS - 1)):
            whole = np.all(np.mod(values, 1) == 0)
            if n and (not whole or values.min() < 0 or (high and values.max() > high)):
                bound = f"0..{high}" if high else ">= 0"
                raise ValueError(f"JointTargets.{name} must be integers {bound}, got {values.tolist()[:10]}")
        if not np.isfinite(positions).all():
            k = int(np.argwhere(~np.isfinite(positions).all(axis=1))[0, 0])
            raise ValueError(
                f"JointTargets has a non-finite position at frame {int(frames[k])}, joint "
                f"{JOINT_NAMES[int(joints[k])]}: {positions[k].tolist()}"
            )
        order = np.lexsort((joints, frames))
        frames, joints = frames[order].astype(np.int64), joints[order].astype(np.int64)
        same = (np.diff(frames) == 0) & (np.diff(joints) == 0)
        if same.any():
            k = int(np.argmax(same))
            raise ValueError(
                f"JointTargets has two entries for joint {JOINT_NAMES[int(joints[k])]} at frame "
                f"{int(frames[k])}"
            )
        object.__setattr__(self, "frames", frames)
        object.__setattr__(self, "joints", joints)
        object.__setattr__(self, "positions", positions[order].astype(np.float32))

    # ------------------------------------------------------------------ construction
    @classmethod
    def empty(cls) -> JointTargets:
        """No targets."""
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3), np.float32))

    @classmethod
    def from_dense(cls, array: np.ndarray, first_frame: int = 0) -> JointTargets:
        """(T, 22, 3) targets, NaN where a joint is free, row k = frame ``first_frame + k``.

        A joint counts as targeted where its x is not NaN (the request checks make the three
        coordinates all NaN or all numbers)."""
        arr = np.asarray(array, dtype=np.float32)
        if arr.ndim != 3 or arr.shape[1:] != (NUM_JOINTS, 3):
            raise ValueError(f"dense joint targets must have shape (T, {NUM_JOINTS}, 3), got {arr.shape}")
        where = np.argwhere(~np.isnan(arr[..., 0]))  # (N, 2) frame-major, joints ascending
        return cls(where[:, 0] + int(first_frame), where[:, 1], arr[where[:, 0], where[:, 1]])

    @classmethod
    def from_entries(cls, entries: Iterable[tuple[int, int | str, Sequence[float]]]) -> JointTargets:
        """(frame, joint index or name, (x, y, z)) entries."""
        rows = list(entries)
        if not rows:
            return cls.empty()
        joints = [JOINT_INDEX[j] if isinstance(j, str) else j for _, j, _ in rows]
        return cls(
            np.array([f for f, _, _ in rows]), np.array(joints), np.array([p for _, _, p in rows], np.float64)
        )

    @classmethod
    def from_rows(cls, rows: np.ndarray) -> JointTargets:
        """(N, 5) rows of frame, joint index, x, y, z (the form :meth:`rows` gives)."""
        arr = np.asarray(rows, dtype=np.float64).reshape(-1, 5)
        return cls(arr[:, 0], arr[:, 1], arr[:, 2:])

    # ------------------------------------------------------------------ views
    def __len__(self) -> int:
        return len(self.frames)

    def rows(self) -> np.ndarray:
        """(N, 5) float64 rows of frame, joint index, x, y, z."""
        return np.column_stack([self.frames, self.joints, self.positions]).astype(np.float64)

    def dense(self, num_frames: int, first_frame: int = 0) -> np.ndarray:
        """(num_frames, 22, 3) float32, row k = frame ``first_frame + k``, NaN where free; entries
        outside those frames are left out."""
        out = np.full((int(num_frames), NUM_JOINTS, 3), np.nan, np.float32)
        k = self.frames - int(first_frame)
        inside = (k >= 0) & (k < num_frames)
        out[k[inside], self.joints[inside]] = self.positions[inside]
        return out

    def between(self, first: int | None = None, stop: int | None = None) -> JointTargets:
        """The entries with ``first <= frame < stop`` (None: no bound)."""
        keep = np.ones(len(self), bool)
        if first is not None:
            keep &= self.frames >= first
        if stop is not None:
            keep &= self.frames < stop
        return self._select(keep)

    def of_joint(self, joint: int) -> JointTargets:
        """The entries of one joint."""
        return self._select(self.joints == joint)

    def with_entry(self, frame: int, joint: int, position: Sequence[float]) -> JointTargets:
        """A copy with one entry added (replacing the entry for that frame and joint, if any)."""
        keep = ~((self.frames == frame) & (self.joints == joint))
        return JointTargets(
            np.append(self.frames[keep], frame),
            np.append(self.joints[keep], joint),
            np.vstack([self.positions[keep], np.asarray(position, np.float64).reshape(1, 3)]),
        )

    def _select(self, keep: np.ndarray) -> JointTargets:
        # A subset of checked, sorted entries is checked and sorted: skip __post_init__ (the
        # stream takes subsets every token).
        out = object.__new__(JointTargets)
        for name in ("frames", "joints", "positions"):
            object.__setattr__(out, name, getattr(self, name)[keep])
        return out

    def __eq__(self, other: Any) -> bool:
        if not isinstance(other, JointTargets):
            return NotImplemented
        return (
            np.array_equal(self.frames, other.frames)
            and np.array_equal(self.joints, other.joints)
            and np.array_equal(self.positions, other.positions)
        )

    __hash__ = None  # type: ignore[assignment]  # mutable arrays inside

    def __repr__(self) -> str:
        if not len(self):
            return "JointTargets(empty)"
        return (
            f"JointTargets({len(self)} entries, frames {int(self.frames[0])}..{int(self.frames[-1])}, "
            f"joints {sorted({JOINT_NAMES[j] for j in self.joints.tolist()})})"
        )
