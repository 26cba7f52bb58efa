"""Training datasets in the HumanML3D layout: build one from BVH folders, read one back.

Layout (the same as HumanML3D's, so a genuine HumanML3D directory reads the same way)::

    root/
      new_joint_vecs/<name>.npy   (T, 263) float32 features (motion.joints_to_features)
      new_joints/<name>.npy       (T, 22, 3) float32 = motion.features_to_joints(features)
      texts/<name>.txt            one caption per line: caption#word/POS tokens#start#end
      train.txt val.txt test.txt  clip names, one per line (also all.txt, train_val.txt)
      Mean.npy Std.npy            (263,) normalisation statistics of the train split

:func:`build_dataset` also writes ``index.csv`` (name, split, source, take, label, style,
mirrored, frames, file) and ``summary.json``; HumanML3D readers ignore both.

Build details:

- Every ``.bvh`` / ``.bvh.gz`` under the source folders is imported with
  :func:`motion_env.bvh.load_bvh` (20 fps, canonical skeleton). Captions come from the file
  name (:mod:`motion_env.captions`: Bandai ``dataset-N_{content}_{style}_{take}``, CMU trial ids
  looked up in a ``CMU-INDEX.md`` found in the file's folder or above it up to the source's
  parent, else the file-name words); a ``<stem>.txt`` next to a BVH file, one caption per line,
  replaces them.
- Each take is also stored mirrored (``M<name>``, left and right swapped in the motion and in
  the captions), like HumanML3D.
- Splits are by take: a hash of the clip name decides train / val / test (85 / 7.5 / 7.5 %), the
  same on every machine, and a mirror always goes where its take goes.
- Mean / Std: over the frames of the train split (mirrors included); the standard deviation is
  then averaged within each feature group (root rotation velocity, root linear velocity, root
  height, joint positions, 6-D rotations, joint velocities, foot contacts) as in HumanML3D's
  ``cal_mean_variance``. One difference: HumanML3D computed them over all of its clips, this
  build over the train split only, so that validation and test stay unseen.
- Takes shorter than ``min_seconds`` are skipped and files that fail to import are listed with
  the reason; neither stops the build. The output directory must be empty or absent: the build
  writes into a temporary sibling folder (``.<out>.partial-<pid>``) and renames it at the end;
  an error or Ctrl-C removes it, so nothing half-written is left behind.
"""

from __future__ import annotations

import csv
import hashlib
import json
import multiprocessing
import os
import shutil
import time
import traceback
from collections import defaultdict
from collections.abc import Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from motion_env.data.captions import (
    DEFAULT_NUM_CAPTIONS,
    ClipLabels,
    caption_tokens,
    captions_for,
    file_stem,
    labels_for_file,
    parse_cmu_index,
)
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
from motion_env.text.mirror import mirror_caption

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


