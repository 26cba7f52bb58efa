"""Training datasets in the HumanML3D layout: the layout, and reading one back.

Layout (the same as HumanML3D's, so a genuine HumanML3D directory reads the same way)::

    root/
      new_joint_vecs/<name>.npy   (T, 263) float32 features (motion.joints_to_features)
      new_joints/<name>.npy       (T, 22, 3) float32 = motion.features_to_joints(features)
      texts/<name>.txt            one caption per line: caption#word/POS tokens#start#end
      train.txt val.txt test.txt  clip names, one per line (also all.txt, train_val.txt)
      Mean.npy Std.npy            (263,) normalisation statistics of the train split

Mirrored clips are named ``M<name>``. :func:`split_of` gives a take's split (a hash of its name,
the same on every machine), :func:`read_split` / :func:`load_stats` read a dataset back, and
:func:`read_captions` / :func:`write_captions` its caption files. :mod:`motion_env.data.build`
builds one from BVH folders (``motion-env data build``).
"""

from __future__ import annotations

import csv
import hashlib
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion_env.data.captions import caption_tokens
from motion_env.motion.skeleton import (
    FEATURE_DIM,
    FOOT_CONTACT,
    FPS,
    LOCAL_VEL,
    NUM_JOINTS,
    RIC,
    ROOT_LIN_VEL,
    ROOT_ROT_VEL,
    ROOT_Y,
    ROT6D,
)

SPLITS: tuple[str, ...] = ("train", "val", "test")
SPLIT_FRACTIONS: tuple[float, float, float] = (0.85, 0.075, 0.075)
# Feature groups whose standard deviations HumanML3D's cal_mean_variance averages.
STD_GROUPS: tuple[slice, ...] = (ROOT_ROT_VEL, ROOT_LIN_VEL, ROOT_Y, RIC, ROT6D, LOCAL_VEL, FOOT_CONTACT)
CMU_INDEX_NAME = "CMU-INDEX.md"
MIRROR_PREFIX = "M"


@dataclass
class DatasetClip:
    """One clip of a HumanML3D-layout dataset.

    Attributes:
        name: the file stem (``M`` prefix for a mirrored clip); a HumanML3D sub-clip (a caption
            with start/end times) is named ``<name>:<start>-<end>``.
        features: (T, 263) float32 HumanML3D features.
        joints: (T, 22, 3) float32 joint positions (``new_joints``; for a sub-clip the matching
            slice of the whole clip's joints, so still placed where the whole clip puts it).
        captions: the captions that describe this clip (or sub-clip).
    """

    name: str
    features: np.ndarray
    joints: np.ndarray
    captions: list[str]

    @property
    def num_frames(self) -> int:
        return int(self.features.shape[0])


# --------------------------------------------------------------------------------------------
# Splits and caption files.
# --------------------------------------------------------------------------------------------


def split_of(take: str, fractions: Sequence[float] = SPLIT_FRACTIONS) -> str:
    """The split of a take, from a hash of its name: the same on every machine and every run.

    A mirrored clip's name (``M<take>``) must be reduced to its take before calling this; the
    build does so, which keeps a take and its mirror in the same split.
    """
    digest = hashlib.sha1(take.encode("utf-8")).digest()
    u = int.from_bytes(digest[:8], "big") / 2.0**64
    edges = np.cumsum(fractions) / float(np.sum(fractions))
    return SPLITS[int(np.searchsorted(edges, u, side="right"))]


def write_captions(path: Path, captions: Iterable[str]) -> None:
    """Write HumanML3D caption lines ``caption#tokens#0.0#0.0`` (whole-clip captions)."""
    lines = []
    for caption in captions:
        caption = " ".join(caption.replace("#", " ").split())
        if caption:
            lines.append(f"{caption}#{caption_tokens(caption)}#0.0#0.0")
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_captions(path: Path) -> list[tuple[str, float, float]]:
    """Read a HumanML3D caption file: ``[(caption, start_s, end_s), ...]``.

    ``start = end = 0`` (or NaN) means the whole clip, as in HumanML3D. A line without ``#``
    fields is a whole-clip caption.
    """
    out = []
    for line in path.read_text(encoding="utf-8").splitlines():
        fields = line.strip().split("#")
        caption = fields[0].strip()
        if not caption:
            continue
        start = end = 0.0
        if len(fields) >= 4:
            try:
                start, end = float(fields[2]), float(fields[3])
            except ValueError as exc:
                raise ValueError(f"{path}: bad start/end times in line {line!r}") from exc
            start = 0.0 if np.isnan(start) else start
            end = 0.0 if np.isnan(end) else end
        out.append((caption, start, end))
    return out


# --------------------------------------------------------------------------------------------
# Whole splits and normalisation statistics.
# --------------------------------------------------------------------------------------------


