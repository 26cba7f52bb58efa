"""Test-wide settings and fixtures, defined once for every test folder.

- torch runs single-threaded (tiny models run faster on one thread, and the 2-core CI machine
  stays responsive);
- real motion capture is read from one place: ``$MOTION_ENV_DATA`` when set, else
  ``../shared/data`` beside the checkout. Tests that need it ask for the :func:`shared_data`
  fixture (or :func:`require_data`) and skip, saying how to point them at the data, when absent;
- the robot models (MJCF) likewise: ``$MOTION_ENV_ROBOTS`` when set, else ``../shared/robots``;
  tests ask for :func:`require_robot` and skip when a robot is absent;
- a compiled loop is tested against the numpy operations it replaces with :func:`both_ways`.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MUJOCO_GL", "egl")
# Caption embeddings are cached on disk by the package; tests keep theirs out of the user's cache.
os.environ.setdefault("MOTION_ENV_CACHE", tempfile.mkdtemp(prefix="motion_env_test_cache_"))

DATA_ENV = "MOTION_ENV_DATA"
DATA_DIR = Path(os.environ.get(DATA_ENV) or Path(__file__).resolve().parents[2] / "shared" / "data")
HUMANML3D_CLIP = "012314"
ROBOTS_ENV = "MOTION_ENV_ROBOTS"
ROBOTS_DIR = Path(os.environ.get(ROBOTS_ENV) or Path(__file__).resolve().parents[2] / "shared" / "robots")


def missing_data(path: Path) -> str:
    """The skip reason for a test whose real data is not at `path`."""
    return f"real motion capture not found at {path}: set {DATA_ENV}=/path/to/shared/data to run this test"


@pytest.fixture(autouse=True, scope="session")
def _single_thread_torch() -> None:
    import torch

    torch.set_num_threads(1)


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The real-data folder (bandai/, cmu/, humanml3d_sample/); skips when it is absent."""
    if not DATA_DIR.is_dir():
        pytest.skip(missing_data(DATA_DIR))
    return DATA_DIR


@pytest.fixture(scope="session")
def require_data() -> Callable[[str], Path]:
    """``require_data("bandai/dataset-2")`` -> that path under the data folder, or skip the test."""

    def require(relative: str) -> Path:
        path = DATA_DIR / relative
        if not path.exists():
            pytest.skip(missing_data(path))
        return path

    return require


@pytest.fixture(scope="session")
def require_robot() -> Callable[[str], Path]:
    """``require_robot("unitree_g1")`` -> that robot's ``scene.xml`` under the robots folder, or
    skip the test."""

    def require(name: str) -> Path:
        path = ROBOTS_DIR / name / "scene.xml"
        if not path.is_file():
            pytest.skip(f"robot model not found at {path}: set {ROBOTS_ENV}=/path/to/shared/robots to run it")
        return path

    return require


LabelledTake = tuple[str, str, str, str, np.ndarray]
"""(name, split, action, style, joints (T + 1, 22, 3)) of a synthetic take."""


@pytest.fixture(scope="session")
def write_labelled_dataset() -> Callable[[Path, list[LabelledTake]], Path]:
    """``write_labelled_dataset(root, takes)`` -> `root` made a HumanML3D-layout dataset with
    ``index.csv`` (the layout ``motion-env data build`` writes) holding the synthetic Bandai `takes`.

    A take keeps T frames of its T + 1 joints (its features need the frame after) and the caption
    "a person does a <action>"; each split gets its ``<split>.txt``.
    """
    from motion_env.motion.features import joints_to_features

    def write(root: Path, takes: list[LabelledTake]) -> Path:
        for sub in ("new_joints", "new_joint_vecs", "texts"):
            (root / sub).mkdir(parents=True)
        rows = ["name,split,source,take,label,style,mirrored,frames,file"]
        splits: dict[str, list[str]] = {}
        for name, split, action, style, joints in takes:
            np.save(root / "new_joints" / f"{name}.npy", joints[:-1].astype(np.float32))
            np.save(root / "new_joint_vecs" / f"{name}.npy", joints_to_features(joints))
            (root / "texts" / f"{name}.txt").write_text(f"a person does a {action}\n")
            rows.append(f"{name},{split},bandai,{name},{action},{style},0,{len(joints) - 1},x.bvh")
            splits.setdefault(split, []).append(name)
        (root / "index.csv").write_text("\n".join(rows) + "\n")
        for split, names in splits.items():
            (root / f"{split}.txt").write_text("\n".join(names) + "\n")
        return root

    return write


