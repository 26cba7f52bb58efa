"""Evaluation of a generator: route following, foot skating and caption steering (scripts/evaluate.py).

Route following (PRODUCT.md's definitions), on two sets of routes:

- held-out takes: the test split's own root paths, with timed waypoints every 2-3 s taken from
  the take (and its last frame), the character starting where the take starts; captions are
  written here from the take's labels in words the training captions do not use;
- synthetic routes: lines, arcs, zigzags and S-curves at walking (1.0-1.5 m/s) and running
  (2.5-3.5 m/s) pace, timed waypoints every 2-3 s, with new walking / running captions.

Per set: root error (mean XZ distance between the pelvis at a waypoint's frame and the waypoint,
cm), location error (share of waypoints missed by > 50 cm), trajectory error (share of clips
with any waypoint missed by > 50 cm) and the largest miss, for the final motions, for the
controller's path alone (before the path is bent through the waypoints) and, on the synthetic
routes, for streaming (:meth:`MotionGenerator.stream`). Foot skating ratio of all generated
clips vs the real test takes, measured the same way.

Caption steering: mean speed and cadence (steps/s, from foot contacts) for running vs walking
captions on an untimed route and without a route; right- vs left-wrist height for "waves with the
right/left hand"; heading change for left- vs right-turn captions without a route; speed of
"exhausted" / "elderly" vs "active" walks. The same numbers on real
takes of the dataset with those labels are given for reference.
"""

from __future__ import annotations

import csv
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.evaluation.metrics import detect_foot_contacts, foot_skating_ratio
from motion_env.motion.skeleton import FPS, JOINT_INDEX
from motion_env.motion.trajectory import root_path_from_joints, waypoint_errors

MISS = 0.5  # metres: a waypoint missed by more than this counts in the location/trajectory errors

# Captions written for the evaluation, in words and sentence frames the training captions
# (motion_env/captions.py) do not use.
WALK_CAPTIONS = (
    "someone ambles along at an easy, unhurried gait",
    "a man makes his way forward on foot at a comfortable clip",
    "the character saunters ahead calmly",
)
RUN_CAPTIONS = (
    "someone hurries along at full tilt, feet pounding",
    "a woman races ahead as fast as her legs allow",
    "the character bolts forward at top speed",
)
# For contrast only: running captions in the training phrasing (captions.py).
RUN_CAPTIONS_TRAINING_PHRASING = ("a person runs forward", "someone jogs straight ahead")
WAVE_RIGHT = ("standing still, someone greets a friend by waving with the right hand",)
WAVE_LEFT = ("standing still, someone greets a friend by waving with the left hand",)
TURN_LEFT = ("a man makes his way forward on foot, then curves off leftward",)
TURN_RIGHT = ("a man makes his way forward on foot, then curves off rightward",)
STYLE_CAPTIONS = {
    "exhausted": ("drained and out of breath, an exhausted man drags himself forward",),
    "elderly": ("an elderly gentleman in his nineties makes his way forward with care",),
    "active": ("full of pep, an active young woman heads forward",),
}
# Held-out takes: the take's action and style in new words.
ACTION_WORDS = {
    "walk": "makes their way straight ahead on foot",
    "walk-turn-left": "makes their way forward on foot, curving off leftward",
    "walk-turn-right": "makes their way forward on foot, curving off rightward",
    "walk-left": "heads forward on foot, drifting off leftward",
    "walk-right": "heads forward on foot, drifting off rightward",
    "run": "hurries ahead at full tilt",
    "dash": "bolts ahead at top speed",
    "wave-both-hands": "greets someone, both arms swinging overhead",
    "wave-left-hand": "greets someone, swinging the left arm overhead",
    "wave-right-hand": "greets someone, swinging the right arm overhead",
    "raise-up-both-hands": "lifts both arms up above the head",
    "raise-up-left-hand": "lifts the left arm up above the head",
    "raise-up-right-hand": "lifts the right arm up above the head",
}
STYLE_WORDS = {
    "active": "a peppy", "elderly": "a frail old", "exhausted": "a drained", "feminine": "a graceful",
    "masculine": "a burly", "normal": "an ordinary", "youthful": "a teenage",
}  # fmt: skip


