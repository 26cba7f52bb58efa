"""Physically wrong versions of a motion, to check that :func:`motion_env.replay.evaluate`
catches them (tests, ``scripts/calibrate_replay.py``). Each returns a new :class:`Motion`; the
corrupted stretch starts in the middle of the clip unless `start` (a frame) is given."""

from __future__ import annotations

import numpy as np

from motion_env.motion.kinematics import heading_from_joints
from motion_env.motion.skeleton import FOOT_JOINTS
from motion_env.motion.types import Motion


def _start(motion: Motion, start: int | None, length: int) -> int:
    if start is None:
        start = max(0, (motion.num_frames - length) // 2)
    if not 0 <= start < motion.num_frames:
        raise ValueError(f"start frame {start} is outside the clip's {motion.num_frames} frames")
    return start


def _with(motion: Motion, joints: np.ndarray, what: str, fps: float | None = None) -> Motion:
    meta = dict(motion.meta, corruption=what)
    return Motion(joints=joints, fps=motion.fps if fps is None else fps, text=motion.text, meta=meta)


def raised(motion: Motion, height: float = 0.3, seconds: float = 1.0, start: int | None = None) -> Motion:
    """The whole body lifted by `height` m for `seconds` (floating)."""
    n = max(1, round(seconds * motion.fps))
    a = _start(motion, start, n)
    joints = motion.joints.copy()
    joints[a : a + n, :, 1] += height
    return _with(motion, joints, f"raised {height:g} m for {seconds:g} s from frame {a}")


def sunk(motion: Motion, depth: float = 0.15) -> Motion:
    """The whole clip lowered by `depth` m into the floor (penetration)."""
    joints = motion.joints.copy()
    joints[..., 1] -= depth
    return _with(motion, joints, f"sunk {depth:g} m")


def glide(motion: Motion, distance: float = 1.5, seconds: float = 1.0, start: int | None = None) -> Motion:
    """Insert `seconds` in which the pose of frame `start` is held while the body slides
    `distance` m forwards (foot skating); the rest of the clip follows from there. The default
    start is the frame of the clip's middle third with a foot lowest."""
    n = max(1, round(seconds * motion.fps))
    if start is None:
        # A pose with a foot on the floor (the lowest foot joint of the clip's middle third), so
        # that the held feet slide rather than hover.
        third = motion.num_frames // 3
        lowest = motion.joints[third : 2 * third + 1, list(FOOT_JOINTS), 1].min(axis=1)
        start = third + int(np.argmin(lowest)) if len(lowest) else 0
    a = _start(motion, start, 1)
    theta = float(heading_from_joints(motion.joints[a]))
    direction = np.array([np.sin(theta), 0.0, np.cos(theta)], dtype=np.float32)
    slide = (np.arange(n, dtype=np.float32) * distance / n)[:, None, None] * direction
    held = motion.joints[a][None] + slide
    joints = np.concatenate([motion.joints[:a], held, motion.joints[a:] + distance * direction])
    return _with(motion, joints, f"glides {distance:g} m in {seconds:g} s from frame {a}")


def teleport(motion: Motion, distance: float = 1.0, start: int | None = None) -> Motion:
    """The body jumps `distance` m sideways (world +X) between frame `start` - 1 and `start`."""
    a = max(1, _start(motion, start, 0))
    joints = motion.joints.copy()
    joints[a:, :, 0] += distance
    return _with(motion, joints, f"jumps {distance:g} m at frame {a}")


def sped_up(motion: Motion, factor: int = 3) -> Motion:
    """The clip played `factor` times too fast: every `factor`-th frame at the same frame rate."""
    if factor < 1:
        raise ValueError(f"speed-up factor must be a positive integer, got {factor}")
    return _with(motion, motion.joints[::factor].copy(), f"played {factor}x too fast")


ALL = {
    "floating": raised,
    "penetration": sunk,
    "foot_skating": glide,
    "teleport": teleport,
    "speed_up": sped_up,
}
"""Each corruption with default settings: raised 30 cm for a second, sunk 15 cm, gliding 1.5 m
in a second, a 1 m jump between two frames, played 3 times too fast."""

CAUGHT_BY: dict[str, frozenset[str]] = {
    "floating": frozenset({"floating"}),
    "penetration": frozenset({"penetration"}),
    "foot_skating": frozenset({"foot_skating"}),
    "teleport": frozenset({"speed"}),
    "speed_up": frozenset({"speed", "acceleration", "root_force", "root_torque"}),
}
"""The checks that should fail on each corruption (a clip played too fast may show in any of its
speeds, accelerations or the forces it needs)."""