@dataclass
class BuildSummary:
    """What :func:`build_dataset` wrote (printed by ``motion-env data build``).

    ``clips`` and ``frames`` count the written clips, mirrors included; ``takes`` the imported
    takes. ``per_source[source]`` and ``per_label[source][label]`` hold ``{"clips", "frames"}``
    (a mirrored clip counts under its mirrored label, e.g. walk-turn-right).
    """

    out: str
    takes: int = 0
    clips: int = 0
    frames: int = 0
    splits: dict[str, int] = field(default_factory=dict)
    per_source: dict[str, dict[str, int]] = field(default_factory=dict)
    per_label: dict[str, dict[str, dict[str, int]]] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    min_seconds: float = 1.0

    @property
    def hours(self) -> float:
        return self.frames / FPS / 3600.0

    def to_dict(self) -> dict:
        return {**asdict(self), "hours": self.hours}

    def format(self, max_listed: int = 10) -> str:
        """A human-readable report: totals, splits, per source, per label, skipped, failed."""

        def hours(frames: int) -> str:
            return f"{frames / FPS / 3600.0:.2f}"

        minutes, secs = divmod(int(round(self.seconds)), 60)
        lines = [
            f"Built {self.out} in {minutes}m{secs:02d}s",
            f"  {self.clips:,} clips ({self.takes:,} takes"
            + (" + mirrors" if self.clips > self.takes else "")
            + f"), {self.hours:.2f} h at {FPS} fps",
            "  splits: " + ", ".join(f"{s} {self.splits.get(s, 0):,}" for s in SPLITS),
            "",
            f"  {'source':<28}{'clips':>8}{'hours':>8}",
        ]
        for source, c in sorted(self.per_source.items()):
            lines.append(f"  {source:<28}{c['clips']:>8,}{hours(c['frames']):>8}")
        lines += ["", f"  {'label (content)':<28}{'clips':>8}{'hours':>8}"]
        for source, labels in sorted(self.per_label.items()):
            for label, c in sorted(labels.items(), key=lambda kv: (-kv[1]["frames"], kv[0])):
                lines.append(f"  {source + ': ' + label:<28.28}{c['clips']:>8,}{hours(c['frames']):>8}")
        lines.append("")
        lines.append(f"  skipped (shorter than {self.min_seconds:g} s): {len(self.skipped)}")
        for name in self.skipped[:max_listed]:
            lines.append(f"    {name}")
        if len(self.skipped) > max_listed:
            lines.append(f"    ... and {len(self.skipped) - max_listed} more (see summary.json)")
        lines.append(f"  failed to import: {len(self.failed)}")
        for name, reason in self.failed[:max_listed]:
            lines.append(f"    {name}: {reason}")
        if len(self.failed) > max_listed:
            lines.append(f"    ... and {len(self.failed) - max_listed} more (see summary.json)")
        for warning in self.warnings:
            lines.append(f"  warning: {warning}")
        return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# Splits, captions files, statistics.
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


class _RunningStats:
    """Frame count, mean and sum of squared deviations, merged clip by clip (Chan et al.)."""

    def __init__(self) -> None:
        self.n = 0
        self.mean = np.zeros(FEATURE_DIM)
        self.m2 = np.zeros(FEATURE_DIM)

    def add(self, n: int, mean: np.ndarray, m2: np.ndarray) -> None:
        if n == 0:
            return
        total = self.n + n
        delta = mean - self.mean
        self.mean = self.mean + delta * (n / total)
        self.m2 = self.m2 + m2 + delta**2 * (self.n * n / total)
        self.n = total


