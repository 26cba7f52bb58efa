"""Reading HumanML3D-layout datasets (motion_env.data.dataset): splits, caption files, statistics.

Reading what ``motion-env data build`` writes is tested with the build, in test_build.py.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from motion_env.data.captions import caption_tokens
from motion_env.data.dataset import SPLITS, load_stats, read_captions, read_split, split_of, write_captions


def test_split_of_is_deterministic_and_proportional() -> None:
    # the hash gives about 85 / 7.5 / 7.5 over many takes, the same on every call
    many = [split_of(f"take_{i:05d}") for i in range(20000)]
    assert many == [split_of(f"take_{i:05d}") for i in range(20000)]
    shares = [many.count(s) / len(many) for s in SPLITS]
    assert shares == pytest.approx([0.85, 0.075, 0.075], abs=0.01)
    assert split_of("dataset-1_walk_normal_002") == split_of("dataset-1_walk_normal_002")


def test_caption_files_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "clip.txt"
    write_captions(path, ["a person walks forward", "  someone   waves # twice ", ""])
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines == [
        f"a person walks forward#{caption_tokens('a person walks forward')}#0.0#0.0",
        f"someone waves twice#{caption_tokens('someone waves twice')}#0.0#0.0",
    ]
    assert read_captions(path) == [("a person walks forward", 0.0, 0.0), ("someone waves twice", 0.0, 0.0)]
    path.write_text("a plain line\nbad times#x#a#b\n", encoding="utf-8")
    with pytest.raises(ValueError, match="bad start/end times"):
        read_captions(path)


def test_reads_a_genuine_humanml3d_directory(tmp_path: Path, require_data: Callable[[str], Path]) -> None:
    sample = require_data("humanml3d_sample")
    require_data("humanml3d_sample/new_joint_vecs/012314.npy")
    root = tmp_path / "HumanML3D"
    shutil.copytree(sample / "new_joint_vecs", root / "new_joint_vecs")
    shutil.copytree(sample / "new_joints", root / "new_joints")
    for name in ("Mean.npy", "Std.npy"):
        shutil.copy(sample / name, root / name)
    (root / "texts").mkdir()
    # HumanML3D's own text format, including a sub-clip annotation (seconds 1.0 to 3.5).
    (root / "texts" / "012314.txt").write_text(
        "a man kicks something or someone with his left leg.#a/DET man/NOUN kick/VERB something/PRON "
        "or/CCONJ someone/PRON with/ADP his/DET left/ADJ leg/NOUN#0.0#0.0\n"
        "a person steps forward.#a/DET person/NOUN step/VERB forward/ADV#1.0#3.5\n"
        "the person walks.#the/DET person/NOUN walk/VERB#nan#nan\n"
    )
    (root / "test.txt").write_text("012314\n")
    clips = read_split(root, "test")
    features = np.load(sample / "new_joint_vecs" / "012314.npy")
    assert [c.name for c in clips] == ["012314", "012314:1-3.5"]
    assert clips[0].captions == ["a man kicks something or someone with his left leg.", "the person walks."]
    np.testing.assert_array_equal(clips[0].features, features)
    assert clips[1].captions == ["a person steps forward."] and clips[1].num_frames == 50
    np.testing.assert_array_equal(clips[1].features, features[20:70])
    mean, std = load_stats(root)
    np.testing.assert_array_equal(mean, np.load(sample / "Mean.npy"))

    (root / "val.txt").write_text("012314\n000001\n")
    with pytest.raises(FileNotFoundError, match=r"000001\.npy.*000001\.txt"):
        read_split(root, "val")
    (root / "Std.npy").unlink()
    with pytest.raises(FileNotFoundError, match="Std.npy"):
        load_stats(root)
