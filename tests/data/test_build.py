"""`motion-env data build` (motion_env.data.build) on synthetic BVH files and on real motion capture."""

from __future__ import annotations

import gzip
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env import motion as mmath
from motion_env.cli import main
from motion_env.data.build import build_dataset
from motion_env.data.captions import caption_tokens
from motion_env.data.dataset import (
    MIRROR_PREFIX,
    SPLITS,
    STD_GROUPS,
    load_stats,
    read_captions,
    read_split,
    split_of,
)
from motion_env.motion.skeleton import FEATURE_DIM, NUM_JOINTS
from motion_env.text.mirror import mirror_caption

# A MotionBuilder-named skeleton in centimetres, Y up, facing +Z (left = +X):
# (name, parent, offset); End Sites are added to the leaves.
_SKELETON = [
    ("Hips", None, (0, 0, 0)),
    ("Spine", "Hips", (0, 10, 0)),
    ("Spine1", "Spine", (0, 14, 0)),
    ("Neck", "Spine1", (0, 24, 0)),
    ("Head", "Neck", (0, 10, 0)),
    ("LeftShoulder", "Spine1", (3, 20, 0)),
    ("LeftArm", "LeftShoulder", (14, 0, 0)),
    ("LeftForeArm", "LeftArm", (27, 0, 0)),
    ("LeftHand", "LeftForeArm", (25, 0, 0)),
    ("RightShoulder", "Spine1", (-3, 20, 0)),
    ("RightArm", "RightShoulder", (-14, 0, 0)),
    ("RightForeArm", "RightArm", (-27, 0, 0)),
    ("RightHand", "RightForeArm", (-25, 0, 0)),
    ("LeftUpLeg", "Hips", (9, -5, 0)),
    ("LeftLeg", "LeftUpLeg", (0, -42, 0)),
    ("LeftFoot", "LeftLeg", (0, -42, 0)),
    ("LeftToeBase", "LeftFoot", (0, -7, 12)),
    ("RightUpLeg", "Hips", (-9, -5, 0)),
    ("RightLeg", "RightUpLeg", (0, -42, 0)),
    ("RightFoot", "RightLeg", (0, -42, 0)),
    ("RightToeBase", "RightFoot", (0, -7, 12)),
]


