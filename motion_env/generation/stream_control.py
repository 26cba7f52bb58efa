"""Joint targets and height limits while streaming (:class:`~motion_env.generation.streaming.MotionStream`).

The stream decodes one token (``rate`` frames) at a time and never changes a frame it has decoded,
so its refinement is causal and closed-form (the gradient steps of the whole-clip refinement, up to
24 decodes of the whole clip, do not fit in a real-time step):

- a pelvis target inside the controller's look-ahead (``path_horizon`` frames, 1 s) becomes an
  anchor of the path, which is bent linearly towards it from the last decoded frame, as timed
  waypoints are (so the pelvis passes exactly through its x, z);
- every targeted joint is blended into its target over the FADE frames (0.5 s) before the
  target's frame and its leftover correction fades out over FADE frames after it
  (:func:`~motion_env.generation.closed_form.causal_field`), then the closed-form finish of
  :func:`~motion_env.generation.closed_form.solve_limbs` solves the limbs (pelvis height, spine, legs,
  arms). A target is therefore met if it is given at least FADE frames before its frame; one
  given later is still met at its frame, with a quicker blend.
- :class:`~motion_env.objectives.HeightLimit` works as for whole clips (the bound eases in over
  FADE frames before the limited frames).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from motion_env.generation.closed_form import FADE, PELVIS, causal_field, limit_bounds, solve_limbs
from motion_env.joint_targets import JointTargets
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
        self.targets: list[JointTargets] = [JointTargets.empty() for _ in range(batch)]
        self.limits: list[list[HeightLimit]] = [[] for _ in range(batch)]
        self.carry: list[dict[int, Any]] = [{} for _ in range(batch)]
        self.errors: list[list[tuple[int, int, float]]] = [[] for _ in range(batch)]

    def reset(self, i: int) -> None:
        self.targets[i], self.limits[i], self.carry[i], self.errors[i] = JointTargets.empty(), [], {}, []

    def active(self, i: int) -> bool:
        return bool(len(self.targets[i]) or self.limits[i] or self.carry[i])

    def set_targets(self, i: int, targets: JointTargets | None, decoded: int) -> None:
        """Replace character i's targets (frames are its episode frames).

        Targets of frames already decoded cannot be met (those frames never change): they are
        dropped with a warning, except those the character already had (a caller that re-sends
        its targets together with a new one, as the studio does, is not warned about the old)."""
        known = {(f, j) for f, j, _ in self.errors[i]}
        known |= set(zip(self.targets[i].frames.tolist(), self.targets[i].joints.tolist(), strict=True))
        self.targets[i] = JointTargets.empty()
        if targets is None:
            return
        past = targets.between(None, decoded)
        late = sorted({int(f) for f, j in zip(past.frames, past.joints, strict=True) if (f, j) not in known})
        if late:
            warnings.warn(
                f"joint_targets of character {i}: frames {late[:10]}{' ...' if len(late) > 10 else ''} are "
                f"already generated (the stream has decoded up to frame {decoded - 1}; frames never change "
                "once decoded): those targets are not used",
                UserWarning,
                stacklevel=3,
            )
        self.targets[i] = targets.between(decoded, None)

    def pelvis_anchors(self, i: int, anchor: int, last: int) -> np.ndarray:
        """(M, 3) x, z and frame (relative to `anchor`) of the pelvis targets in (anchor, last]."""
        pelvis = self.targets[i].of_joint(PELVIS).between(anchor + 1, last + 1)
        rows = np.column_stack([pelvis.positions[:, 0], pelvis.positions[:, 2], pelvis.frames - anchor])
        return rows.astype(np.float32).reshape(-1, 3)

    def apply(self, i: int, first: int, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """Character i's new frames first.. (n, 22, 3), feet pinned, -> the frames with their targets met.

        contacts: (n, 4) the decoded foot contacts (> 0.5 planted).
        """
        n = len(joints)
        window = self.targets[i].dense(n + FADE + 1, first).astype(np.float64)
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
        out = solve_limbs(joints, desired.astype(np.float32), [], planted, bounds=(low, high))
        done = self.targets[i].between(first, first + n)
        for f, j, target in zip(done.frames, done.joints, done.positions, strict=True):
            self.errors[i].append((int(f), int(j), float(np.linalg.norm(out[f - first, j] - target))))
        self.targets[i] = self.targets[i].between(first + n, None)
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