def _clip_stats(features: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    f = features.astype(np.float64)
    mean = f.mean(axis=0)
    return f.shape[0], mean, ((f - mean) ** 2).sum(axis=0)


def grouped_std(std: np.ndarray) -> np.ndarray:
    """HumanML3D's std post-processing: each feature group gets its mean standard deviation.

    std: (263,). A group whose features never vary (std 0) gets 1, so that normalising by it
    cannot divide by zero (HumanML3D has no such group; a tiny dataset can).
    """
    out = np.asarray(std, dtype=np.float64).copy()
    for group in STD_GROUPS:
        value = out[group].mean()
        out[group] = value if value > 1e-12 else 1.0
    return out


# --------------------------------------------------------------------------------------------
# Building.
# --------------------------------------------------------------------------------------------


@dataclass
class _Job:
    path: str
    name: str
    split: str
    mirror: bool
    min_frames: int
    out: str


def _process(job: _Job) -> dict:
    """Import one file and write its clip (and mirror). Runs in a worker process."""
    from motion_env import motion as mmath
    from motion_env.io.bvh import load_bvh

    result: dict = {"name": job.name, "status": "ok", "frames": 0, "stats": None}
    try:
        joints = load_bvh(job.path).joints
        if joints.shape[0] < job.min_frames:
            result.update(status="short", frames=int(joints.shape[0]))
            return result
        variants = [(job.name, joints)]
        if job.mirror:
            variants.append((MIRROR_PREFIX + job.name, mmath.mirror(joints)))
        arrays = []
        for name, j in variants:
            # load_bvh has floored the clip robustly already; joints_to_features' own floor (the
            # lowest joint of the whole clip) would let one bad frame lift everything.
            features = mmath.joints_to_features(j, floor=False)
            if not np.isfinite(features).all():
                raise ValueError("features contain NaN or infinite values")
            arrays.append((name, features, mmath.features_to_joints(features)))
        out = Path(job.out)
        stats = _RunningStats()
        for name, features, new_joints in arrays:
            np.save(out / "new_joint_vecs" / f"{name}.npy", features.astype(np.float32))
            np.save(out / "new_joints" / f"{name}.npy", new_joints.astype(np.float32))
            stats.add(*_clip_stats(features))
        result["frames"] = int(arrays[0][1].shape[0])
        if job.split == "train":
            result["stats"] = (stats.n, stats.mean, stats.m2)
    except Exception as exc:  # one bad file is reported, not fatal for the build
        message = str(exc).removeprefix(f"{job.path}: ").removeprefix(f"{job.path} ")
        result.update(status="failed", reason=f"{type(exc).__name__}: {message}".strip())
        if not isinstance(exc, (ValueError, FileNotFoundError, OSError, EOFError)):
            # An unexpected error type is a bug rather than a bad file: say where it happened.
            where = traceback.extract_tb(exc.__traceback__)[-1]
            result["reason"] += f" (at {Path(where.filename).name}:{where.lineno} in {where.name})"
    return result


def find_motion_files(sources: Sequence[str | Path]) -> list[tuple[Path, Path]]:
    """All ``.bvh`` / ``.bvh.gz`` files under the source folders: ``[(source_root, file), ...]``.

    A source may also be a single file. Each file is listed once, in sorted order.
    """
    found: list[tuple[Path, Path]] = []
    seen: set[Path] = set()
    for source in sources:
        root = Path(source).expanduser()
        if not root.exists():
            raise FileNotFoundError(f"source folder {root} does not exist")
        if root.is_file():
            files = [root]
            root = root.parent
        else:
            files = sorted(p for p in root.rglob("*") if p.name.lower().endswith((".bvh", ".bvh.gz")))
        for f in files:
            key = f.resolve()
            if key not in seen and f.is_file():
                seen.add(key)
                found.append((root, f))
    return found


class _CmuIndexFinder:
    """Finds the CMU-INDEX.md that applies to a file (its folder or above, up to the source's parent)."""

    def __init__(self, explicit: Path | None = None) -> None:
        self._explicit = parse_cmu_index(explicit.read_text(encoding="utf-8")) if explicit else None
        self._by_dir: dict[Path, dict[str, str] | None] = {}

    def __call__(self, root: Path, file: Path) -> dict[str, str] | None:
        if self._explicit is not None:
            return self._explicit
        stop = root.resolve().parent
        d = file.resolve().parent
        while True:
            if d not in self._by_dir:
                index_file = d / CMU_INDEX_NAME
                self._by_dir[d] = (
                    parse_cmu_index(index_file.read_text(encoding="utf-8")) if index_file.is_file() else None
                )
            if self._by_dir[d] is not None or d == stop or d.parent == d:
                return self._by_dir[d]
            d = d.parent


def _clip_name(labels: ClipLabels, root: Path, file: Path) -> str:
    if labels.source in ("bandai", "cmu"):
        base = labels.take if labels.source == "bandai" else f"cmu_{labels.take}"
    else:
        rel = file.relative_to(root).with_name(file_stem(file))
        base = "_".join(rel.parts)
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in base)


def _sidecar_captions(file: Path) -> list[str] | None:
    txt = file.with_name(file_stem(file) + ".txt")
    if not txt.is_file():
        return None
    lines = [
        " ".join(line.replace("#", " ").split()) for line in txt.read_text(encoding="utf-8").splitlines()
    ]
    return [line for line in lines if line] or None


