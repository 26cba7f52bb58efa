"""Building a training dataset in the HumanML3D layout from BVH folders (``motion-env data build``).

The layout, and reading a dataset back, are in :mod:`motion_env.data.dataset`.
:func:`build_dataset` also writes ``index.csv`` (name, split, source, take, label, style,
mirrored, frames, file) and ``summary.json`` (the :class:`BuildSummary`); HumanML3D readers
ignore both.

- Every ``.bvh`` / ``.bvh.gz`` under the source folders (:func:`find_motion_files`) is imported
  with :func:`motion_env.io.bvh.load_bvh` (20 fps, canonical skeleton), in worker processes
  (:mod:`motion_env.data.jobs`). Captions come from the file name
  (:mod:`motion_env.data.captions`: Bandai ``dataset-N_{content}_{style}_{take}``, CMU trial ids
  looked up in a ``CMU-INDEX.md`` found in the file's folder or above it up to the source's
  parent, else the file-name words); a ``<stem>.txt`` next to a BVH file, one caption per line,
  replaces them.
- Each take is also stored mirrored (``M<name>``, left and right swapped in the motion and in
  the captions), like HumanML3D.
- Splits are by take: a hash of the clip name decides train / val / test (85 / 7.5 / 7.5 %,
  :func:`motion_env.data.dataset.split_of`), the same on every machine, and a mirror always goes
  where its take goes.
- Mean / Std: over the frames of the train split (mirrors included); the standard deviation is
  then averaged within each feature group (root rotation velocity, root linear velocity, root
  height, joint positions, 6-D rotations, joint velocities, foot contacts) as in HumanML3D's
  ``cal_mean_variance`` (:mod:`motion_env.data.stats`). One difference: HumanML3D computed them
  over all of its clips, this build over the train split only, so that validation and test stay
  unseen.
- Takes shorter than ``min_seconds`` are skipped and files that fail to import are listed with
  the reason; neither stops the build. The output directory must be empty or absent: the build
  writes into a temporary sibling folder (``.<out>.partial-<pid>``) and renames it at the end;
  an error or Ctrl-C removes it, so nothing half-written is left behind.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import time
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from motion_env.data.captions import (
    DEFAULT_NUM_CAPTIONS,
    ClipLabels,
    captions_for,
    file_stem,
    labels_for_file,
    parse_cmu_index,
)
from motion_env.data.dataset import CMU_INDEX_NAME, MIRROR_PREFIX, SPLITS, split_of, write_captions
from motion_env.data.jobs import Job, run_jobs
from motion_env.data.stats import RunningStats, clip_stats, grouped_std
from motion_env.motion.skeleton import FPS
from motion_env.text.mirror import mirror_caption


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
        min_frames = max(round(min_seconds * FPS), 2)
        jobs = [Job(str(e["file"]), e["name"], e["split"], mirror, min_frames, str(tmp)) for e in entries]
        summary = BuildSummary(out=str(out), min_seconds=min_seconds)
        stats = _tally(entries, run_jobs(jobs, workers, progress), summary)
        _write_outputs(entries, summary, stats, tmp, mirror)
        summary.seconds = time.perf_counter() - t0
        (tmp / "summary.json").write_text(json.dumps(summary.to_dict(), indent=1) + "\n", encoding="utf-8")
        if out.exists():
            out.rmdir()  # checked empty above
        tmp.rename(out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return summary


def _tally(entries: list[dict], results: dict[str, dict], summary: BuildSummary) -> RunningStats:
    """Attach each file's result to its entry, list the skipped and failed files in the summary;
    the feature statistics of the train split."""
    stats = RunningStats()
    for e in entries:
        r = results[e["name"]]
        e["result"] = r
        if r["status"] == "short":
            summary.skipped.append(f"{e['file'].name} ({r['frames'] / FPS:.2f} s)")
        elif r["status"] == "failed":
            summary.failed.append((str(e["file"]), r["reason"]))
        elif r["stats"] is not None:
            stats.add(*r["stats"])
    return stats


def _write_outputs(
    entries: list[dict], summary: BuildSummary, stats: RunningStats, tmp: Path, mirror: bool
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
            stats.add(*clip_stats(np.load(tmp / "new_joint_vecs" / f"{name}.npy")))
    mean = stats.mean
    std = grouped_std(np.sqrt(stats.m2 / stats.n))
    np.save(tmp / "Mean.npy", mean.astype(np.float32))
    np.save(tmp / "Std.npy", std.astype(np.float32))
    summary.splits = {s: len(split_names[s]) for s in SPLITS}
    summary.per_source = dict(per_source)
    summary.per_label = {s: dict(v) for s, v in per_label.items()}
