#!/usr/bin/env python
"""Evaluate the retargeting onto the shipped robots: held-out real takes and generated clips.

For each robot and each clip, motion_env.retarget at --fps, then the numbers of
motion_env.retarget.quality (joint-range violations, floor penetration, floating while the human
stands, the largest joint jump between frames, correlation of hand and foot heights with the
human's, distance travelled robot / human) and the speed (human frames retargeted per second, one
thread). Prints a table per robot and writes every clip's numbers to --json.

- real takes: Bandai Namco dataset 2, test split (the project's hash split), --takes-per-action of
  each of walk, run, turns, waves and raises;
- generated: one clip per caption of walk, run, turn, wave and raise with the shipped model.

    python scripts/evaluate_retarget.py --json runs/retarget_eval.json
    python scripts/evaluate_retarget.py --data /path/to/shared/data --no-generated
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # the speed is measured on one thread

import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import motion_env  # noqa: E402
from motion_env.args import parse_dataclass, write_json  # noqa: E402
from motion_env.data.captions.files import labels_for_file  # noqa: E402
from motion_env.data.dataset import split_of  # noqa: E402
from motion_env.retarget.quality import QUALITY_BOUNDS, measure  # noqa: E402

DATA = os.environ.get("MOTION_ENV_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data"
# Action groups of the real takes: group -> Bandai content labels.
ACTIONS = {
    "walk": ("walk",),
    "run": ("run",),
    "turn": ("walk-turn-left", "walk-turn-right"),
    "wave": ("wave-both-hands", "wave-left-hand", "wave-right-hand"),
    "raise": ("raise-up-both-hands", "raise-up-left-hand", "raise-up-right-hand"),
}
# Generated clips: group -> (caption, waypoints or None).
GENERATED = {
    "walk": ("a person walks forward", [[0.0, 4.0]]),
    "run": ("a person runs forward", [[0.0, 6.0]]),
    "turn": ("a person walks forward and turns left", [[0.0, 2.5], [-2.0, 3.5]]),
    "wave": ("a person stands and waves with the right hand", None),
    "raise": ("a person raises both hands above the head", None),
}
COLUMNS = (
    ("range_violations", "violations", "{:d}"),
    ("penetration_cm", "penetr. cm", "{:.2f}"),
    ("stand_float_cm", "float cm", "{:.2f}"),
    ("max_jump_rad", "jump rad", "{:.3f}"),
    ("hand_corr", "hand corr", "{:.3f}"),
    ("foot_corr", "foot corr", "{:.3f}"),
    ("distance_ratio", "dist. ratio", "{:.3f}"),
    ("hand_residual_cm", "hand res. cm", "{:.2f}"),
    ("foot_residual_cm", "foot res. cm", "{:.2f}"),
)
_WORST = {"hand_corr": min, "foot_corr": min}  # the worst of a correlation is its smallest


def real_takes(data: Path, per_action: int) -> list[tuple[str, str, Path]]:
    """(group, take, path) of held-out (test split) Bandai takes, the first `per_action` per group."""
    folder = data / "bandai" / "dataset-2" / "bvh"
    if not folder.is_dir():
        raise FileNotFoundError(f"no Bandai Namco takes at {folder} (give --data /path/to/shared/data)")
    out = []
    for group, contents in ACTIONS.items():
        picked = []
        for path in sorted(folder.glob("*.bvh.gz")):
            labels = labels_for_file(path)
            if labels.label in contents and split_of(labels.take) == "test":
                picked.append((group, labels.take, path))
        # Spread the picks over the contents (a left and a right turn, ...).
        by_content = [[p for p in picked if labels_for_file(p[2]).label == c] for c in contents]
        order = [p for batch in zip(*by_content) for p in batch] if len(contents) > 1 else picked
        out.extend((order or picked)[:per_action])
    return out


def summarize(rows: list[dict]) -> dict:
    """Worst value of each number over `rows` (largest; smallest for a correlation), the range of
    the distance ratio, and the speed over all of them."""
    out: dict = {"clips": len(rows)}
    for key, _, _ in COLUMNS:
        values = [r[key] for r in rows if r[key] is not None]
        if key == "distance_ratio":
            out[key] = (min(values), max(values)) if values else None
        else:
            out[key] = _WORST.get(key, max)(values) if values else None
    out["human_fps"] = sum(r["human_frames"] for r in rows) / sum(r["seconds"] for r in rows)
    return out


def _cell(key: str, value, fmt: str) -> str:
    if value is None:
        return "–"
    if key == "distance_ratio":
        return f"{value[0]:.2f}–{value[1]:.2f}"
    return fmt.format(value)


def format_table(robot: str, groups: dict[str, dict]) -> str:
    header = ["clips", "n", *(label for _, label, _ in COLUMNS), "human fps"]
    lines = [f"### {robot}", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for name, s in groups.items():
        cells = [name, str(s["clips"]), *(_cell(k, s[k], f) for k, _, f in COLUMNS), f"{s['human_fps']:.0f}"]
        lines.append("| " + " | ".join(cells) + " |")
    bounds = ", ".join(
        f"{k} {'>=' if lo is not None else '<='} {lo if lo is not None else hi}"
        + (f" and <= {hi}" if lo is not None and hi is not None else "")
        for k, (lo, hi) in QUALITY_BOUNDS.items()
    )
    lines += ["", f"bounds: {bounds}"]
    return "\n".join(lines)


@dataclass
class Args:
    data: str = str(DATA)  # the shared data folder (bandai/ inside; $MOTION_ENV_DATA overrides)
    robots: str = "unitree_g1,booster_t1"  # robots, comma-separated
    fps: float = 50.0  # robot frame rate
    takes_per_action: int = 2  # real takes per action group
    generated: bool = True  # also clips of the shipped model (--no-generated: real takes only)
    frames: int = 160  # frames per generated clip (20 fps)
    seed: int = 0  # seed of the generated clips
    json: str = ""  # write every clip's numbers here (empty: do not)
    replay: bool = False  # also judge each robot clip with the robot replay (replay.evaluate_robot)


def judge(result: Any, robot: str) -> dict[str, Any]:
    """The robot replay's verdict on one retargeted clip (plausible, and the checks that failed)."""
    from motion_env.replay import evaluate_robot
    from motion_env.retarget import load_robot

    verdict = evaluate_robot(result.qpos, load_robot(robot).model, result.fps)
    return {"plausible": bool(verdict["plausible"]), "failed": list(verdict["failed"])}


