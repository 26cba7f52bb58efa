"""Tests of what the replay's public functions accept (motion_env.replay.inputs): a bad input
fails at once with a ValueError naming the argument, not deep inside the fit or MuJoCo."""

from __future__ import annotations

import types

import numpy as np
import pytest

from motion_env.replay import evaluate, evaluate_detailed, measure
from motion_env.replay.fit import clip_rest_directions, fit_qpos, fit_rotations
from motion_env.replay.mjcf import load_model, model_index
from motion_env.replay.plausibility import load_thresholds
from motion_env.replay.tracking import track


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_joints_changed_to_nan_after_construction_name_the_frames(standing_clip, bad) -> None:
    clip = standing_clip(1.5)
    clip.joints[5, 3, 1] = bad  # a Motion checks its joints when made; its array can change later
    clip.joints[7, 0, 0] = bad
    for run in (evaluate, evaluate_detailed, measure):
        with pytest.raises(ValueError, match=r"motion\.joints has NaN or infinite values at frames \[5, 7\]"):
            run(clip)


def test_a_motion_made_another_way_is_checked(standing_clip) -> None:
    joints = standing_clip(1.0).joints
    odd = types.SimpleNamespace(joints=joints[:, :21], fps=20.0)  # measure takes any joints + fps
    with pytest.raises(ValueError, match=r"motion\.joints must have shape \(T, 22, 3\).*got \(20, 21, 3\)"):
        measure(odd)
    with pytest.raises(ValueError, match=r"motion\.joints has NaN or infinite values at frames \[2\]"):
        measure(
            types.SimpleNamespace(joints=np.where(np.arange(20)[:, None, None] == 2, np.nan, joints), fps=20)
        )
    with pytest.raises(TypeError, match="motion_env.Motion"):
        measure(joints)
    with pytest.raises(TypeError, match="motion_env.Motion"):
        evaluate(joints)


@pytest.mark.parametrize("fps", [0.0, -20.0, float("nan"), float("inf")])
def test_a_rate_that_is_not_positive_is_named(standing_clip, fps) -> None:
    clip = standing_clip(1.0)
    clip.fps = fps
    for run in (evaluate, measure):
        with pytest.raises(ValueError, match=r"motion\.fps must be a positive finite number"):
            run(clip)


@pytest.mark.parametrize("mass", [0, -70.0, float("nan"), float("inf"), "heavy", None])
def test_a_mass_that_is_not_positive_is_named(standing_clip, mass) -> None:
    clip = standing_clip(1.0)
    for run in (evaluate, evaluate_detailed, measure):
        with pytest.raises(ValueError, match=r"^mass must be a positive finite number of kg, got"):
            run(clip, mass=mass)


def test_thresholds_missing_a_check_or_not_numbers(standing_clip) -> None:
    clip = standing_clip(1.0)
    thresholds = load_thresholds()
    with pytest.raises(ValueError, match=r"thresholds missing for \['speed'\]"):
        evaluate(clip, thresholds={k: v for k, v in thresholds.items() if k != "speed"})
    with pytest.raises(ValueError, match=r"thresholds\['speed'\] must be a number"):
        evaluate(clip, thresholds=dict(thresholds, speed="fast"))


def test_the_fit_checks_raw_arrays(standing_clip) -> None:
    joints = standing_clip(0.5).joints.astype(np.float64)
    model = load_model()
    index = model_index(model)
    bad = joints.copy()
    bad[2, 10] = np.nan
    for run in (lambda j: fit_qpos(j, model, index), fit_rotations, clip_rest_directions):
        with pytest.raises(ValueError, match=r"^joints has NaN or infinite values at frames \[2\]"):
            run(bad)
        with pytest.raises(ValueError, match=r"^joints must have shape \(T, 22, 3\)"):
            run(joints[:, :, :2])
    assert fit_qpos(joints, model, index).shape == (len(joints), model.nq)


def test_tracking_checks_its_gain(standing_clip) -> None:
    with pytest.raises(ValueError, match="^stiffness must be a positive finite number"):
        track(standing_clip(0.5), stiffness=0.0)