@pytest.fixture(scope="session")
def _humanml3d_arrays(require_data: Callable[[str], Path]) -> tuple[np.ndarray, np.ndarray]:
    joints = require_data(f"humanml3d_sample/new_joints/{HUMANML3D_CLIP}.npy")
    features = require_data(f"humanml3d_sample/new_joint_vecs/{HUMANML3D_CLIP}.npy")
    return np.load(joints).astype(np.float32), np.load(features).astype(np.float32)


@pytest.fixture
def humanml3d_sample(_humanml3d_arrays: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The HumanML3D reference clip: (T, 22, 3) joints and (T-1, 263) features, float32 (fresh copies)."""
    joints, features = _humanml3d_arrays
    return joints.copy(), features.copy()


@pytest.fixture(scope="session")
def random_generator():
    """The untrained test generator (tiny random models, seed 0)."""
    from motion_env.generation.generator import MotionGenerator

    return MotionGenerator.random(seed=0)


@pytest.fixture(scope="session")
def pretrained_generator():
    """The shipped default model; skips when the weights are not installed."""
    from motion_env.generation.generator import MotionGenerator

    try:
        return MotionGenerator.from_pretrained()
    except FileNotFoundError as exc:
        pytest.skip(f"the shipped model is not installed: {exc}")


BUILT_DATASET = Path(__file__).resolve().parents[1] / "data" / "mocap"


@pytest.fixture(scope="session")
def built_dataset() -> Path:
    """The dataset built from the real mocap (``motion-env data build ... --out data/mocap``); skips
    when it is absent."""
    if not (BUILT_DATASET / "index.csv").is_file():
        pytest.skip(f"no built dataset at {BUILT_DATASET} (motion-env data build ... --out data/mocap)")
    return BUILT_DATASET


@pytest.fixture
def tiny_classifier():
    """An untrained action/style classifier of a few hundred weights (seed 0)."""
    import torch

    from motion_env.models.classifier import ClassifierConfig, MotionClassifier

    torch.manual_seed(0)
    config = ClassifierConfig(
        actions=("walk", "run", "wave-left-hand"),
        styles=("normal", "exhausted"),
        window=16,
        width=8,
        layers=2,
    )
    return MotionClassifier(config).eval()


@pytest.fixture
def both_ways(monkeypatch: pytest.MonkeyPatch) -> Callable[..., dict[bool, Any]]:
    """``both_ways(module, name, run, min_calls=1)``: what ``run()`` returns with numba's compiled
    loops on and off (``jit_cache``'s switch), as {True: ..., False: ...}; fails unless
    ``module.name``, the compiled loop under test, ran `min_calls` times when they were on."""
    from motion_env.models import jit_cache

    def run_both(
        module: ModuleType, name: str, run: Callable[[], Any], min_calls: int = 1
    ) -> dict[bool, Any]:
        calls = []
        compiled = getattr(module, name)
        monkeypatch.setattr(module, name, lambda *a: calls.append(1) or compiled(*a))
        outputs = {}
        for on in (True, False):
            monkeypatch.setattr(jit_cache, "_enabled", on)
            outputs[on] = run()
        monkeypatch.setattr(jit_cache, "_enabled", None)
        assert len(calls) >= min_calls, f"{module.__name__}.{name} ran {len(calls)} times"
        return outputs

    return run_both