def replay_summary(robot: str, rows: list[dict[str, Any]]) -> str:
    """One line per source: how many clips the robot replay judged plausible, and why not."""
    lines = []
    for source in ("real", "generated"):
        mine = [r for r in rows if r["source"] == source and "plausible" in r]
        if mine:
            failed = sorted({c for r in mine for c in r["failed"]})
            ok = sum(r["plausible"] for r in mine)
            lines.append(
                f"{robot} robot replay, {source}: {ok} / {len(mine)} plausible; failed checks: {failed}"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = parse_dataclass(Args, argv, description=__doc__)

    clips: list[tuple[str, str, str, motion_env.Motion]] = []  # (source, group, name, motion)
    for group, take, path in real_takes(Path(args.data), args.takes_per_action):
        clips.append(("real", group, take, motion_env.load_motion(path)))
    if args.generated:
        import torch

        torch.set_num_threads(1)
        gen = motion_env.MotionGenerator.from_pretrained()
        for group, (text, route) in GENERATED.items():
            motion = gen.generate(text, route, num_frames=args.frames, seed=args.seed)
            clips.append(("generated", group, text, motion))

    robots = [r.strip() for r in args.robots.split(",") if r.strip()]
    rows = []
    for robot in robots:
        motion_env.retarget(clips[0][3], robot=robot, fps=args.fps)  # warm-up: load the model once
        for source, group, name, motion in clips:
            t0 = time.perf_counter()
            result = motion_env.retarget(motion, robot=robot, fps=args.fps)
            seconds = time.perf_counter() - t0
            row = {"robot": robot, "source": source, "group": group, "clip": name}
            row.update(human_frames=motion.num_frames, seconds=seconds, **measure(result, motion))
            if args.replay:
                row.update(judge(result, robot))
            rows.append(row)
            print(f"{robot:11s} {source:9s} {group:5s} {row['frames']:4d} frames  "
                  f"jump {row['max_jump_rad']:.3f}  penetr. {row['penetration_cm']:.2f} cm  "
                  f"{motion.num_frames / seconds:5.0f} human fps  {name}")  # fmt: skip

    results: dict = {
        "command": " ".join(
            ["python", "scripts/evaluate_retarget.py", *(sys.argv[1:] if argv is None else argv)]
        ),
        "fps": args.fps,
        "threads": 1,
        "summary": {},
        "clips": rows,
    }
    print()
    for robot in robots:
        mine = [r for r in rows if r["robot"] == robot]
        groups = {}
        for source in ("real", "generated"):
            for group in ACTIONS:
                chosen = [r for r in mine if r["source"] == source and r["group"] == group]
                if chosen:
                    groups[f"{source} {group}"] = summarize(chosen)
        groups["all"] = summarize(mine)
        results["summary"][robot] = groups
        print(format_table(robot, groups))
        print()
        if args.replay:
            print(replay_summary(robot, mine))
    if args.json:
        write_json(args.json, results)
    bad = [r for r in rows if r["range_violations"]]
    return 1 if bad else 0


if __name__ == "__main__":
    np.set_printoptions(precision=3)
    sys.exit(main())
