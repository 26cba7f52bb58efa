"""Calibrate the thresholds of `motion_env.replay.evaluate` on real motion capture.

    python scripts/calibrate_replay.py --data ../shared/data [--workers 2] [--stride 1]

Takes: every Bandai Namco and CMU BVH under --data, loaded with `motion_env.load_bvh`, split by
take with `motion_env.data.dataset.split_of` (the split `motion-env data build` gives them: the
Bandai file stem, `cmu_<trial>` for CMU). CMU trials that do not happen on a flat floor
(playground, ladder, steps, stools, uneven terrain: see OFF_FLOOR) are left out; the replay
scene has nothing but a floor.

Thresholds: for each check, the QUANTILE of the per-take values (the worst frame of each take)
over the train split, times MARGIN, and at least MINIMUM. Then the held-out test:

- the test split's walk, run and turn takes (Bandai walk / run / dash / walk-turn / walk-back /
  walk-left / walk-right, CMU trials described as walk, run, jog or navigate) must be judged
  plausible;
- each of the corruptions of `motion_env.replay.corruptions`, applied to them, must be caught.

Writes the thresholds (and how they were made) to --out and prints the numbers.
"""

from __future__ import annotations

import argparse
import csv
import json
import re
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from motion_env.data.captions import parse_cmu_index
from motion_env.data.dataset import split_of
from motion_env.io.bvh import load_bvh
from motion_env.motion.skeleton import FPS
from motion_env.replay import corruptions
from motion_env.replay.kinematic import measure
from motion_env.replay.plausibility import CHECKS, UNITS, report, signals, thresholds_path

QUANTILE = 99.0
MARGIN = 1.25
MINIMUM = {
    "penetration": 0.02,
    "floating": 0.1,
    "foot_skating": 0.1,
    "self_penetration": 0.02,
    "joint_limits": 5.0,
    "speed": 5.0,
    "acceleration": 50.0,
    "root_force": 2.0,
    "root_torque": 1.0,
}
OFF_FLOOR = re.compile(r"playground|climb|ladder|stool|steps|uneven terrain|sit on", re.IGNORECASE)
BANDAI_LOCOMOTION = {
    "walk",
    "run",
    "dash",
    "walk-turn-left",
    "walk-turn-right",
    "walk-back",
    "walk-left",
    "walk-right",
}
CMU_LOCOMOTION = re.compile(r"^(slow |brisk )?(walk|run|jog|navigate)", re.IGNORECASE)
MIN_FRAMES_FOR_CORRUPTION = 50  # 2.5 s: room for a one-second corruption in the middle


@dataclass(frozen=True)
class Take:
    path: Path
    name: str  # the dataset's clip name
    source: str  # "bandai" or "cmu"
    action: str  # Bandai content label or CMU description
    split: str
    locomotion: bool


def find_takes(data: Path) -> list[Take]:
    """Every flat-floor take under `data` with its split and whether it is walk/run/turn."""
    takes = []
    for path in sorted((data / "bandai").glob("*/bvh/*.bvh*")):
        stem = path.name.split(".bvh")[0]
        content = stem.split("_")[1]
        takes.append(Take(path, stem, "bandai", content, split_of(stem), content in BANDAI_LOCOMOTION))
    index_file = data / "cmu" / "CMU-INDEX.md"
    index = parse_cmu_index(index_file.read_text(encoding="utf-8")) if index_file.is_file() else {}
    for path in sorted((data / "cmu").rglob("*.bvh*")):
        trial = path.name.split(".bvh")[0]
        desc = index.get(trial, trial)
        if OFF_FLOOR.search(desc):
            continue
        name = f"cmu_{trial}"
        takes.append(Take(path, name, "cmu", desc, split_of(name), bool(CMU_LOCOMOTION.match(desc))))
    return takes


def _values(path: str) -> dict[str, float] | str:
    """Per-check values (worst frame) of one take, or the error that stopped it."""
    try:
        motion = load_bvh(path)
        sig = signals(measure(motion))
        return {c: float(sig[c].max()) for c in CHECKS}
    except (ValueError, FileNotFoundError) as exc:
        return f"{type(exc).__name__}: {exc}"


def _held_out(args: tuple[str, dict[str, float]]) -> dict | str:
    """Report on one held-out take and its corruptions: which checks failed for each."""
    path, thresholds = args
    try:
        motion = load_bvh(path)
        variants = {"real": motion}
        if motion.num_frames >= MIN_FRAMES_FOR_CORRUPTION:
            variants.update({k: fn(motion) for k, fn in corruptions.ALL.items()})
        return {k: report(measure(v), thresholds)["failed"] for k, v in variants.items()}
    except (ValueError, FileNotFoundError) as exc:
        return f"{type(exc).__name__}: {exc}"


def _map(fn, items: list, workers: int, desc: str) -> list:
    if workers <= 1:
        return [fn(x) for x in tqdm(items, desc=desc, unit="take")]
    with ProcessPoolExecutor(workers) as pool:
        return list(tqdm(pool.map(fn, items, chunksize=4), total=len(items), desc=desc, unit="take"))


def _parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--data", type=Path, required=True, help="folder with bandai/ and cmu/ (../shared/data)"
    )
    parser.add_argument("--out", type=Path, default=thresholds_path(), help="thresholds JSON to write")
    parser.add_argument("--stride", type=int, default=1, help="use every n-th calibration take (quick runs)")
    parser.add_argument("--workers", type=int, default=1, help="processes")
    parser.add_argument("--values", type=Path, default=None, help="also write every take's values (.csv)")
    args = parser.parse_args(argv)
    if not (args.data / "bandai").is_dir() and not (args.data / "cmu").is_dir():
        parser.error(f"no bandai/ or cmu/ folder under {args.data}")
    return args