@dataclass
class Case:
    """One route to follow: caption, (K, 3) timed waypoints, start (x, z, heading), frames."""

    name: str
    text: str
    waypoints: np.ndarray
    start: np.ndarray
    num_frames: int
    group: str


# --------------------------------------------------------------------------------------------
# Routes
# --------------------------------------------------------------------------------------------


def _waypoint_frames(num_frames: int, rng: np.random.Generator) -> list[int]:
    """Frames every 2-3 s (40-60 frames) after the start, and the last frame."""
    frames, f = [], 0
    while True:
        f += int(rng.integers(40, 61))
        if f >= num_frames - 10:
            break
        frames.append(f)
    return frames + [num_frames - 1]


def synthetic_path(
    kind: str, speed: float, num_frames: int, rng: np.random.Generator, corners: list[int] | None = None
) -> np.ndarray:
    """A (T, 2) XZ path from the origin, heading +Z, at constant `speed` (m/s).

    Shapes are scaled by time, so that a run is the same shape as a walk, only larger:
    "line"; "arc": turning 11-19 deg/s to one side; "zigzag": legs at +-30-50 deg that change
    at the `corners` frames (default: every 2-3 s); "scurve": the heading swinging +-30-50 deg
    with a period of 6-9 s.
    """
    t = np.arange(num_frames) / FPS
    side = rng.choice([-1.0, 1.0])
    if kind == "line":
        heading = np.zeros_like(t)
    elif kind == "arc":
        heading = side * t / rng.uniform(3.0, 5.0)
    elif kind == "zigzag":
        corners = corners if corners is not None else _waypoint_frames(num_frames, rng)
        leg = np.searchsorted(np.asarray(corners), np.arange(num_frames), side="right")
        heading = side * np.deg2rad(rng.uniform(30, 50)) * np.where(leg % 2 == 0, 1.0, -1.0)
    elif kind == "scurve":
        heading = side * np.deg2rad(rng.uniform(30, 50)) * np.sin(2 * np.pi * t / rng.uniform(6.0, 9.0))
    else:
        raise ValueError(f"unknown synthetic path kind {kind!r}")
    step = np.stack([np.sin(heading), np.cos(heading)], axis=1) * speed / FPS
    return np.concatenate([np.zeros((1, 2)), np.cumsum(step[:-1], axis=0)])


def synthetic_cases(num_frames: int = 200, repeats: int = 2, seed: int = 0) -> list[Case]:
    """Lines, arcs, zigzags, S-curves at walking and running pace, timed waypoints every 2-3 s."""
    rng = np.random.default_rng(seed)
    cases = []
    for kind in ("line", "arc", "zigzag", "scurve"):
        for pace, (lo, hi), captions in (
            ("walk", (1.0, 1.5), WALK_CAPTIONS),
            ("run", (2.5, 3.5), RUN_CAPTIONS),
        ):
            for r in range(repeats):
                speed = float(rng.uniform(lo, hi))
                frames = _waypoint_frames(num_frames, rng)
                path = synthetic_path(kind, speed, num_frames, rng, corners=frames[:-1])
                wp = np.array([[*path[f], f] for f in frames], np.float32)
                text = captions[int(rng.integers(len(captions)))]
                cases.append(Case(f"{kind}-{pace}-{r}", text, wp, np.zeros(3, np.float32), num_frames, pace))
    return cases


def _read_index(data_dir: Path) -> dict[str, dict[str, str]]:
    path = data_dir / "index.csv"
    if not path.is_file():
        return {}
    with path.open(newline="", encoding="utf-8") as f:
        return {row["name"]: row for row in csv.DictReader(f)}


def heldout_caption(label: str, style: str, fallback: str) -> str:
    """A caption for a held-out take written from its labels in new words (or `fallback`)."""
    if label not in ACTION_WORDS:
        return fallback
    return f"{STYLE_WORDS.get(style, 'a')} person {ACTION_WORDS[label]}"