def build_dataset(
    sources: Sequence[str | Path],
    out: str | Path,
    mirror: bool = True,
    workers: int = 2,
    captions_per_clip: int = DEFAULT_NUM_CAPTIONS,
    seed: int = 0,
    min_seconds: float = 1.0,
    cmu_index: str | Path | None = None,
    progress: bool = True,
) -> BuildSummary:
    """Turn BVH folders into a HumanML3D-layout dataset directory (see the module docstring).

    Args:
        sources: folders searched recursively for ``.bvh`` / ``.bvh.gz`` files (or single files).
        out: the dataset directory to create; must not exist or be empty.
        mirror: also store every take mirrored (``M<name>``).
        workers: processes importing files in parallel (1: in this process).
        captions_per_clip: captions written per clip (label-derived captions only).
        seed: seed of the caption wording.
        min_seconds: takes shorter than this are skipped (counted in the summary).
        cmu_index: a ``CMU-INDEX.md`` to use for every file, instead of looking for one.
        progress: show a tqdm progress bar.
    Returns:
        the :class:`BuildSummary`, also written to ``out/summary.json``.
    Raises:
        FileExistsError: ``out`` exists and is not an empty directory.
        FileNotFoundError: a source does not exist.
        ValueError: no BVH file found, or none could be imported.
    """
    t0 = time.perf_counter()
    out = Path(out).expanduser()
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise FileExistsError(f"output directory {out} exists and is not empty; nothing was written")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    if captions_per_clip < 1:
        raise ValueError(f"captions_per_clip must be >= 1, got {captions_per_clip}")
    files = find_motion_files(sources)
    if not files:
        raise ValueError(f"no .bvh or .bvh.gz files under {', '.join(str(s) for s in sources)}")

    find_index = _CmuIndexFinder(Path(cmu_index) if cmu_index else None)
    entries: list[dict] = []
    taken: set[str] = set()
    for root, file in files:
        labels = labels_for_file(file, find_index(root, file))
        name = base = _clip_name(labels, root, file)
        k = 2
        while name in taken or MIRROR_PREFIX + name in taken:
            name, k = f"{base}-{k}", k + 1
        taken.update((name, MIRROR_PREFIX + name))
        captions = _sidecar_captions(file) or captions_for(labels, n=captions_per_clip, seed=seed)
        entries.append(
            {"file": file, "name": name, "labels": labels, "captions": captions, "split": split_of(name)}
        )

    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.partial-{os.getpid()}")
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        for sub in ("new_joint_vecs", "new_joints", "texts"):
            (tmp / sub).mkdir(parents=True)
        summary, stats = _run_jobs(entries, tmp, mirror, workers, round(min_seconds * FPS), progress)
        summary.min_seconds = min_seconds
        _write_outputs(entries, summary, stats, tmp, mirror)
        summary.out = str(out)
        summary.seconds = time.perf_counter() - t0
        (tmp / "summary.json").write_text(json.dumps(summary.to_dict(), indent=1) + "\n", encoding="utf-8")
        if out.exists():
            out.rmdir()  # checked empty above
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return summary


def _run_jobs(
    entries: list[dict], tmp: Path, mirror: bool, workers: int, min_frames: int, progress: bool
) -> tuple[BuildSummary, _RunningStats]:
    """Import every file (in ``workers`` processes); the summary's skipped/failed lists and the
    train split's feature statistics."""
    from tqdm import tqdm

    jobs = [
        _Job(str(e["file"]), e["name"], e["split"], mirror, max(min_frames, 2), str(tmp)) for e in entries
    ]
    bar = tqdm(total=len(jobs), desc="data build", unit="file", disable=not progress, dynamic_ncols=True)
    results: dict[str, dict] = {}
    if workers == 1:
        for job in jobs:
            results[job.name] = _process(job)
            bar.update()
    else:
        # forkserver: workers start from a clean interpreter, safe even when the caller has
        # threads running (torch, tqdm), and cheaper than spawn.
        methods = multiprocessing.get_all_start_methods()
        ctx = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
        try:
            futures = [pool.submit(_process, job) for job in jobs]
            for future in as_completed(futures):
                r = future.result()
                results[r["name"]] = r
                bar.update()
        finally:
            # On Ctrl-C or an error, drop the queued files instead of importing them all first.
            pool.shutdown(wait=True, cancel_futures=True)
    bar.close()

    summary = BuildSummary(out=str(tmp))
    stats = _RunningStats()
    for e in entries:
        r = results[e["name"]]
        e["result"] = r
        if r["status"] == "short":
            summary.skipped.append(f"{e['file'].name} ({r['frames'] / FPS:.2f} s)")
        elif r["status"] == "failed":
            summary.failed.append((str(e["file"]), r["reason"]))
        elif r["stats"] is not None:
            stats.add(*r["stats"])
    return summary, stats


