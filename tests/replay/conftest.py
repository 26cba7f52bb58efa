"""Fixtures of the replay tests: a still standing clip, the humanoid's forward kinematics, and
real held-out takes (skipped with a reason when the shared data is absent)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest

from motion_env.motion.skeleton import NUM_JOINTS
from motion_env.motion.types import Motion
from motion_env.replay.humanoid import from_mujoco, rest_positions
from motion_env.replay.mjcf import model_index

BANDAI_DIR = "bandai/dataset-2/bvh"


def _standing_clip(seconds: float = 2.0) -> Motion:
    """The humanoid's rest pose held still, as a motion."""
    rest = rest_positions().astype(np.float32)
    return Motion(np.repeat(rest[None], round(20 * seconds), axis=0))


def _forward_kinematics(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Canonical joint positions (T, 22, 3) of the humanoid, in the motion frame."""
    index = model_index(model)
    data = mujoco.MjData(model)
    out = np.zeros((len(qpos), NUM_JOINTS, 3))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[t] = from_mujoco(data.site_xpos[index.joint_sites])
    return out


@pytest.fixture(scope="session")
def standing_clip() -> Callable[..., Motion]:
    """``standing_clip(seconds=2.0)`` -> the humanoid's rest pose held still."""
    return _standing_clip


@pytest.fixture(scope="session")
def forward_kinematics() -> Callable[[mujoco.MjModel, np.ndarray], np.ndarray]:
    """``forward_kinematics(model, qpos (T, nq))`` -> (T, 22, 3) joint positions, motion frame."""
    return _forward_kinematics


@pytest.fixture(scope="session")
def bandai(require_data: Callable[[str], Path]) -> Path:
    """The Bandai Namco dataset-2 BVH folder (skips when absent)."""
    return require_data(BANDAI_DIR)


@pytest.fixture(scope="session")
def held_out_takes(bandai: Path) -> list[Path]:
    """One test-split take per kind: walk, walk-turn-left, walk-turn-right, run (Bandai dataset 2)."""
    from motion_env.data.dataset import split_of

    picked = []
    for content in ("walk", "walk-turn-left", "walk-turn-right", "run"):
        files = sorted(bandai.glob(f"dataset-2_{content}_*.bvh.gz"))
        test = [f for f in files if split_of(f.name.split(".bvh")[0]) == "test"]
        assert test, f"no test-split {content} take in {bandai}"
        picked.append(test[0])
    return picked
