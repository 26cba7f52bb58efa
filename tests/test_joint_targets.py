"""JointTargets: the one sparse type for joint targets, and its round trips with the dense form."""

from __future__ import annotations

import numpy as np
import pytest

import motion_env
from motion_env.generation.request_controls import check_joint_targets
from motion_env.joint_targets import JointTargets


def test_dense_round_trip_and_order() -> None:
    dense = np.full((30, 22, 3), np.nan, np.float32)
    dense[20, 21] = [0.3, 1.6, 1.2]
    dense[5, 0] = [0.0, 0.9, 1.0]
    dense[5, 15] = [0.1, 1.7, 1.0]
    t = JointTargets.from_dense(dense, first_frame=100)
    assert t.frames.tolist() == [105, 105, 120] and t.joints.tolist() == [0, 15, 21]
    np.testing.assert_array_equal(t.dense(30, first_frame=100), dense)
    assert JointTargets.from_rows(t.rows()) == t
    assert motion_env.JointTargets is JointTargets


def test_entries_by_name_window_and_replacement() -> None:
    t = JointTargets.from_entries([(40, "right_wrist", (0.3, 1.6, 1.2)), (10, 0, (0.5, 0.9, 2.0))])
    assert t.frames.tolist() == [10, 40]
    assert len(t.between(11, None)) == 1 and len(t.between(None, 11)) == 1
    assert t.of_joint(0).frames.tolist() == [10]
    moved = t.with_entry(40, 21, (0.0, 1.0, 0.0))
    assert len(moved) == 2 and moved.positions[1].tolist() == [0.0, 1.0, 0.0]
    assert len(JointTargets.empty()) == 0 and "empty" in repr(JointTargets.empty())


@pytest.mark.parametrize(
    ("frames", "joints", "positions", "match"),
    [
        ([1], [22], [[0, 0, 0]], "joints must be integers 0..21"),
        ([-1], [0], [[0, 0, 0]], "frames must be integers >= 0"),
        ([1.5], [0], [[0, 0, 0]], "frames must be integers"),
        ([1], [0], [[0, np.nan, 0]], "non-finite position at frame 1, joint pelvis"),
        ([1, 1], [3, 3], [[0, 0, 0], [1, 1, 1]], "two entries for joint spine1 at frame 1"),
        ([1, 2], [0], [[0, 0, 0]], r"one N"),
    ],
)
def test_bad_entries_name_the_problem(frames, joints, positions, match) -> None:
    with pytest.raises(ValueError, match=match):
        JointTargets(np.array(frames), np.array(joints), np.array(positions, float))


def test_request_check_takes_both_forms() -> None:
    dense = np.full((10, 22, 3), np.nan, np.float32)
    dense[4, 20] = [0.1, 1.2, 0.3]
    sparse = check_joint_targets(dense, 10)
    assert isinstance(sparse, JointTargets) and check_joint_targets(sparse, 10) == sparse
    assert check_joint_targets(np.full((10, 22, 3), np.nan), 10) is None
    with pytest.raises(ValueError, match="outside the clip's num_frames=4"):
        check_joint_targets(sparse, 4)
    far = JointTargets.from_entries([(2, 0, (1e6, 1.0, 0.0))])
    with pytest.raises(ValueError, match="frame 2, joint 0 .pelvis. is .*within"):
        check_joint_targets(far, 10)


def test_generator_and_stream_read_sparse_as_dense() -> None:
    gen = motion_env.MotionGenerator.random()
    dense = np.full((24, 22, 3), np.nan, np.float32)
    dense[16, 21] = [0.2, 1.1, 0.5]
    sparse = JointTargets.from_dense(dense)
    a = gen.generate("a person walks", num_frames=24, seed=1, joint_targets=dense).joints
    b = gen.generate("a person walks", num_frames=24, seed=1, joint_targets=sparse).joints
    np.testing.assert_array_equal(a, b)
    runs = []
    for targets in (dense, sparse):
        stream = gen.stream(["a person walks"], seed=2)
        stream.set_joint_targets(targets, first_frame=0 if targets is dense else None)
        runs.append(np.stack([stream.step() for _ in range(24)]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_unreachable_targets_warn_naming_the_frames() -> None:
    high = JointTargets.from_entries([(12, "head", (0.0, 2.4, 1.0)), (30, "right_wrist", (0.0, 2.0, 1.0))])
    match = r"head at frame 12 \(y = 2.40 m\) is above what that joint can reach"
    with pytest.warns(UserWarning, match=match):
        check_joint_targets(high, 40)
    low = JointTargets.from_entries([(5, "left_wrist", (0.0, -0.3, 0.0))])
    with pytest.warns(UserWarning, match="left_wrist at frame 5 .* below the floor"):
        check_joint_targets(low, 40)
