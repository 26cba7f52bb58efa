"""The evaluation suite of a generator (``python scripts/evaluate.py``): routes, skating, steering.

:func:`evaluate_generator` runs :mod:`.route_following` on held-out takes and synthetic routes and
:mod:`.steering` on new caption wordings, and :func:`format_results` prints the tables. The
numbers are defined in ``docs/metrics.md``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.evaluation.captions import STYLE_CAPTIONS
from motion_env.evaluation.metrics import foot_skating_ratio
from motion_env.evaluation.route_following import evaluate_routes, heldout_cases, synthetic_cases
from motion_env.evaluation.steering import caption_steering, real_reference

__all__ = ["evaluate_generator", "format_results"]


def evaluate_generator(
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
    """Plain-text tables of :func:`evaluate_generator`'s results."""
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