def _missing_error(root: Path, missing: list[Path], what: str) -> FileNotFoundError:
    listed = ", ".join(str(p.relative_to(root)) for p in missing[:10])
    more = f" and {len(missing) - 10} more" if len(missing) > 10 else ""
    return FileNotFoundError(f"{root}: {len(missing)} {what} missing: {listed}{more}")


def read_split(root: str | Path, split: str) -> list[DatasetClip]:
    """Read one split of a HumanML3D-layout directory (built here, or HumanML3D itself).

    Captions with start/end times (HumanML3D's sub-clip annotations) become clips of their own,
    ``features[int(start * 20):int(end * 20)]``, named ``<name>:<start>-<end>``; a clip with only
    such captions is not returned whole (both as HumanML3D's loader does; unlike it, no length
    filter is applied: the training code crops). Caption token fields are ignored.

    Args:
        root: the dataset directory.
        split: ``"train"``, ``"val"``, ``"test"`` (or any ``<split>.txt`` there, e.g. ``"all"``).
    Returns:
        the clips in the order of the split file.
    Raises:
        FileNotFoundError: the split file, or some clip's features, joints or texts (all missing
            files are named).
        ValueError: a clip whose arrays have the wrong shapes.
    """
    root = Path(root).expanduser()
    split_file = root / f"{split}.txt"
    if not split_file.is_file():
        present = sorted(p.stem for p in root.glob("*.txt")) if root.is_dir() else []
        raise FileNotFoundError(
            f"{split_file} not found" + (f" (split files there: {', '.join(present)})" if present else "")
        )
    names = [line.strip() for line in split_file.read_text(encoding="utf-8").splitlines() if line.strip()]
    missing = [
        p
        for n in names
        for p in (
            root / "new_joint_vecs" / f"{n}.npy",
            root / "new_joints" / f"{n}.npy",
            root / "texts" / f"{n}.txt",
        )
        if not p.is_file()
    ]
    if missing:
        raise _missing_error(root, missing, f"file(s) listed by {split_file.name} are")
    clips = []
    for name in names:
        features = np.load(root / "new_joint_vecs" / f"{name}.npy").astype(np.float32, copy=False)
        joints = np.load(root / "new_joints" / f"{name}.npy").astype(np.float32, copy=False)
        if features.ndim != 2 or features.shape[1] != FEATURE_DIM:
            raise ValueError(
                f"{root / 'new_joint_vecs' / name}.npy: shape {features.shape}, expected (T, 263)"
            )
        if joints.shape != (features.shape[0], NUM_JOINTS, 3):
            raise ValueError(
                f"{root / 'new_joints' / name}.npy: shape {joints.shape}, expected "
                f"({features.shape[0]}, {NUM_JOINTS}, 3) to match its features"
            )
        whole: list[str] = []
        parts: dict[tuple[float, float], list[str]] = defaultdict(list)
        for caption, start, end in read_captions(root / "texts" / f"{name}.txt"):
            if start == 0.0 and end == 0.0:
                whole.append(caption)
            else:
                parts[(start, end)].append(caption)
        if whole:
            clips.append(DatasetClip(name, features, joints, whole))
        for (start, end), captions in parts.items():
            a, b = int(start * FPS), int(end * FPS)
            if b - a >= 1 and a < features.shape[0]:
                clips.append(DatasetClip(f"{name}:{start:g}-{end:g}", features[a:b], joints[a:b], captions))
    return clips


def load_stats(root: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(mean (263,), std (263,))`` float32 from ``Mean.npy`` / ``Std.npy`` of a dataset directory."""
    root = Path(root).expanduser()
    paths = [root / "Mean.npy", root / "Std.npy"]
    missing = [p for p in paths if not p.is_file()]
    if missing:
        raise _missing_error(root, missing, "normalisation file(s) are")
    mean, std = (np.load(p).astype(np.float32) for p in paths)
    for p, a in zip(paths, (mean, std), strict=True):
        if a.shape != (FEATURE_DIM,):
            raise ValueError(f"{p}: shape {a.shape}, expected ({FEATURE_DIM},)")
    if not (std > 0).all():
        raise ValueError(f"{paths[1]}: {int((std <= 0).sum())} non-positive standard deviations")
    return mean, std


def read_index(root: str | Path) -> dict[str, dict[str, str]]:
    """Take name -> its row of ``index.csv`` (split, source, take, label, style, mirrored, frames,
    file: what ``motion-env data build`` writes); empty for a dataset without one (a HumanML3D
    folder)."""
    path = Path(root).expanduser() / "index.csv"
    if not path.is_file():
        return {}
    with path.open(newline="", encoding="utf-8") as f:
        return {row["name"]: row for row in csv.DictReader(f)}
