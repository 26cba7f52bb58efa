"""The import of the motion files during a build: one :class:`Job` per file, run in worker processes.

Each job imports a BVH file, writes its clip (and the mirrored clip) as features and joints into
the dataset being built, and returns its frame count and, for a train clip, its feature
statistics. A file that fails is reported with the reason instead of stopping the build.
"""

from __future__ import annotations

import multiprocessing
import traceback
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from motion_env.data.dataset import MIRROR_PREFIX
from motion_env.data.stats import RunningStats, clip_stats


@dataclass
class Job:
    """Import ``path`` as the clip ``name`` of ``split`` into the dataset folder ``out``.

    ``mirror``: also write ``M<name>``; ``min_frames``: shorter takes are reported, not written.
    """

    path: str
    name: str
    split: str
    mirror: bool
    min_frames: int
    out: str


def clip_arrays(
    name: str, joints: np.ndarray, mirror: bool = True
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """A take's clip (and its mirror ``M<name>``) as a build stores them: ``(name, features (T,
    263), new_joints (T, 22, 3))``, from the (T + 1, 22, 3) joints :func:`motion_env.io.bvh.load_bvh` gave.

    Raises:
        ValueError: the features are not finite.
    """
    from motion_env import motion as mmath

    variants = [(name, joints)]
    if mirror:
        variants.append((MIRROR_PREFIX + name, mmath.mirror(joints)))
    arrays = []
    for clip, j in variants:
        # load_bvh has floored the clip robustly already; joints_to_features' own floor (the
        # lowest joint of the whole clip) would let one bad frame lift everything.
        features = mmath.joints_to_features(j, floor=False)
        if not np.isfinite(features).all():
            raise ValueError("features contain NaN or infinite values")
        arrays.append((clip, features, mmath.features_to_joints(features)))
    return arrays


def run_job(job: Job) -> dict:
    """Import one file and write its clip (and mirror). Runs in a worker process.

    Returns ``{"name", "status": "ok" | "short" | "failed", "frames", "stats"}`` (``stats``:
    ``(n, mean, m2)`` of a train clip and its mirror, else None; ``reason`` when failed).
    """
    from motion_env.io.bvh import load_bvh

    result: dict = {"name": job.name, "status": "ok", "frames": 0, "stats": None}
    try:
        joints = load_bvh(job.path).joints
        if joints.shape[0] < job.min_frames:
            result.update(status="short", frames=int(joints.shape[0]))
            return result
        arrays = clip_arrays(job.name, joints, job.mirror)
        out = Path(job.out)
        stats = RunningStats()
        for name, features, new_joints in arrays:
            np.save(out / "new_joint_vecs" / f"{name}.npy", features.astype(np.float32))
            np.save(out / "new_joints" / f"{name}.npy", new_joints.astype(np.float32))
            stats.add(*clip_stats(features))
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


def run_jobs(jobs: Sequence[Job], workers: int, progress: bool) -> dict[str, dict]:
    """Run every job (in ``workers`` processes; 1: in this one): clip name -> :func:`run_job`'s result."""
    from tqdm import tqdm

    bar = tqdm(total=len(jobs), desc="data build", unit="file", disable=not progress, dynamic_ncols=True)
    results: dict[str, dict] = {}
    if workers == 1:
        for job in jobs:
            results[job.name] = run_job(job)
            bar.update()
    else:
        # forkserver: workers start from a clean interpreter, safe even when the caller has
        # threads running (torch, tqdm), and cheaper than spawn.
        methods = multiprocessing.get_all_start_methods()
        ctx = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx)
        try:
            futures = [pool.submit(run_job, job) for job in jobs]
            for future in as_completed(futures):
                r = future.result()
                results[r["name"]] = r
                bar.update()
        finally:
            # On Ctrl-C or an error, drop the queued files instead of importing them all first.
            pool.shutdown(wait=True, cancel_futures=True)
    bar.close()
    return results
