"""The IK's stacked frame task: its errors are what they say, its Jacobian their derivative."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

pytest.importorskip("mink")

from motion_env.retarget.frame_tasks import FrameTargets, inverse_left_jacobian, rotation_vectors  # noqa: E402


def test_rotation_vectors_match_scipy_up_to_a_half_turn() -> None:
    turns = Rotation.random(300, random_state=1)
    np.testing.assert_allclose(rotation_vectors(turns.as_matrix()), turns.as_rotvec(), atol=1e-9)
    half = Rotation.from_rotvec([[0.0, np.pi - 1e-9, 0.0], [1e-9, 0.0, 0.0]])
    got = rotation_vectors(half.as_matrix())
    np.testing.assert_allclose(np.abs(got), np.abs(half.as_rotvec()), atol=1e-6)


def test_inverse_left_jacobian_is_the_derivative_of_the_rotation_vector() -> None:
    rng = np.random.default_rng(0)
    for vector in [rng.normal(size=3), np.array([0.0, 0.0, 1e-6]), np.array([2.9, 0.3, -0.2])]:
        omega, h = rng.normal(size=3), 1e-7
        moved = (Rotation.from_rotvec(omega * h) * Rotation.from_rotvec(vector)).as_rotvec()
        numeric = (moved - Rotation.from_rotvec(vector).as_rotvec()) / h
        np.testing.assert_allclose(inverse_left_jacobian(vector[None])[0] @ omega, numeric, atol=1e-5)


@pytest.mark.parametrize("robot", ["unitree_g1", "booster_t1"])
def test_frame_targets_jacobian_is_the_derivative_of_its_error(robot: str) -> None:
    """On a random pose with random targets, moving the joints by a small step dq changes the
    stacked (weighted) error by the Jacobian times dq: positions, orientations and the centre of
    mass's x, y."""
    import mink
    import mujoco

    from motion_env.retarget import load_robot

    bot = load_robot(robot)
    rng = np.random.default_rng(2)
    task = FrameTargets(bot, com_cost=20.0)
    k = len(bot.tasks)
    turns = Rotation.random(k, random_state=3).as_matrix()
    task.set_targets(rng.normal(size=(k, 3)), turns, rng.normal(size=3))
    q = bot.home.copy()
    joints = slice(7, bot.model.nq)
    q[joints] += 0.1 * rng.normal(size=bot.model.nq - 7)
    configuration = mink.Configuration(bot.model)
    configuration.update(q)
    weighted_jacobian, weighted_error, _ = task.compute_qp_residual(configuration)
    assert weighted_jacobian.shape == (len(task.cost), bot.model.nv)
    step = 1e-6 * rng.normal(size=bot.model.nv)
    moved = q.copy()
    mujoco.mj_integratePos(bot.model, moved, step, 1.0)
    configuration.update(moved)
    _, moved_error = task.compute_qp_residual(configuration)[:2]
    # The weighted error is -cost * error: it moves by -(weighted Jacobian) @ step.
    np.testing.assert_allclose(moved_error - weighted_error, -weighted_jacobian @ step, atol=1e-9, rtol=1e-3)
