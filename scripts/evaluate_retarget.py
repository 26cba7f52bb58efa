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
    python scripts/evaluate_retarget.py --bench --no-generated --takes-per-action 2

--hands: only whether the robot's hands follow raised human hands: on the raise and wave takes
(and the generated raise, wave and a walking turn with raised hands), the correlation of each
raised hand's height (one whose height varies by RAISED_STD or more) with the robot wrist's, per
robot; with --guess MJCF[,MJCF], also with the mapping guessed from those files (measured at the
named robot's wrist frames) and the warnings the guess gave:

    python scripts/evaluate_retarget.py --hands --robots booster_t1 \
        --guess motion_env/retarget/robots/booster_t1/t1.xml

--bench: only the speed, per robot: every clip retargeted once (after a warm-up) between two
runs of the bench's calibration workload (:func:`motion_env.evaluation.bench.calibrated`), in
wall and CPU time, each also as its quiet-machine equivalent.
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
RAISED_STD = 0.05  # m: a human hand whose height varies this much is raised (--hands)
HANDS_CAPTION = "a person walks forward and turns left while raising both hands above the head"
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
    bench: bool = False  # only time the retargeting beside the calibration workload
    hands: bool = False  # only the raised-hand check (see the docstring)
    guess: str = ""  # --hands: MJCF files (comma-separated) to retarget onto with a guessed mapping


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


def time_retarget(clips: list[motion_env.Motion], robot: str, fps: float) -> dict[str, Any]:
    """Human frames retargeted per second over `clips`, wall and CPU time (the bench's shape)."""
    frames = sum(c.num_frames for c in clips)
    wall, cpu = time.perf_counter(), time.process_time()
    for motion in clips:
        motion_env.retarget(motion, robot=robot, fps=fps)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return {"frames": frames, "frames_per_s": frames / wall, "cpu": {"frames_per_s": frames / cpu}}


def bench(robots: list[str], clips: list[motion_env.Motion], fps: float) -> dict[str, Any]:
    """Per robot, :func:`time_retarget` beside the calibration workload; prints a line each."""
    from motion_env.evaluation.bench import calibrated

    out = {}
    for robot in robots:
        motion_env.retarget(clips[0], robot=robot, fps=fps)  # warm-up: load the model once
        out[robot] = result = calibrated(time_retarget, clips, robot, fps)
        print(
            f"{robot}: {result['frames']} human frames, {result['frames_per_s']:.0f} human frames/s "
            f"(CPU time {result['cpu']['frames_per_s']:.0f}), calibration {result['calibration_ms']:.0f} ms "
            f"-> quiet-machine equivalent {result['quiet']['frames_per_s']:.0f} "
            f"(from CPU time {result['quiet_cpu']['frames_per_s']:.0f})"
        )
    return out


def raised_hand_corr(
    qpos: np.ndarray, fps: float, motion: motion_env.Motion, model: Any, frames: list[tuple[str, str]]
) -> list[float]:
    """Per raised human hand of `motion`, the correlation of its height with the height of the
    robot frame (type, name) in `frames` (left, right) over `qpos` (T, nq) at `fps` on `model`."""
    import mujoco

    from motion_env.motion.kinematics import resample
    from motion_env.motion.skeleton import JOINT_INDEX

    human = resample(motion.joints.astype(np.float64), motion.fps, fps)[: len(qpos)]
    kinds = {"site": mujoco.mjtObj.mjOBJ_SITE, "body": mujoco.mjtObj.mjOBJ_BODY}
    ids = [mujoco.mj_name2id(model, kinds[kind], name) for kind, name in frames]
    data, robot = mujoco.MjData(model), np.zeros((len(qpos), 2))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        for side, ((kind, _), i) in enumerate(zip(frames, ids)):
            robot[t, side] = (data.site_xpos if kind == "site" else data.xpos)[i, 2]
    out = []
    for side, joint in enumerate(("left_wrist", "right_wrist")):
        height = human[:, JOINT_INDEX[joint], 1]
        if height.std() >= RAISED_STD:
            moving = robot[:, side].std() > 1e-9
            out.append(float(np.corrcoef(robot[:, side], height)[0, 1]) if moving else float("nan"))
    return out


def hands(robots: list[str], clips: list[tuple[str, str, str, Any]], guess: list[str], fps: float) -> dict:
    """The --hands check: per robot (and guessed model), each clip's raised-hand correlations."""
    import warnings

    from motion_env.retarget import load_robot

    out: dict = {}
    for robot in robots:
        bot = load_robot(robot)
        wrists = [next(t for t in bot.tasks if t.human == f"{s}_wrist") for s in ("left", "right")]
        frames = [(t.type, t.frame) for t in wrists]
        for target in [robot, *guess]:
            model = bot.model if target == robot else None
            rows, said = [], set()
            for _, group, name, motion in clips:
                with warnings.catch_warnings(record=True) as seen:
                    warnings.simplefilter("always")
                    result = motion_env.retarget(motion, robot=target, fps=fps)
                said |= {str(w.message) for w in seen}
                model = model or load_robot(target).model
                r = raised_hand_corr(result.qpos, fps, motion, model, frames)
                rows.append({"clip": name, "group": group, "r": r})
                print(f"{robot:11s} {Path(target).name:11s} {group:5s} r {np.round(r, 3)}  {name}")
            every = [x for row in rows for x in row["r"]]
            print(f"{robot} ({target}): {len(every)} raised hands, r min {np.nanmin(every):.3f}, "
                  f"mean {np.nanmean(every):.3f}")  # fmt: skip
            for message in sorted(said):
                print(f"  warned: {message}")
            out[f"{robot}:{target}"] = {"clips": rows, "warnings": sorted(said)}
    return out


def main(argv: list[str] | None = None) -> int:
    args = parse_dataclass(Args, argv, description=__doc__)

    clips: list[tuple[str, str, str, motion_env.Motion]] = []  # (source, group, name, motion)
    for group, take, path in real_takes(Path(args.data), args.takes_per_action):
        clips.append(("real", group, take, motion_env.load_motion(path)))
    if args.generated:
        import torch

        torch.set_num_threads(1)
        gen = motion_env.MotionGenerator.from_pretrained()
        captions = (
            dict(GENERATED, hands=(HANDS_CAPTION, [[0.0, 2.5], [-2.0, 3.5]])) if args.hands else GENERATED
        )
        for group, (text, route) in captions.items():
            motion = gen.generate(text, route, num_frames=args.frames, seed=args.seed)
            clips.append(("generated", group, text, motion))

    robots = [r.strip() for r in args.robots.split(",") if r.strip()]
    command = ["python", "scripts/evaluate_retarget.py", *(sys.argv[1:] if argv is None else argv)]
    if args.hands:
        chosen = [c for c in clips if c[1] in ("raise", "wave", "hands")]
        guessed = [g.strip() for g in args.guess.split(",") if g.strip()]
        checked = hands(robots, chosen, guessed, args.fps)
        if args.json:
            write_json(args.json, {"command": " ".join(command), "fps": args.fps, "hands": checked})
        return 0
    if args.bench:
        speeds = bench(robots, [c[3] for c in clips], args.fps)
        if args.json:
            info = {"command": " ".join(command), "fps": args.fps, "threads": 1}
            write_json(args.json, {**info, "bench": speeds})
        return 0
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
        "command": " ".join(command),
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