def heldout_cases(
    data_dir: str | Path, max_clips: int = 64, min_frames: int = 60, seed: int = 0, split: str = "test"
) -> tuple[list[Case], list[np.ndarray]]:
    """Routes of a held-out split's takes: (cases, the takes' real joints (T, 22, 3)).

    split: "test" for reporting; "val" for choosing between models or settings.
    """
    from motion_env.data.dataset import read_split

    data_dir = Path(data_dir)
    index = _read_index(data_dir)
    clips = [c for c in read_split(data_dir, split) if len(c.joints) >= min_frames and ":" not in c.name]
    rng = np.random.default_rng(seed)
    if len(clips) > max_clips:
        clips = [clips[i] for i in sorted(rng.choice(len(clips), max_clips, replace=False))]
    cases, real = [], []
    for clip in clips:
        joints = np.asarray(clip.joints, np.float32)
        path = root_path_from_joints(joints)
        frames = _waypoint_frames(len(joints), rng)
        wp = np.array([[path[f, 0], path[f, 1], f] for f in frames], np.float32)
        row = index.get(clip.name, {})
        label = row.get("label", "")
        moving = np.linalg.norm(path[-1, :2] - path[0, :2]) > 1.0
        text = heldout_caption(label, row.get("style", ""), clip.captions[0])
        cases.append(
            Case(clip.name, text, wp, path[0].copy(), len(joints), "moving" if moving else "in place")
        )
        real.append(joints)
    return cases, real


# --------------------------------------------------------------------------------------------
# Metrics
# --------------------------------------------------------------------------------------------


def route_summary(errors: list[np.ndarray]) -> dict[str, float]:
    """Per-clip waypoint misses (m) -> root error (cm), location/trajectory error, max miss (cm)."""
    if not errors:
        return {"clips": 0}
    flat = np.concatenate(errors)
    return {
        "root_error_cm": float(flat.mean() * 100),
        "location_error": float((flat > MISS).mean()),
        "trajectory_error": float(np.mean([e.max() > MISS for e in errors])),
        "max_miss_cm": float(flat.max() * 100),
        "clips": len(errors),
        "waypoints": int(flat.size),
    }


def speed_and_cadence(joints: np.ndarray, skip: int = 20) -> tuple[float, float]:
    """Mean pelvis speed (m/s) and cadence (foot strikes per second) after the first `skip` frames."""
    j = np.asarray(joints, np.float64)[skip:]
    if len(j) < 2:
        return 0.0, 0.0
    xz = j[:, 0, [0, 2]]
    speed = float(np.linalg.norm(np.diff(xz, axis=0), axis=1).sum() / (len(j) - 1) * FPS)
    contact = detect_foot_contacts(j)  # (T, 4): left ankle, left toe, right ankle, right toe
    strikes = 0
    for foot in (contact[:, :2].any(axis=1), contact[:, 2:].any(axis=1)):
        strikes += int(np.sum(foot[1:] & ~foot[:-1]))
    return speed, strikes / ((len(j) - 1) / FPS)


def wrist_heights(joints: np.ndarray) -> dict[str, float]:
    """Mean right- and left-wrist height above the pelvis (cm) and their difference."""
    j = np.asarray(joints, np.float64)
    right = (j[:, JOINT_INDEX["right_wrist"], 1] - j[:, 0, 1]).mean() * 100
    left = (j[:, JOINT_INDEX["left_wrist"], 1] - j[:, 0, 1]).mean() * 100
    return {"right_cm": float(right), "left_cm": float(left), "right_minus_left_cm": float(right - left)}


def heading_change(joints: np.ndarray) -> float:
    """How far the body turns over a clip (degrees; positive = counterclockwise seen from above,
    a left turn for a body facing +Z with +X on its left)."""
    heading = np.unwrap(root_path_from_joints(np.asarray(joints, np.float64))[:, 2])
    return float(np.rad2deg(heading[-1] - heading[0]))


def _mean_std(values: list[float]) -> dict[str, float]:
    arr = np.asarray(values, np.float64)
    return {"mean": float(arr.mean()), "std": float(arr.std()), "n": int(arr.size)}


# --------------------------------------------------------------------------------------------
# Running the generator
# --------------------------------------------------------------------------------------------


