"""Caption steering: does the body do what the caption says, in words the training never used?

Speed and cadence (steps/s, from foot contacts) for running vs walking captions on an untimed
route and without a route; right- vs left-wrist height for "waves with the right/left hand";
heading change for left- vs right-turn captions without a route; speed of "exhausted" /
"elderly" vs "active" walks. The same numbers on real takes of the dataset with those labels
(:func:`real_reference`) are the reference. Definitions in ``docs/metrics.md``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from motion_env.data.dataset import read_index
from motion_env.evaluation.captions import (
    RUN_CAPTIONS,
    RUN_CAPTIONS_TRAINING_PHRASING,
    STYLE_CAPTIONS,
    TURN_LEFT,
    TURN_RIGHT,
    WALK_CAPTIONS,
    WAVE_LEFT,
    WAVE_RIGHT,
)
from motion_env.evaluation.metrics import heading_change, speed_and_cadence, wrist_heights


def _mean_std(values: list[float]) -> dict[str, float]:
    arr = np.asarray(values, np.float64)
    return {"mean": float(arr.mean()), "std": float(arr.std()), "n": int(arr.size)}


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
    index = read_index(data_dir)
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
