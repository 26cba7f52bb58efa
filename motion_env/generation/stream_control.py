"""Joint targets and height limits while streaming (:class:`~motion_env.generation.streaming.MotionStream`).

The stream decodes one token (``rate`` frames) at a time and never changes a frame it has decoded,
so its refinement is causal and closed-form (the gradient steps of the whole-clip refinement, up to
24 decodes of the whole clip, do not fit in a real-time step):

- a pelvis target inside the controller's look-ahead (``path_horizon`` frames, 1 s) becomes an
  anchor of the path, which is bent linearly towards it from the last decoded frame, as timed
  waypoints are (so the pelvis passes exactly through its x, z);
- every targeted joint is blended into its target over the FADE frames (0.5 s) before the
  target's frame and its leftover correction fades out over FADE frames after it
  (:func:`~motion_env.generation.targets.causal_field`), then the closed-form finish of
  :func:`~motion_env.generation.targets.finish` solves the limbs (pelvis height, spine, legs,
  arms). A target is therefore met if it is given at least FADE frames before its frame; one
  given later is still met at its frame, with a quicker blend.
- :class:`~motion_env.objectives.HeightLimit` works as for whole clips (the bound eases in over
  FADE frames before the limited frames).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from motion_env.generation.targets import FADE, PELVIS, causal_field, finish, limit_bounds
from motion_env.motion.skeleton import JOINT_NAMES, NUM_JOINTS
from motion_env.objectives import HeightLimit

__all__ = ["StreamControl"]


class StreamControl:
    """The joint targets and height limits of B streamed characters, in episode frames.

    Attributes:
        errors: per character, a list of (frame, joint, metres) of every target the stream has
            emitted, and how far its joint was from it.
    """

    def __init__(self, batch: int) -> None:
        self.targets: list[dict[int, np.ndarray]] = [{} for _ in range(batch)]
        self.limits: list[list[HeightLimit]] = [[] for _ in range(batch)]
        self.carry: list[dict[int, Any]] = [{} for _ in range(batch)]
        self.errors: list[list[tuple[int, int, float]]] = [[] for _ in range(batch)]

    def reset(self, i: int) -> None:
        self.targets[i], self.limits[i], self.carry[i], self.errors[i] = {}, [], {}, []

    def active(self, i: int) -> bool:
        return bool(self.targets[i] or self.limits[i] or self.carry[i])

    def set_targets(self, i: int, targets: np.ndarray | None, first_frame: int, decoded: int) -> None:
        """Replace character i's targets: row k of (F, 22, 3) `targets` is episode frame first_frame + k."""
        self.targets[i] = {}
        if targets is None:
            return
        rows = np.flatnonzero(~np.isnan(targets[..., 0]).all(axis=1))
        late = [int(r) + first_frame for r in rows if r + first_frame < decoded]
        if late:
            warnings.warn(
                f"joint_targets of character {i}: frames {late[:10]}{' ...' if len(late) > 10 else ''} are "
                f"already generated (the stream has decoded up to frame {decoded - 1}; frames never change "
                "once decoded): those targets are not used",
                UserWarning,
                stacklevel=3,
            )
        for r in rows:
            if r + first_frame >= decoded:
                self.targets[i][int(r) + first_frame] = targets[r]

    def pelvis_anchors(self, i: int, anchor: int, last: int) -> np.ndarray:
        """(M, 3) x, z and frame (relative to `anchor`) of the pelvis targets in (anchor, last]."""
        rows = [
            (float(t[PELVIS, 0]), float(t[PELVIS, 2]), float(f - anchor))
            for f, t in sorted(self.targets[i].items())
            if anchor < f <= last and not np.isnan(t[PELVIS, 0])
        ]
        return np.array(rows, np.float32).reshape(-1, 3)

    def apply(self, i: int, first: int, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """Character i's new frames first.. (n, 22, 3), feet pinned, -> the frames with their targets met.

        contacts: (n, 4) the decoded foot contacts (> 0.5 planted).
        """
        n = len(joints)
        window = np.full((n + FADE + 1, NUM_JOINTS, 3), np.nan)
        for f in range(first, first + n + FADE + 1):
            if f in self.targets[i]:
                window[f - first] = self.targets[i][f]
        desired = np.full((n, NUM_JOINTS, 3), np.nan)
        for j in range(NUM_JOINTS):
            known = ~np.isnan(window[:, j, 0])
            if known.any() or j in self.carry[i]:
                desired[:, j], self.carry[i][j] = causal_field(
                    joints[:, j], window[:, j], known, self.carry[i].get(j)
                )
                if self.carry[i][j] is None or (not known.any() and self.carry[i][j][0] >= FADE):
                    del self.carry[i][j]
        bounds = limit_bounds(self.limits[i], first + n + FADE + 1)
        low, high = bounds[0][first : first + n], bounds[1][first : first + n]
        planted = (np.asarray(contacts) > 0.5).reshape(n, 2, 2).any(axis=2)
        out = finish(joints, desired.astype(np.float32), [], planted, bounds=(low, high))
        for f in range(first, first + n):
            if f in self.targets[i]:
                t = self.targets[i].pop(f)
                for j in np.flatnonzero(~np.isnan(t[:, 0])):
                    self.errors[i].append((f, int(j), float(np.linalg.norm(out[f - first, j] - t[j]))))
        return out

    def describe(self, i: int) -> str:
        """Character i's target errors so far, one line."""
        if not self.errors[i]:
            return "no targets emitted"
        d = np.array([e[2] for e in self.errors[i]])
        worst = self.errors[i][int(d.argmax())]
        return (
            f"{len(d)} targets: mean error {d.mean() * 100:.2f} cm, largest {d.max() * 100:.2f} cm "
            f"({JOINT_NAMES[worst[1]]} at frame {worst[0]})"
        )