def _generate(
    gen: Any, cases: list[Case], seed: int, batch: int = 16
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Final joints and the controller-only root paths of every case (batched)."""
    joints, raw = [], []
    for first in range(0, len(cases), batch):
        chunk = cases[first : first + batch]
        frames = max(c.num_frames for c in chunk)
        args = ([c.text for c in chunk], [c.waypoints for c in chunk], frames, seed + first)
        starts = np.stack([c.start for c in chunk])
        motions = gen.generate_batch(*args, starts=starts)
        paths = gen.root_paths(*args, starts=starts, snap=False)
        for c, m, p in zip(chunk, motions, paths, strict=True):
            joints.append(m.joints[: c.num_frames])
            raw.append(p[: c.num_frames])
    return joints, raw


def _stream(gen: Any, cases: list[Case], seed: int) -> list[np.ndarray]:
    """Every case streamed frame by frame in one batch (the environment's path)."""
    stream = gen.stream(
        [c.text for c in cases], [c.waypoints for c in cases], np.stack([c.start for c in cases]), seed
    )
    frames = max(c.num_frames for c in cases)
    out = np.stack([stream.step() for _ in range(frames)], axis=1)  # (B, T, 22, 3)
    return [out[i, : c.num_frames] for i, c in enumerate(cases)]


def evaluate_routes(
    gen: Any, cases: list[Case], seed: int, stream: bool
) -> tuple[dict[str, Any], list[np.ndarray]]:
    """Route metrics of the final motions, the controller alone and (optionally) streaming."""
    joints, raw = _generate(gen, cases, seed)
    final = [waypoint_errors(j[:, 0, [0, 2]], c.waypoints) for j, c in zip(joints, cases, strict=True)]
    ctrl = [waypoint_errors(p[:, :2], c.waypoints) for p, c in zip(raw, cases, strict=True)]
    out: dict[str, Any] = {
        "final": route_summary(final),
        "controller_only": route_summary(ctrl),
        "groups": {},
        "foot_skating": float(np.mean([foot_skating_ratio(j) for j in joints])),
    }
    for group in sorted({c.group for c in cases}):
        idx = [i for i, c in enumerate(cases) if c.group == group]
        out["groups"][group] = {
            "final": route_summary([final[i] for i in idx]),
            "controller_only": route_summary([ctrl[i] for i in idx]),
            "foot_skating": float(np.mean([foot_skating_ratio(joints[i]) for i in idx])),
        }
    if stream:
        streamed = _stream(gen, cases, seed)
        out["stream"] = route_summary(
            [waypoint_errors(j[:, 0, [0, 2]], c.waypoints) for j, c in zip(streamed, cases, strict=True)]
        )
        out["stream_foot_skating"] = float(np.mean([foot_skating_ratio(j) for j in streamed]))
        joints = joints + streamed
    return out, joints


def caption_steering(gen: Any, seeds: int = 4, num_frames: int = 200, seed: int = 0) -> dict[str, Any]:
    """Speed/cadence for run vs walk captions, wrist heights for waves, speed for walking styles."""
    # Far enough that a run does not arrive (and slow down) within the clip.
    untimed = np.array([[0.0, 4.0 * k] for k in range(1, 11)], np.float32)

    def run(texts: tuple[str, ...], route: np.ndarray | None, frames: int = num_frames) -> list[np.ndarray]:
        batch = [t for t in texts for _ in range(seeds)]
        return [
            m.joints
            for m in gen.generate_batch(batch, None if route is None else [route] * len(batch), frames, seed)
        ]

    out: dict[str, Any] = {}
    for route_name, route in (("untimed_route", untimed), ("no_route", None)):
        for pace, texts in (("walk", WALK_CAPTIONS), ("run", RUN_CAPTIONS)):
            sc = [speed_and_cadence(j) for j in run(texts, route)]
            out[f"{pace}_{route_name}"] = {
                "speed_mps": _mean_std([s for s, _ in sc]),
                "cadence_steps_per_s": _mean_std([c for _, c in sc]),
            }
    sc = [speed_and_cadence(j) for j in run(RUN_CAPTIONS_TRAINING_PHRASING, untimed)]
    out["run_training_phrasing_untimed_route"] = {
        "speed_mps": _mean_std([s for s, _ in sc]),
        "cadence_steps_per_s": _mean_std([c for _, c in sc]),
    }
    for side, texts in (("wave_right", WAVE_RIGHT), ("wave_left", WAVE_LEFT)):
        heights = [wrist_heights(j) for j in run(texts, None, 120)]
        out[side] = {k: _mean_std([h[k] for h in heights]) for k in heights[0]}
    for side, texts in (("turn_left", TURN_LEFT), ("turn_right", TURN_RIGHT)):
        out[side] = {"heading_change_deg": _mean_std([heading_change(j) for j in run(texts, None)])}
    for style, texts in STYLE_CAPTIONS.items():
        sc = [speed_and_cadence(j) for j in run(texts, untimed)]
        out[f"walk_{style}"] = {
            "speed_mps": _mean_std([s for s, _ in sc]),
            "cadence_steps_per_s": _mean_std([c for _, c in sc]),
        }
    return out


def real_reference(data_dir: str | Path, max_per_group: int = 40, seed: int = 0) -> dict[str, Any]:
    """The steering numbers on real takes of the dataset (all splits) with matching labels."""
    data_dir = Path(data_dir)
    index = _read_index(data_dir)
    if not index:
        return {"skipped": f"no index.csv in {data_dir}"}
    rng = np.random.default_rng(seed)
    groups = {
        "walk": lambda r: r["label"] == "walk",
        "run": lambda r: r["label"] == "run",
        "wave_right": lambda r: r["label"] == "wave-right-hand",
        "wave_left": lambda r: r["label"] == "wave-left-hand",
        "turn_left": lambda r: r["label"] == "walk-turn-left",
        "turn_right": lambda r: r["label"] == "walk-turn-right",
        "walk_exhausted": lambda r: r["label"] == "walk" and r["style"] == "exhausted",
        "walk_elderly": lambda r: r["label"] == "walk" and r["style"] == "elderly",
        "walk_active": lambda r: r["label"] == "walk" and r["style"] == "active",
    }
    out: dict[str, Any] = {}
    for name, keep in groups.items():
        names = sorted(n for n, r in index.items() if r.get("source") == "bandai" and keep(r))
        if not names:
            continue
        names = [names[i] for i in rng.choice(len(names), min(max_per_group, len(names)), replace=False)]
        clips = [np.load(data_dir / "new_joints" / f"{n}.npy") for n in names]
        if name.startswith("wave"):
            heights = [wrist_heights(j) for j in clips]
            out[name] = {k: _mean_std([h[k] for h in heights]) for k in heights[0]}
        elif name.startswith("turn"):
            out[name] = {"heading_change_deg": _mean_std([heading_change(j) for j in clips])}
        else:
            sc = [speed_and_cadence(j) for j in clips]
            out[name] = {
                "speed_mps": _mean_std([s for s, _ in sc]),
                "cadence_steps_per_s": _mean_std([c for _, c in sc]),
            }
    return out


def evaluate(
    gen: Any,
    data_dir: str | Path | None,
    max_clips: int = 64,
    seed: int = 0,
    stream: bool = True,
    steering_seeds: int = 4,
    split: str = "test",
) -> dict[str, Any]:
    """Every measurement of this module; a JSON-ready dict (held-out takes from `split`)."""
    t0 = time.perf_counter()
    results: dict[str, Any] = {"model": gen.name, "untrained": gen.untrained, "seed": seed, "split": split}
    generated: list[np.ndarray] = []
    if data_dir is not None:
        cases, real = heldout_cases(data_dir, max_clips, seed=seed, split=split)
        results["heldout"], joints = evaluate_routes(gen, cases, seed, stream=False)
        generated += joints
        results["real_foot_skating"] = float(np.mean([foot_skating_ratio(j) for j in real]))
        results["real_foot_skating_groups"] = {
            group: float(
                np.mean([foot_skating_ratio(j) for j, c in zip(real, cases, strict=True) if c.group == group])
            )
            for group in sorted({c.group for c in cases})
        }
        results["reference"] = real_reference(data_dir, seed=seed)
    synthetic = synthetic_cases(seed=seed)
    results["synthetic"], joints = evaluate_routes(gen, synthetic, seed, stream=stream)
    generated += joints
    results["foot_skating"] = float(np.mean([foot_skating_ratio(j) for j in generated]))
    results["steering"] = caption_steering(gen, steering_seeds, seed=seed)
    results["seconds"] = time.perf_counter() - t0
    return results


def _fmt_route(name: str, r: dict[str, Any]) -> str:
    if not r.get("clips"):
        return f"{name:<34}  (no clips)"
    return (
        f"{name:<34}{r['root_error_cm']:>9.1f}{r['location_error']:>10.3f}{r['trajectory_error']:>10.3f}"
        f"{r['max_miss_cm']:>10.1f}{r['clips']:>7d}{r['waypoints']:>6d}"
    )


def _cell(d: dict[str, Any] | None, key: str) -> str:
    if not d or key not in d:
        return f"{'-':>22}"
    return f"{d[key]['mean']:>14.2f} +- {d[key]['std']:<4.2f}"


def format_results(results: dict[str, Any]) -> str:
    """Plain-text tables of :func:`evaluate`'s results."""
    lines = [f"model: {results['model']}{' (UNTRAINED)' if results['untrained'] else ''}", ""]
    head = ("root cm", 9), ("loc err", 10), ("traj err", 10), ("max cm", 10), ("clips", 7), ("wps", 6)
    lines.append(f"{'route following':<34}" + "".join(f"{h:>{w}}" for h, w in head))
    for set_name in ("heldout", "synthetic"):
        if set_name not in results:
            continue
        r = results[set_name]
        lines.append(_fmt_route(f"{set_name}: final motion", r["final"]))
        lines.append(_fmt_route(f"{set_name}: controller only", r["controller_only"]))
        if "stream" in r:
            lines.append(_fmt_route(f"{set_name}: streamed", r["stream"]))
        for group, g in r["groups"].items():
            lines.append(_fmt_route(f"  {group}: final", g["final"]))
            lines.append(_fmt_route(f"  {group}: controller only", g["controller_only"]))
    lines.append("")
    skating = f"foot skating ratio: all generated {results['foot_skating']:.3f}"
    if "real_foot_skating" in results:
        skating += f", real {results.get('split', 'test')} takes {results['real_foot_skating']:.3f}"
    for set_name in ("heldout", "synthetic"):
        if "foot_skating" in results.get(set_name, {}):
            skating += f"; {set_name} {results[set_name]['foot_skating']:.3f}"
    if "stream_foot_skating" in results.get("synthetic", {}):
        skating += f", synthetic streamed {results['synthetic']['stream_foot_skating']:.3f}"
    for group, real in results.get("real_foot_skating_groups", {}).items():
        generated = results["heldout"]["groups"][group]["foot_skating"]
        skating += f"\n  held-out {group}: generated {generated:.3f}, the real takes {real:.3f}"
    lines += [skating, ""]
    ref, st = results.get("reference", {}), results["steering"]
    lines.append(f"{'caption steering':<34}{'generated':>22}{'real takes':>22}")

    def row(label: str, gen_key: str, ref_key: str, metric: str) -> None:
        lines.append(f"{label:<34}{_cell(st.get(gen_key), metric)}{_cell(ref.get(ref_key), metric)}")

    for pace in ("walk", "run"):
        for route in ("untimed_route", "no_route"):
            row(f"{pace} speed m/s ({route})", f"{pace}_{route}", pace, "speed_mps")
            row(f"{pace} cadence steps/s ({route})", f"{pace}_{route}", pace, "cadence_steps_per_s")
    row("run speed m/s (training phrasing)", "run_training_phrasing_untimed_route", "run", "speed_mps")
    for side in ("wave_right", "wave_left"):
        row(f"{side}: right-left wrist cm", side, side, "right_minus_left_cm")
    for side in ("turn_left", "turn_right"):
        row(f"{side}: heading change deg (no route)", side, side, "heading_change_deg")
    for style in STYLE_CAPTIONS:
        row(f"walk {style} speed m/s", f"walk_{style}", f"walk_{style}", "speed_mps")
    lines.append(f"\n({results['seconds']:.0f} s)")
    return "\n".join(lines)
