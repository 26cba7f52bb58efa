"""scripts/walk_direction.py: the facing-against-travel angle on made-up bodies, and a smoke run
on the untrained test model."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from motion_env.motion.skeleton import FACE_JOINTS, FPS, NUM_JOINTS

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "walk_direction.py"


def _script():
    spec = importlib.util.spec_from_file_location("walk_direction", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _body(velocity_xz: tuple[float, float], frames: int = 10) -> np.ndarray:
    """(frames, 22, 3) a body facing +Z (right side towards -X) whose joints all move at `velocity_xz` m/s."""
    pose = np.zeros((NUM_JOINTS, 3))
    r_hip, l_hip, r_sdr, l_sdr = FACE_JOINTS
    pose[[r_hip, r_sdr], 0], pose[[l_hip, l_sdr], 0] = -0.1, 0.1
    t = np.arange(frames)[:, None, None] / FPS
    step = np.array([velocity_xz[0], 0.0, velocity_xz[1]])
    return pose[None] + t * step


@pytest.mark.parametrize(
    ("velocity", "angle"), [((0.0, 1.0), 0.0), ((1.0, 0.0), 90.0), ((-1.0, 0.0), 90.0), ((0.0, -1.5), 180.0)]
)
def test_the_angle_between_facing_and_travel(velocity: tuple[float, float], angle: float) -> None:
    got = _script().directions(_body(velocity), min_speed=0.4)
    assert got.shape == (9,)
    np.testing.assert_allclose(got, angle, atol=1e-6)


def test_slow_frames_are_not_counted() -> None:
    module = _script()
    assert module.directions(_body((0.0, 0.3)), min_speed=0.4).shape == (0,)
    assert "backwards 100%" in module.shares([module.directions(_body((0.0, -1.0)), 0.4)])


def test_prints_every_route_for_clips_and_the_stream() -> None:
    argv = [sys.executable, str(SCRIPT), "--weights", "random", "--seeds", "1", "--frames", "12",
            "--text", "a person walks", "--min-speed", "0"]  # fmt: skip
    out = subprocess.run(argv, check=True, capture_output=True, text=True, timeout=300).stdout
    assert len(re.findall(r"clip: +(forwards|no moving)", out)) == 5, out
    assert len(re.findall(r"stream: +(forwards|no moving)", out)) == 5, out
