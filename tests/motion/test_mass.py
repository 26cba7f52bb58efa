"""The centre of mass: one weighted sum of the joints, the replay humanoid's."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.motion.mass import COM_WEIGHTS, centre_of_mass
from motion_env.motion.skeleton import FPS


def test_centre_of_mass_moves_with_the_body() -> None:
    assert COM_WEIGHTS.sum() == pytest.approx(1.0)
    joints = np.random.default_rng(0).normal(size=(3, 22, 3))
    shifted = joints + np.array([0.3, -0.2, 1.0])
    np.testing.assert_allclose(centre_of_mass(shifted), centre_of_mass(joints) + [0.3, -0.2, 1.0], atol=1e-12)


def test_centre_of_mass_is_the_replays(humanml3d_sample) -> None:
    from motion_env.motion.types import Motion
    from motion_env.replay import measure
    from motion_env.replay.humanoid import to_mujoco

    joints, _ = humanml3d_sample
    replayed = measure(Motion(joints=joints[:40], fps=FPS)).com
    np.testing.assert_allclose(to_mujoco(centre_of_mass(joints[:40])), replayed, atol=0.005)