def _write_outputs(
    entries: list[dict], summary: BuildSummary, stats: _RunningStats, tmp: Path, mirror: bool
) -> None:
    """Texts, split files, index.csv, Mean/Std; fills the summary's counts."""
    split_names: dict[str, list[str]] = {s: [] for s in SPLITS}
    per_source: dict[str, dict[str, int]] = defaultdict(lambda: {"clips": 0, "frames": 0})
    per_label: dict[str, dict[str, dict[str, int]]] = defaultdict(
        lambda: defaultdict(lambda: {"clips": 0, "frames": 0})
    )
    rows = []
    for e in entries:
        r = e["result"]
        if r["status"] != "ok":
            continue
        labels: ClipLabels = e["labels"]
        summary.takes += 1
        variants = [(e["name"], e["captions"], labels.label, False)]
        if mirror:
            variants.append(
                (
                    MIRROR_PREFIX + e["name"],
                    [mirror_caption(c) for c in e["captions"]],
                    mirror_caption(labels.label),
                    True,
                )
            )
        for name, captions, label, mirrored in variants:
            write_captions(tmp / "texts" / f"{name}.txt", captions)
            split_names[e["split"]].append(name)
            for counter in (per_source[labels.source], per_label[labels.source][label]):
                counter["clips"] += 1
                counter["frames"] += r["frames"]
            summary.clips += 1
            summary.frames += r["frames"]
            rows.append(
                [
                    name,
                    e["split"],
                    labels.source,
                    labels.take,
                    label,
                    labels.style,
                    int(mirrored),
                    r["frames"],
                ]
                + [str(e["file"])]
            )
    if summary.clips == 0:
        reasons = "".join(f"; {Path(n).name}: {why}" for n, why in summary.failed[:3])
        raise ValueError(
            f"none of the {len(entries)} files could be used "
            f"({len(summary.failed)} failed, {len(summary.skipped)} too short){reasons}"
        )
    for split, names in split_names.items():
        (tmp / f"{split}.txt").write_text("".join(f"{n}\n" for n in sorted(names)), encoding="utf-8")
    all_names = sorted(n for names in split_names.values() for n in names)
    (tmp / "all.txt").write_text("".join(f"{n}\n" for n in all_names), encoding="utf-8")
    train_val = sorted(split_names["train"] + split_names["val"])
    (tmp / "train_val.txt").write_text("".join(f"{n}\n" for n in train_val), encoding="utf-8")
    with open(tmp / "index.csv", "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(["name", "split", "source", "take", "label", "style", "mirrored", "frames", "file"])
        writer.writerows(rows)

    if stats.n == 0:
        # A tiny dataset can hash every take into val/test: normalise with all clips instead.
        summary.warnings.append("the train split is empty; Mean/Std are computed over all clips")
        for name in all_names:
            stats.add(*_clip_stats(np.load(tmp / "new_joint_vecs" / f"{name}.npy")))
    mean = stats.mean
    std = grouped_std(np.sqrt(stats.m2 / stats.n))
    np.save(tmp / "Mean.npy", mean.astype(np.float32))
    np.save(tmp / "Std.npy", std.astype(np.float32))
    summary.splits = {s: len(split_names[s]) for s in SPLITS}
    summary.per_source = dict(per_source)
    summary.per_label = {s: dict(v) for s, v in per_label.items()}


# --------------------------------------------------------------------------------------------
# Reading.
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
