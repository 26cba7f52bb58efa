"""Flights of a run fall freely on the robot; the low-pass keeps a steady motion steady to the ends;
a retargeted run is plausible on both robots."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import pytest

from motion_env.retarget.flight import GRAVITY, MAX_FLIGHT, ballistic_lift, flights
from motion_env.retarget.smoothing import smooth_qpos

FPS = 50.0
RUNS = "bandai/dataset-2/bvh/dataset-2_run_active_{}.bvh.gz"  # held-out runs, cut in mid-stride


def _acceleration(height: np.ndarray) -> np.ndarray:
    return np.diff(height, 2) * FPS**2


def test_flights_are_the_runs_of_true() -> None:
    in_air = np.array([1, 1, 0, 0, 1, 0, 1, 1, 1], dtype=bool)
    assert flights(in_air) == [(0, 1), (4, 4), (6, 8)]
    assert flights(np.zeros(4, dtype=bool)) == []


def test_a_flight_between_two_stances_falls_at_g() -> None:
    """A hop whose centre rises and falls at half of g (the scaled arc) is made a free fall
    through the same take-off and landing heights; the stances are left as they are."""
    t = np.arange(40) / FPS
    height = 0.7 + 0.002 * np.sin(7 * t)  # standing, swaying
    in_air = (t >= 0.3) & (t < 0.5)
    air = t[in_air] - 0.28
    height[in_air] += 0.5 * 0.5 * GRAVITY * air * (0.22 - air)  # falls at g / 2
    lift = ballistic_lift(height, in_air, FPS)
    assert np.all(lift[~in_air] == 0)
    new = height + lift
    inside = np.flatnonzero(in_air)
    accel = _acceleration(new[inside[0] - 1 : inside[-1] + 2])
    np.testing.assert_allclose(accel, -GRAVITY, atol=1e-9)
    assert np.all(lift[in_air] > 0)  # a free fall over the same time rises higher


def test_a_flight_at_the_end_keeps_its_take_off_and_falls_at_g() -> None:
    height = np.full(20, 0.7)
    in_air = np.arange(20) >= 15
    height[in_air] += 0.3 * np.arange(1, 6) / FPS  # rising, no gravity
    new = height + ballistic_lift(height, in_air, FPS)
    assert new[14] == height[14]
    np.testing.assert_allclose(_acceleration(new[14:]), -GRAVITY, atol=1e-9)
    all_air = ballistic_lift(height, np.ones(20, dtype=bool), FPS)
    assert not all_air.any()  # no frame on the floor to start from: left as it is


def test_a_body_up_longer_than_a_jump_is_left_floating() -> None:
    """Both feet up for longer than MAX_FLIGHT is no jump (a clip that floats): made ballistic, it
    would rise metres; it is left as it is, for the replay to judge."""
    frames = int(np.ceil(MAX_FLIGHT * FPS)) + 5
    height = np.full(frames + 20, 0.7)
    in_air = np.zeros(frames + 20, dtype=bool)
    in_air[10 : 10 + frames] = True
    height[in_air] += 0.3
    assert not ballistic_lift(height, in_air, FPS).any()


def test_the_low_pass_keeps_a_steady_motion_steady_at_the_ends() -> None:
    """A root moving at a steady speed and a joint turning steadily are not braked near the
    clip's ends (a repeated end frame would decelerate them over the last few frames)."""
    model = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><freejoint/><geom size='.1'/><body><joint axis='0 1 0'/>"
        "<geom size='.1'/></body></body></worldbody></mujoco>"
    )
    n = 30
    qpos = np.zeros((n, model.nq))
    qpos[:, 0] = 3.0 * np.arange(n) / FPS  # 3 m/s
    qpos[:, 3] = 1.0
    qpos[:, 7] = 0.5 + 2.0 * np.arange(n) / FPS  # 2 rad/s
    out = smooth_qpos(model, qpos, 1.5)
    np.testing.assert_allclose(out, qpos, atol=1e-9)


@pytest.mark.parametrize(("robot", "take"), [("unitree_g1", "041"), ("booster_t1", "023")])
def test_a_retargeted_run_is_plausible_on_the_robot(
    robot: str, take: str, require_data: Callable[[str], Path]
) -> None:
    """A held-out run, retargeted: the robot replay judges it plausible. Before the flights fell
    freely and the clip's ends stayed steady, the G1 needed a root force of 6.4 N/kg on run 041
    (threshold 4.5); with those but without the centre of mass tracked, the T1 a root torque of
    3.3 N m/kg on run 023 (threshold 3.2)."""
    import motion_env
    from motion_env.replay import evaluate_robot
    from motion_env.retarget import load_robot

    motion = motion_env.load_motion(require_data(RUNS.format(take)))
    result = motion_env.retarget(motion, robot=robot, fps=FPS)
    report = evaluate_robot(result.qpos, load_robot(robot).model, FPS)
    assert report["plausible"], report["summary"]
