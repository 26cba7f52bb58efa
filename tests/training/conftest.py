"""Fixtures of the trainer tests: a tiny HumanML3D-layout dataset cut from the real sample clip,
and a deterministic stand-in text encoder."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.text.encoders import TextEncoder

# (first, last) frames of the sample clip cut into five clips; the last one is the val split.
CUTS = [(0, 80), (40, 130), (90, 170), (10, 100), (60, 170)]


class HashText(TextEncoder):
    """A deterministic stand-in for MiniLM: a fixed random 8-d vector per caption length."""

    name, dim = "hash", 8

    def _embed(self, texts: list[str]) -> torch.Tensor:
        return torch.stack(
            [torch.randn(8, generator=torch.Generator().manual_seed(len(t) * 7919)) for t in texts]
        )


@pytest.fixture(scope="session")
def hash_text() -> Callable[..., TextEncoder]:
    """``hash_text()`` -> a :class:`HashText`; ``hash_text("other")`` -> the same under another name."""

    def make(name: str = "hash") -> TextEncoder:
        encoder = HashText()
        encoder.name = name
        return encoder

    return make


@pytest.fixture
def tiny_dataset(
    tmp_path_factory: pytest.TempPathFactory,
    humanml3d_sample: tuple[np.ndarray, np.ndarray],
    require_data: Callable[[str], Path],
) -> Path:
    """Five overlapping cuts of the HumanML3D sample clip (four train, one val) with captions and
    the sample's Mean/Std; skips when the real data is absent."""
    joints, feats = humanml3d_sample
    root = tmp_path_factory.mktemp("tiny_dataset")
    for d in ("new_joint_vecs", "new_joints", "texts"):
        (root / d).mkdir()
    names: dict[str, list[str]] = {"train": [], "val": []}
    for i, (a, b) in enumerate(CUTS):
        name = f"clip{i}"
        np.save(root / "new_joint_vecs" / f"{name}.npy", feats[a:b])
        np.save(root / "new_joints" / f"{name}.npy", joints[a:b])
        captions = ["a person walks", "someone moves forward"] if i % 2 else ["a person turns around"]
        (root / "texts" / f"{name}.txt").write_text("".join(f"{c}#x/NOUN#0.0#0.0\n" for c in captions))
        names["val" if i == len(CUTS) - 1 else "train"].append(name)
    for split, ns in names.items():
        (root / f"{split}.txt").write_text("\n".join(ns) + "\n")
    for stats in ("Mean.npy", "Std.npy"):
        shutil.copy(require_data(f"humanml3d_sample/{stats}"), root / stats)
    return root
