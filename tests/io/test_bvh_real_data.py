"""motion_env.io's BVH import on the real motion capture of the shared data folder: Bandai walks,
runs and turns, a CMU walk, and (slow) every shared file."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from motion_env import motion as M
from motion_env import skeleton as S
from motion_env.io.bvh import load_bvh
from motion_env.io.load import load_motion

BANDAI = "bandai/dataset-2/bvh"
CMU = "cmu/bvh"


def _check_real_clip(joints: np.ndarray, walking: bool = True) -> None:
    """Floor, pelvis height, start pose, and left/right judged against where the feet point."""
    lowest = joints[:, list(S.FOOT_JOINTS), 1].min(axis=1)  # (T,) lowest foot joint per frame
    assert lowest.min() >= -0.03 and abs(np.percentile(lowest, 5)) <= 0.03
    if walking:  # a foot is always on the floor (runs have flight phases)
        assert np.median(lowest) <= 0.03
    assert 0.7 < np.median(joints[:, 0, 1]) < 1.15
    theta = M.heading_from_joints(joints)
    assert abs(theta[0]) < 1e-4
    np.testing.assert_allclose(joints[0, 0, [0, 2]], 0.0, atol=1e-5)
    # Heading comes from the left/right hips and shoulders; feet on the floor point forward only
    # if left and right are right (left hip at +X when facing +Z).
    for ankle, toe in ((7, 10), (8, 11)):
        stance = joints[:, ankle, 1] < 0.12
        toe_dir = (joints[stance, toe] - joints[stance, ankle])[:, [0, 2]]
        facing = np.stack([np.sin(theta[stance]), np.cos(theta[stance])], axis=-1)
        assert np.mean((toe_dir * facing).sum(-1) > 0) > 0.9
    assert joints[0, S.JOINT_INDEX["left_hip"], 0] > 0 > joints[0, S.JOINT_INDEX["right_hip"], 0]


@pytest.mark.parametrize("name", ["walk_normal_001", "walk_elderly_010", "run_normal_001", "run_active_005"])
def test_bandai_walks_and_runs_go_forward(name: str, require_data):
    path = require_data(f"{BANDAI}/dataset-2_{name}.bvh.gz")
    motion = load_motion(path)
    assert motion.fps == S.FPS and motion.meta["source"] == str(path) and motion.meta["dropped_frames"] == "0"
    j = motion.joints
    _check_real_clip(j, walking=name.startswith("walk"))
    travel = j[-1, 0, [0, 2]] - j[0, 0, [0, 2]]
    assert np.linalg.norm(travel) > 1.0 and travel[1] > 0.9 * np.linalg.norm(travel)  # forward = +Z


@pytest.mark.parametrize("turn", ["left", "right"])
@pytest.mark.parametrize("take", ["normal_001", "youthful_002", "exhausted_003"])
def test_bandai_turns_turn_the_right_way(turn: str, take: str, require_data):
    j = load_bvh(require_data(f"{BANDAI}/dataset-2_walk-turn-{turn}_{take}.bvh.gz")).joints
    _check_real_clip(j)
    theta = np.unwrap(M.heading_from_joints(j))
    sign = 1.0 if turn == "left" else -1.0  # θ grows turning left: facing +Z, left is +X
    assert sign * (theta[-1] - theta[0]) > np.deg2rad(45)
    assert sign * j[-1, 0, 0] > 0.5 and np.linalg.norm(j[-1, 0, [0, 2]]) > 1.0


def test_cmu_daz_walk_imports_and_walks(require_data):
    path = require_data(f"{CMU}/02_01.bvh.gz")
    motion = load_bvh(path)
    assert 3 <= int(motion.meta["dropped_frames"]) <= 12  # frame 0 T-pose plus the blend out of it
    assert motion.meta["units"] == "cm" and motion.meta["source_fps"] == "120"
    j = motion.joints
    _check_real_clip(j)
    travel = j[-1, 0, [0, 2]] - j[0, 0, [0, 2]]
    assert np.linalg.norm(travel) > 2.0 and travel[1] > 0.9 * np.linalg.norm(travel)
    # No T-pose left: the wrists hang below the shoulders from the first frame on.
    assert (j[:, [20, 21], 1] < j[:, [16, 17], 1] - 0.15).all()


@pytest.mark.slow
def test_every_shared_bvh_imports(shared_data):
    """A sample of every 25th file under shared/data (all of them with MOTION_ENV_ALL_BVH=1)."""
    files = sorted(shared_data.glob("**/*.bvh*"))
    if not files:
        pytest.skip(f"no BVH files under {shared_data}")
    if os.environ.get("MOTION_ENV_ALL_BVH") != "1":
        files = files[::25]
    failures, start = {}, time.perf_counter()
    for path in files:
        try:
            j = load_bvh(path).joints
            assert 0.3 < np.median(j[:, 0, 1]) < 1.5, f"pelvis height {np.median(j[:, 0, 1]):.2f} m"
        except (ValueError, AssertionError) as exc:
            failures[path.name] = str(exc)
    assert not failures, failures
    assert time.perf_counter() - start < 0.2 * len(files)  # about 20 ms a file