def write_bvh(path: Path, seconds: float, turn_deg: float = 0.0, fps: int = 30, phase: float = 0.0) -> Path:
    """A small walking-like BVH: the root moves along +Z while turning ``turn_deg`` in total,
    legs and arms swing. Gzip-compressed when ``path`` ends with ``.gz``."""
    children: dict[str | None, list[int]] = {}
    for i, (_, parent, _) in enumerate(_SKELETON):
        children.setdefault(parent, []).append(i)
    lines = ["HIERARCHY"]

    def emit(i: int, depth: int) -> None:
        name, parent, offset = _SKELETON[i]
        pad = "  " * depth
        lines.append(f"{pad}{'ROOT' if parent is None else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {offset[0]:.2f} {offset[1]:.2f} {offset[2]:.2f}")
        pos = "Xposition Yposition Zposition " if parent is None else ""
        lines.append(f"{pad}  CHANNELS {6 if parent is None else 3} {pos}Zrotation Xrotation Yrotation")
        for c in children.get(name, []):
            emit(c, depth + 1)
        if name not in children:
            lines.extend([f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET 0.00 5.00 0.00", pad + "  }"])
        lines.append(pad + "}")

    emit(0, 0)
    n = max(int(round(seconds * fps)), 1)
    lines += ["MOTION", f"Frames: {n}", f"Frame Time: {1.0 / fps:.6f}"]
    index = {name: i for i, (name, _, _) in enumerate(_SKELETON)}
    for f in range(n):
        t = f / fps
        swing = 25.0 * np.sin(2 * np.pi * 1.0 * t + phase)
        yaw = turn_deg * f / max(n - 1, 1)
        heading = np.radians(yaw)
        rot = np.zeros((len(_SKELETON), 3))  # (Z, X, Y) degrees per joint
        rot[0, 2] = yaw
        rot[index["LeftUpLeg"], 1] = swing
        rot[index["RightUpLeg"], 1] = -swing
        rot[index["LeftLeg"], 1] = max(0.0, -swing)
        rot[index["RightLeg"], 1] = max(0.0, swing)
        rot[index["LeftArm"], 0] = -70.0
        rot[index["RightArm"], 0] = 70.0
        rot[index["LeftArm"], 1] = -0.6 * swing
        rot[index["RightArm"], 1] = 0.6 * swing
        dist = 110.0 * t  # cm
        root = [dist * np.sin(heading) * 0.5, 95.0 + 2.0 * np.cos(4 * np.pi * t), dist * np.cos(heading)]
        values = root + [v for r in rot for v in r]
        lines.append(" ".join(f"{v:.4f}" for v in values))
    text = "\n".join(lines) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.name.endswith(".gz"):
        with gzip.open(path, "wt") as f:
            f.write(text)
    else:
        path.write_text(text)
    return path


@pytest.fixture(scope="module")
def synthetic_sources(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Bandai-named, CMU-named and generic files, one too short, one broken, one with captions."""
    root = tmp_path_factory.mktemp("sources")
    for take in range(1, 7):
        write_bvh(
            root / "bandai" / f"dataset-2_walk-turn-left_exhausted_{take:03d}.bvh.gz", 2.5, 90.0, phase=take
        )
    write_bvh(root / "bandai" / "dataset-2_walk_happy_001.bvh", 2.0, phase=0.3)
    write_bvh(root / "bandai" / "dataset-2_run_sad_001.bvh", 0.5)  # shorter than 1 s: skipped
    (root / "bandai" / "dataset-2_run_sad_002.bvh").write_text("HIERARCHY\nROOT Hips\n{\n")  # broken
    write_bvh(root / "cmu" / "bvh" / "02_01.bvh", 2.0, phase=1.0)
    (root / "cmu" / "CMU-INDEX.md").write_text("Subject #2\n\n02_01  walk\n\n02_02  walk\n")
    write_bvh(root / "mine" / "session1" / "turn_left_slowly.bvh", 2.0, 45.0)
    write_bvh(root / "mine" / "session1" / "my_move.bvh", 1.5, phase=2.0)
    (root / "mine" / "session1" / "my_move.txt").write_text(
        "a person does my special move\n\nsomeone moves\n"
    )
    return root


@pytest.fixture(scope="module")
def built(synthetic_sources: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    out = tmp_path_factory.mktemp("built") / "mocap"
    sources = [synthetic_sources / "bandai", synthetic_sources / "cmu", synthetic_sources / "mine"]
    summary = build_dataset(sources, out, workers=2, captions_per_clip=5, progress=False)
    return out, summary


def test_build_writes_humanml3d_layout(built: tuple[Path, object]) -> None:
    out, summary = built
    for name in "new_joints new_joint_vecs texts train.txt val.txt test.txt Mean.npy Std.npy".split():
        assert (out / name).exists(), name
    assert summary.takes == 10 and summary.clips == 20
    assert len(summary.skipped) == 1 and "dataset-2_run_sad_001" in summary.skipped[0]
    assert len(summary.failed) == 1 and summary.failed[0][0].endswith("dataset-2_run_sad_002.bvh")
    assert summary.failed[0][1]  # a reason is given
    assert summary.per_source["bandai"]["clips"] == 14 and summary.per_source["cmu"]["clips"] == 2
    assert summary.per_source["other"]["clips"] == 4
    assert summary.per_label["bandai"]["walk-turn-left"]["clips"] == 6
    assert summary.per_label["bandai"]["walk-turn-right"]["clips"] == 6  # the mirrors
    assert summary.hours == pytest.approx(summary.frames / 20 / 3600)
    assert sum(summary.splits.values()) == 20
    text = summary.format()
    assert "20 clips" in text and "bandai: walk-turn-left" in text and "dataset-2_run_sad_002" in text

    names = [n for s in SPLITS for n in (out / f"{s}.txt").read_text().split()]
    assert len(names) == len(set(names)) == 20
    for name in names:
        features = np.load(out / "new_joint_vecs" / f"{name}.npy")
        joints = np.load(out / "new_joints" / f"{name}.npy")
        assert features.dtype == np.float32 and features.shape[1] == FEATURE_DIM
        assert joints.shape == (features.shape[0], NUM_JOINTS, 3)
        np.testing.assert_allclose(joints, mmath.features_to_joints(features), atol=1e-5)
        lines = (out / "texts" / f"{name}.txt").read_text().splitlines()
        assert len(lines) >= 2
        for line in lines:
            caption, tokens, start, end = line.split("#")
            assert tokens == caption_tokens(caption) and (start, end) == ("0.0", "0.0")


def test_mirrors_swap_left_and_right(built: tuple[Path, object]) -> None:
    out, _ = built
    name = "dataset-2_walk-turn-left_exhausted_001"
    captions = [c for c, _, _ in read_captions(out / "texts" / f"{name}.txt")]
    mirrored = [c for c, _, _ in read_captions(out / "texts" / f"{MIRROR_PREFIX}{name}.txt")]
    assert mirrored == [mirror_caption(c) for c in captions]
    assert all("left" in c for c in captions) and all("right" in c and "left" not in c for c in mirrored)
    turn = []
    for n in (name, MIRROR_PREFIX + name):
        heading = np.unwrap(mmath.heading_from_joints(np.load(out / "new_joints" / f"{n}.npy")))
        turn.append(np.degrees(heading[-1] - heading[0]))
    assert turn[0] > 45 and turn[1] < -45  # the take turns left, its mirror right
    sidecar = [c for c, _, _ in read_captions(out / "texts" / "session1_my_move.txt")]
    assert sidecar == ["a person does my special move", "someone moves"]


def test_splits_are_by_take_and_deterministic(built: tuple[Path, object]) -> None:
    out, _ = built
    split_names = {s: set((out / f"{s}.txt").read_text().split()) for s in SPLITS}
    takes = {s: {n.removeprefix(MIRROR_PREFIX) if n.startswith(MIRROR_PREFIX) else n for n in names}
             for s, names in split_names.items()}  # fmt: skip
    for a in SPLITS:
        for b in SPLITS:
            if a != b:
                assert not takes[a] & takes[b], (a, b)
        for name in split_names[a]:
            partner = name[1:] if name.startswith(MIRROR_PREFIX) else MIRROR_PREFIX + name
            assert partner in split_names[a], name  # a take and its mirror share a split
            assert split_of(partner.removeprefix(MIRROR_PREFIX) if partner.startswith("M") else partner) == a


def test_stats_follow_humanml3d(built: tuple[Path, object]) -> None:
    out, _ = built
    mean, std = load_stats(out)
    assert mean.shape == std.shape == (FEATURE_DIM,) and (std > 0).all()
    train = read_split(out, "train")
    assert train, "the synthetic takes should put some clips in train"
    frames = np.concatenate([c.features for c in train]).astype(np.float64)
    np.testing.assert_allclose(mean, frames.mean(axis=0), atol=1e-5)
    raw_std = frames.std(axis=0)
    for group in STD_GROUPS:
        assert np.allclose(std[group], std[group][0])  # one value per feature group
        expected = raw_std[group].mean()
        assert std[group][0] == pytest.approx(expected if expected > 1e-12 else 1.0, rel=1e-4)


def test_read_back_every_split(built: tuple[Path, object]) -> None:
    out, _ = built
    clips = [c for s in SPLITS for c in read_split(out, s)]
    assert len(clips) == 20
    for c in clips:
        assert c.features.shape == (c.num_frames, FEATURE_DIM)
        assert c.joints.shape == (c.num_frames, NUM_JOINTS, 3)
        assert c.captions and all(isinstance(t, str) and t for t in c.captions)
    with pytest.raises(FileNotFoundError, match="nosuch.txt"):
        read_split(out, "nosuch")


def test_refuses_to_write_into_a_non_empty_directory(synthetic_sources: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "mine"
    out.mkdir()
    keep = out / "precious.txt"
    keep.write_text("do not touch")
    with pytest.raises(FileExistsError, match="not empty"):
        build_dataset([synthetic_sources / "cmu"], out, workers=1, progress=False)
    assert keep.read_text() == "do not touch" and sorted(p.name for p in out.iterdir()) == ["precious.txt"]
    assert main(["data", "build", str(synthetic_sources / "cmu"), "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert not list(tmp_path.glob(".mine.partial-*"))  # no temporary folder left behind
    with pytest.raises(FileNotFoundError, match="does not exist"):
        build_dataset([tmp_path / "absent"], tmp_path / "new", workers=1, progress=False)


def test_cli_builds_into_an_empty_directory_and_prints_the_summary(
    synthetic_sources: Path, tmp_path: Path, capsys
) -> None:
    out = tmp_path / "empty"
    out.mkdir()
    source = str(synthetic_sources / "cmu")
    assert main(["data", "build", source, "--out", str(out), "--workers", "1", "--no-mirror"]) == 0
    printed = capsys.readouterr().out
    assert "1 clips (1 takes)" in printed and "cmu: walk" in printed
    assert sorted((out / "texts").iterdir()) == [out / "texts" / "cmu_02_01.txt"]
    assert all("walk" in c for c, _, _ in read_captions(out / "texts" / "cmu_02_01.txt"))


def test_real_bandai_and_cmu_files(tmp_path: Path, require_data: Callable[[str], Path]) -> None:
    names = ["dataset-2_walk-turn-left_normal_001", "dataset-2_wave-right-hand_exhausted_001"]
    src = tmp_path / "src"
    (src / "bandai").mkdir(parents=True)
    for n in names:
        (src / "bandai" / f"{n}.bvh.gz").symlink_to(require_data(f"bandai/dataset-2/bvh/{n}.bvh.gz"))
    (src / "cmu").mkdir()
    (src / "cmu" / "02_01.bvh.gz").symlink_to(require_data("cmu/bvh/02_01.bvh.gz"))
    (src / "cmu" / "CMU-INDEX.md").symlink_to(require_data("cmu/CMU-INDEX.md"))
    summary = build_dataset([src], tmp_path / "out", workers=1, progress=False)
    assert summary.takes == 3 and summary.clips == 6 and not summary.failed and not summary.skipped
    assert summary.per_label["bandai"]["wave-left-hand"]["clips"] == 1  # the mirror of the right-hand wave
    assert summary.per_label["cmu"]["walk"]["clips"] == 2
    clips = {c.name: c for s in SPLITS for c in read_split(tmp_path / "out", s)}
    wave, wave_m = clips[names[1]], clips[MIRROR_PREFIX + names[1]]
    assert all("right" in c for c in wave.captions) and all("left" in c for c in wave_m.captions)
    # the waving hand is the one the caption names, in the take and in its mirror
    right_up = (wave.joints[:, 21, 1] - wave.joints[:, 20, 1]).max()
    left_up = (wave_m.joints[:, 20, 1] - wave_m.joints[:, 21, 1]).max()
    assert right_up > 0.5 and left_up > 0.5
    turn = clips[names[0]]
    heading = np.unwrap(mmath.heading_from_joints(turn.joints))
    assert np.degrees(heading[-1] - heading[0]) > 60  # walk-turn-left turns left (+θ)
    assert any("walk" in c for c in clips["cmu_02_01"].captions)


# --- scripts/pack_takes.py and scripts/train_vqvae_runs.py: a built dataset sent to a lent GPU ---

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def _script(name: str, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPTS / name), *args], capture_output=True, text=True, timeout=300, check=check
    )


@pytest.fixture(scope="module")
def unpacked(built: tuple[Path, object], tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    built_dir, folder = built[0], tmp_path_factory.mktemp("pack")
    pack = folder / "takes.npz"
    _script(
        "pack_takes.py",
        "pack",
        "--data",
        str(built_dir),
        "--splits",
        "train,val,test",
        "--out",
        str(pack),
        "--workers",
        "1",
    )
    _script("pack_takes.py", "unpack", str(pack), "--out", str(folder / "mocap"), "--workers", "1")
    return pack, folder / "mocap"


def test_a_pack_unpacks_into_the_dataset_it_was_made_from(
    built: tuple[Path, object], unpacked: tuple[Path, Path]
) -> None:
    built, (_, out) = built[0], unpacked
    _, std = load_stats(built)
    for split in ("train", "val", "test"):
        assert (out / f"{split}.txt").read_text().split() == (built / f"{split}.txt").read_text().split()
        for a, b in zip(read_split(out, split), read_split(built, split), strict=True):
            assert a.name == b.name and a.captions == b.captions
            assert a.features.shape == b.features.shape
            assert np.abs((a.features - b.features) / std).max() < 1e-2, a.name
    for name in ("Mean.npy", "Std.npy"):
        np.testing.assert_array_equal(np.load(out / name), np.load(built / name))


def test_check_compares_and_unpack_never_overwrites(
    built: tuple[Path, object], unpacked: tuple[Path, Path]
) -> None:
    built, (pack, out) = built[0], unpacked
    assert "largest difference" in _script("pack_takes.py", "check", str(pack), "--data", str(built)).stdout
    again = _script("pack_takes.py", "unpack", str(pack), "--out", str(out), check=False)
    assert again.returncode != 0 and "not empty" in again.stderr
    exists = _script("pack_takes.py", "pack", "--data", str(built), "--out", str(pack), check=False)
    assert exists.returncode != 0 and "exists" in exists.stderr


def test_side_by_side_runs_are_exported_as_they_would_ship(
    unpacked: tuple[Path, Path], tmp_path: Path
) -> None:
    pack, _ = unpacked  # the pack itself: unpacked by the script into a folder of its own
    tiny = {"width": 16, "code_dim": 8, "codebook_size": 16, "batch_size": 2, "window": 8, "read_weight": 1.0}
    runs = [f"a={json.dumps(tiny)}", f"b={json.dumps({**tiny, 'lr': 1e-3})}"]
    args = [
        "--pack",
        str(pack),
        "--device",
        "cpu",
        "--budget",
        "0.2",
        "--work",
        str(tmp_path / "work"),
    ]
    _script(
        "train_vqvae_runs.py", *args, "--out", str(tmp_path / "out"), *[x for r in runs for x in ("--run", r)]
    )
    record = json.loads((tmp_path / "out" / "runs.json").read_text())
    for name in ("a", "b"):
        assert (
            record["runs"][name]["final"]["step"] == 40  # the budget is spent: the probe's steps
            and "val_mpjpe_local_cm" in record["runs"][name]["final"]
            and record["runs"][name]["probe_seconds_per_step"] > 0
        )
        ckpt = torch.load(tmp_path / "out" / f"{name}.pt", weights_only=True)
        assert "optimizer" not in ckpt and ckpt["config"]["width"] == 16
        assert all(t.dtype == torch.float16 for t in ckpt["model"].values() if t.is_floating_point())
    bad = _script(
        "train_vqvae_runs.py", *args, "--out", str(tmp_path / "bad"), "--run", 'a={"widht": 8}', check=False
    )
    assert bad.returncode != 0 and "widht" in bad.stderr