def _thresholds(results: list[dict[str, float] | str]) -> tuple[dict, dict, float]:
    """Thresholds from the calibration takes' values (the failed takes' errors left out), the
    values' percentiles per check, and the share of the takes that pass every check; printed."""
    ok_values = [r for r in results if not isinstance(r, str)]
    values = {c: np.array([r[c] for r in ok_values]) for c in CHECKS}
    thresholds, stats = {}, {}
    for c in CHECKS:
        v = values[c]
        thresholds[c] = float(max(np.percentile(v, QUANTILE) * MARGIN, MINIMUM[c]))
        stats[c] = {f"p{q}": float(np.percentile(v, q)) for q in (50, 90, 99)} | {"max": float(v.max())}

    print(f"\nthresholds ({QUANTILE:g}th percentile of {len(ok_values)} takes x {MARGIN:g}, "
          f"at least the minimum):")  # fmt: skip
    print(f"  {'check':<17}{'threshold':>10}  {'p50':>8}{'p90':>8}{'p99':>8}{'max':>8}  unit")
    for c in CHECKS:
        s = stats[c]
        row = "".join(f"{s[q]:8.3f}" for q in ("p50", "p90", "p99", "max"))
        print(f"  {c:<17}{thresholds[c]:10.3f}  {row}  {UNITS[c]}")
    calib_pass = sum(all(r[c] <= thresholds[c] for c in CHECKS) for r in ok_values) / max(len(ok_values), 1)
    print(f"  calibration takes that pass every check: {100 * calib_pass:.1f} %")
    return thresholds, stats, calib_pass


def _write_values(path: Path, calib: list[Take], results: list[dict[str, float] | str]) -> None:
    """Every calibration take's values as a .csv (one row a take)."""
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["name", "source", "action", *CHECKS])
        for t, r in zip(calib, results):
            if not isinstance(r, str):
                writer.writerow([t.name, t.source, t.action, *(f"{r[c]:.6g}" for c in CHECKS)])


def _held_out_test(held: list[Take], held_results: list[dict | str]) -> dict:
    """The held-out test's numbers: how many real takes are judged plausible, which checks fail
    them, and how each corruption is caught; printed."""
    ok = [(t, r) for t, r in zip(held, held_results) if not isinstance(r, str)]
    plausible = [t for t, r in ok if not r["real"]]
    rate = len(plausible) / max(len(ok), 1)
    print(f"\nheld-out walk/run/turn takes judged plausible: {len(plausible)}/{len(ok)} = {100 * rate:.1f} %")
    fails = Counter(c for _, r in ok for c in r["real"])
    for t, r in ok:
        if r["real"]:
            print(f"  not plausible: {t.name} ({t.action}): {', '.join(r['real'])}")
    detection = {}
    for k, expected in corruptions.CAUGHT_BY.items():
        tried = [(t, r[k]) for t, r in ok if k in r]
        caught = sum(bool(f) for _, f in tried)
        right = sum(bool(set(f) & expected) for _, f in tried)
        detection[k] = {"takes": len(tried), "caught": caught, "caught_by_expected_check": right}
        missed = [t.name for t, f in tried if not set(f) & expected]
        by_check = Counter(c for _, f in tried for c in f)
        detection[k]["failed_checks"] = dict(by_check)
        print(f"  corruption {k:<13} caught {caught}/{len(tried)}, by {'/'.join(sorted(expected))}: "
              f"{right}/{len(tried)}" + (f"  missed: {missed[:5]}" if missed else ""))  # fmt: skip
        print(f"    checks failing: {', '.join(f'{c} {n}' for c, n in by_check.most_common())}")
    return {
        "takes": len(ok),
        "plausible": len(plausible),
        "pass_rate": rate,
        "failed_checks": dict(fails),
        "corruptions": detection,
    }


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    takes = find_takes(args.data)
    calib = [t for t in takes if t.split == "train"][:: max(1, args.stride)]
    held = [t for t in takes if t.split == "test" and t.locomotion]
    by_source = Counter(t.source for t in held)
    print(
        f"{len(takes)} flat-floor takes; calibrating on {len(calib)} train takes, testing on {len(held)} "
        f"held-out walk/run/turn takes ({by_source['bandai']} Bandai, {by_source['cmu']} CMU)"
    )

    results = _map(_values, [str(t.path) for t in calib], args.workers, "calibration")
    thresholds, stats, calib_pass = _thresholds(results)
    failed = [(t.name, r) for t, r in zip(calib, results) if isinstance(r, str)]
    if failed:
        print(f"  ({len(failed)} takes could not be loaded: {failed[:3]} ...)")
    if args.values:
        _write_values(args.values, calib, results)

    held_results = _map(_held_out, [(str(t.path), thresholds) for t in held], args.workers, "held-out")
    out = {
        "thresholds": thresholds,
        "units": UNITS,
        "method": {
            "command": f"python scripts/calibrate_replay.py --data {args.data} --stride {args.stride}",
            "fps": FPS,
            "quantile": QUANTILE,
            "margin": MARGIN,
            "minimum": MINIMUM,
            "calibration_takes": len(results) - len(failed),
            "calibration_split": (
                "train (motion_env.data.dataset.split_of), flat-floor Bandai Namco and CMU takes"
            ),
            "stride": args.stride,
        },
        "calibration_values": stats,
        "calibration_pass_rate": calib_pass,
        "held_out": _held_out_test(held, held_results),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(f"\nwrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
