"""Fixtures of the retargeting tests: synthetic clips (no data needed) and a short real walk
(skipped with a reason when the shared data is absent). The original robot models are found by
the ``require_robot`` fixture of ``tests/conftest.py``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.motion.types import Motion
from motion_env.replay.humanoid import rest_positions

pytest.importorskip("mink", reason="the optional 'robots' extra (mink) is not installed")

WALK = "bandai/dataset-2/bvh/dataset-2_walk_normal_001.bvh.gz"
_RIGHT_ARM = [JOINT_INDEX[n] for n in ("right_elbow", "right_wrist")]


def _rotate_about_forward(points: np.ndarray, center: np.ndarray, angle: float) -> np.ndarray:
    """Rotate (..., 3) motion-frame points about the forward (+Z) axis through `center`."""
    c, s = np.cos(angle), np.sin(angle)
    rel = points - center
    return center + np.stack(
        [c * rel[..., 0] - s * rel[..., 1], s * rel[..., 0] + c * rel[..., 1], rel[..., 2]], -1
    )


def _waving_clip(frames: int = 30, raise_to: float = 2.0) -> Motion:
    """The canonical rest pose standing still, the right arm lifted sideways by up to `raise_to`
    radians and back (a smooth wave; the feet stay on the floor)."""
    rest = rest_positions()
    shoulder = rest[JOINT_INDEX["right_shoulder"]]
    joints = np.repeat(rest[None], frames, axis=0)
    # The right arm hangs at -x: turning it by -angle about +Z lifts it.
    angles = -raise_to * np.sin(np.linspace(0, np.pi, frames)) ** 2
    for t, a in enumerate(angles):
        joints[t, _RIGHT_ARM] = _rotate_about_forward(rest[_RIGHT_ARM], shoulder, a)
    return Motion(joints.astype(np.float32), text="a person raises the right arm")


def _crossing_clip(frames: int = 30) -> Motion:
    """The canonical rest pose standing still, both arms crossing in front of the chest and back:
    each wrist goes a hand's width in front of the other shoulder (the arms pass through the
    trunk of a robot that follows them blindly)."""
    rest = rest_positions()
    joints = np.repeat(rest[None], frames, axis=0).astype(np.float64)
    share = np.sin(np.linspace(0, np.pi, frames))[:, None] ** 2
    chest = rest[JOINT_INDEX["spine3"]]
    for side, other in (("left", "right"), ("right", "left")):
        wrist, elbow = JOINT_INDEX[f"{side}_wrist"], JOINT_INDEX[f"{side}_elbow"]
        # Motion axes: +Y up, +Z forward.
        target = chest + 0.6 * (rest[JOINT_INDEX[f"{other}_shoulder"]] - chest) + np.array([0, -0.12, 0.06])
        joints[:, wrist] = rest[wrist] + share * (target - rest[wrist])
        joints[:, elbow] = rest[elbow] + share * np.array([0.0, 0.0, 0.10])
    return Motion(joints.astype(np.float32), text="a person crosses the arms")


@pytest.fixture(scope="session")
def crossing_clip() -> Callable[..., Motion]:
    """``crossing_clip(frames=30)`` -> a standing clip that crosses both arms over the chest."""
    return _crossing_clip


@pytest.fixture(scope="session")
def waving_clip() -> Callable[..., Motion]:
    """``waving_clip(frames=30, raise_to=2.0)`` -> a standing clip that lifts the right arm."""
    return _waving_clip


@pytest.fixture(scope="session")
def real_walk(require_data: Callable[[str], Path]) -> Motion:
    """The first 3 s of a real walk (Bandai Namco, normal style); skips when the data is absent."""
    from motion_env.io.load import load_motion

    motion = load_motion(require_data(WALK))
    return Motion(motion.joints[:60], fps=motion.fps, text="a person walks")
