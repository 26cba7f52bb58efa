"""Fixtures of the render tests: a synthetic walking figure and a colour mask for pictures."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from motion_env import motion as M
from motion_env import skeleton as S
from motion_env.motion.types import Motion
from motion_env.render.drawing import hex_rgb

SMALL = {"width": 160, "height": 120}


def _walker(frames: int = 12, heading: float = 0.0, speed: float = 1.2, arms_out: bool = False) -> Motion:
    """A rest-pose body gliding along its heading at `speed` m/s (20 fps), feet on the floor."""
    rot = np.zeros((frames, S.NUM_JOINTS, 4))
    rot[..., 0] = 1.0
    rot[:, 0] = M.quat_from_yaw(np.full(frames, heading))
    t = np.arange(frames) / S.FPS
    root = np.stack([np.sin(heading) * speed * t, np.zeros(frames), np.cos(heading) * speed * t], -1)
    joints = M.forward_kinematics(root, rot)
    if arms_out:
        # Arms straight out sideways from the shoulders: the left hand far on the body's left.
        left = M.from_heading_frame(np.array([1.0, 0.0]), heading)
        for shoulder, elbow, wrist, side in ((16, 18, 20, 1.0), (17, 19, 21, -1.0)):
            out = np.array([left[0], 0.0, left[1]]) * side
            joints[:, elbow] = joints[:, shoulder] + 0.26 * out
            joints[:, wrist] = joints[:, shoulder] + 0.53 * out
    joints[..., 1] -= joints[..., 1].min()
    return Motion(joints.astype(np.float32), text="a person glides forward")


def _mask(img: np.ndarray, color: str, tol: float = 40.0) -> np.ndarray:
    """(H, W) pixels within `tol` (RGB distance) of a '#rrggbb' colour."""
    return np.linalg.norm(img.astype(float) - hex_rgb(color) * 255, axis=-1) < tol


@pytest.fixture(scope="session")
def small() -> dict[str, int]:
    """A small picture size (160x120) that keeps the tests fast."""
    return dict(SMALL)


@pytest.fixture(scope="session")
def walker() -> Callable[..., Motion]:
    """``walker(frames=12, heading=0.0, speed=1.2, arms_out=False)`` -> a synthetic gliding figure."""
    return _walker


@pytest.fixture(scope="session")
def mask() -> Callable[..., np.ndarray]:
    """``mask(img, "#rrggbb", tol=40)`` -> (H, W) bool: the pixels of that colour."""
    return _mask
