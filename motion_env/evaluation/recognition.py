"""Caption recognition: does a generated clip show the action and style its caption names?
(``python scripts/evaluate_captions.py``, ``motion-env eval captions``; issue #11.)

For every (action, style) the classifier knows (:mod:`motion_env.evaluation.classifier`), the
generator makes clips from two kinds of caption, with no waypoints: the project's own caption
templates (:func:`motion_env.data.captions.bandai.captions_for_bandai`, the training wording) and
held-out new wordings (:func:`motion_env.evaluation.captions.heldout_captions`: two sentence
frames, each with its own words, which no caption any model trains on uses; the clips of a pair
take them in turn). The classifier scores them, and the real held-out takes of the split, by:

- action recognised: the top action is the named one;
- style recognised: the top style is the named one;
- right pair in the top 3: the named (action, style) is among the three most likely pairs
  (p(action) * p(style));
- chance: 1 / actions, 1 / styles, 3 / (actions * styles).

Clip lengths follow the real takes: the median frames of the action's takes in the split (40 to
200). Also measured: the heading change of turn captions (no waypoints), the speed of run
captions on an untimed straight route, and the share of one-hand waves whose named wrist reaches
higher than the other.
"""

from __future__ import annotations

import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.data.captions.bandai import captions_for_bandai
from motion_env.evaluation.captions import RUN_CAPTIONS, heldout_captions
from motion_env.evaluation.classifier import LabelledClip, classify, labelled_clips, load_classifier
from motion_env.evaluation.metrics import heading_change, speed_and_cadence
from motion_env.motion.skeleton import JOINT_INDEX

__all__ = ["CAPTION_SETS", "evaluate_recognition", "format_recognition", "recognition_scores", "run_captions"]

CAPTION_SETS = ("templates", "other_wordings")
MIN_FRAMES, MAX_FRAMES = 40, 200
RUN_SPEED = 2.3  # m/s, the target for run wordings on an untimed route
TURN_RANGE = (60.0, 120.0)  # degrees the named way, the target for turns without waypoints
# An untimed straight route far enough that a run does not arrive (and slow down) within the clip.
UNTIMED_ROUTE = np.array([[0.0, 4.0 * k] for k in range(1, 11)], np.float32)


def recognition_scores(
    action_probs: np.ndarray,
    style_probs: np.ndarray,
    actions: list[int],
    styles: list[int],
) -> dict[str, float]:
    """Action / style accuracy and the right (action, style) among the top 3 pairs.

    Args:
        action_probs: (N, A); style_probs: (N, S).
        actions: N indices of the named actions; styles: N indices of the named styles (-1: none;
            such clips count for the action only).
    """
    act, sty = np.asarray(actions, int), np.asarray(styles, int)
    has = sty >= 0
    out: dict[str, float] = {"clips": int(len(act))}
    out["action"] = float((action_probs.argmax(1) == act).mean()) if len(act) else float("nan")
    out["style"] = float((style_probs.argmax(1)[has] == sty[has]).mean()) if has.any() else float("nan")
    if has.any():
        pairs = (action_probs[has][:, :, None] * style_probs[has][:, None, :]).reshape(int(has.sum()), -1)
        top3 = np.argsort(-pairs, axis=1)[:, :3]  # (N, 3) flat pair indices
        right = act[has] * style_probs.shape[1] + sty[has]
        out["pair_top3"] = float((top3 == right[:, None]).any(1).mean())
    else:
        out["pair_top3"] = float("nan")
    return out


def _named_wrist_highest(joints: np.ndarray, side: str) -> bool:
    other = "left" if side == "right" else "right"
    peak = {s: float(joints[:, JOINT_INDEX[f"{s}_wrist"], 1].max()) for s in (side, other)}
    return peak[side] > peak[other]


def _summary(values: list[float]) -> dict[str, float]:
    a = np.asarray(values, np.float64)
    return {"mean": float(a.mean()), "min": float(a.min()), "max": float(a.max()), "n": int(a.size)}


def _specific(clips: dict[tuple[str, str], list[np.ndarray]]) -> dict[str, Any]:
    """Turn angles and one-hand waves of clips keyed by (action, style)."""
    out: dict[str, Any] = {}
    for action, sign in (("walk-turn-left", 1.0), ("walk-turn-right", -1.0)):
        angles = [sign * heading_change(j) for (a, _), js in clips.items() if a == action for j in js]
        if angles:
            lo, hi = TURN_RANGE
            out[action] = {
                "turn_deg_named_way": _summary(angles),
                "share_60_120": float(np.mean([lo <= x <= hi for x in angles])),
            }
    for action, side in (("wave-left-hand", "left"), ("wave-right-hand", "right")):
        hits = [_named_wrist_highest(j, side) for (a, _), js in clips.items() if a == action for j in js]
        if hits:
            out[action] = {"named_hand_highest": float(np.mean(hits)), "n": len(hits)}
    return out


def evaluate_recognition(
    gen: Any,
    model: Any,
    real: list[LabelledClip],
    seeds: int = 2,
    seed: int = 0,
    log: Any = print,
) -> dict[str, Any]:
    """The table (real takes, template captions, other wordings, chance) and the specific measures.

    Args:
        gen: a :class:`~motion_env.generation.generator.MotionGenerator`.
        model: a trained :class:`~motion_env.evaluation.classifier.MotionClassifier`.
        real: labelled held-out takes (their lengths set the clip length per action; they are
            also scored, as the "real held-out takes" row).
        seeds: clips per caption (template captions: one caption per seed, each different).
        seed: the base seed of the generator.
    """
    cfg = model.config
    a_index = {a: i for i, a in enumerate(cfg.actions)}
    s_index = {s: i for i, s in enumerate(cfg.styles)}
    real = [c for c in real if c.action in a_index]
    lengths: dict[str, list[int]] = defaultdict(list)
    for c in real:
        lengths[c.action].append(len(c.joints))
    frames = {
        a: int(np.clip(np.median(lengths[a]) if lengths[a] else 120, MIN_FRAMES, MAX_FRAMES))
        for a in cfg.actions
    }
    pa, ps = classify(model, [c.joints for c in real])
    sty = [s_index.get(c.style, -1) if c.style else -1 for c in real]
    table: dict[str, Any] = {
        "real held-out takes": recognition_scores(pa, ps, [a_index[c.action] for c in real], sty)
    }
    per_action: dict[str, Any] = {}
    specific: dict[str, Any] = {}
    t0 = time.perf_counter()
    for name in CAPTION_SETS:
        clips: dict[tuple[str, str], list[np.ndarray]] = {}
        texts_used: dict[str, list[str]] = {}
        for action in cfg.actions:
            texts, keys = [], []
            for style in cfg.styles:
                if name == "templates":
                    batch = captions_for_bandai(action, style, n=seeds, seed=seed)[:seeds]
                else:
                    batch = _cycle(heldout_captions(action, style), seeds)
                texts += batch
                keys += [(action, style)] * len(batch)
            texts_used[action] = sorted(set(texts))
            motions = gen.generate_batch(texts, None, frames[action], seed)
            for key, m in zip(keys, motions, strict=True):
                clips.setdefault(key, []).append(m.joints)
        keys = [k for k, js in clips.items() for _ in js]
        pa, ps = classify(model, [j for js in clips.values() for j in js])
        a_true = [a_index[a] for a, _ in keys]
        s_true = [s_index[s] for _, s in keys]
        row = (
            "generated, the project's own caption templates"
            if name == "templates"
            else "generated, other wordings"
        )
        table[row] = recognition_scores(pa, ps, a_true, s_true)
        per_action[name] = {
            "action": {
                a: float((pa.argmax(1)[np.array(a_true) == i] == i).mean()) for a, i in a_index.items()
            },
            "style": {
                s: float((ps.argmax(1)[np.array(s_true) == i] == i).mean()) for s, i in s_index.items()
            },
            "most_often_called": {
                a: cfg.actions[
                    int(np.bincount(pa.argmax(1)[np.array(a_true) == i], minlength=len(a_index)).argmax())
                ]
                for a, i in a_index.items()
            },
            "captions": texts_used,
        }
        specific[name] = _specific(clips)
        log(
            f"{row}: action {table[row]['action']:.2f} style {table[row]['style']:.2f} "
            f"top-3 {table[row]['pair_top3']:.2f} ({len(keys)} clips, {time.perf_counter() - t0:.0f} s)"
        )
    table["chance"] = {
        "action": 1.0 / len(cfg.actions),
        "style": 1.0 / len(cfg.styles),
        "pair_top3": min(1.0, 3.0 / (len(cfg.actions) * len(cfg.styles))),
    }
    real_by_key: dict[tuple[str, str], list[np.ndarray]] = defaultdict(list)
    for c in real:
        real_by_key[(c.action, c.style or "")].append(c.joints)
    specific["real held-out takes"] = _specific(real_by_key)
    specific["runs_untimed_route"] = _run_speeds(gen, cfg.styles, seeds, seed, frames.get("run", 120))
    specific["runs_untimed_route"]["real held-out takes"] = (
        _summary([speed_and_cadence(c.joints)[0] for c in real if c.action == "run" and len(c.joints) > 25])
        if any(c.action == "run" and len(c.joints) > 25 for c in real)
        else {}
    )
    return {
        "table": table,
        "per_label": per_action,
        "specific": specific,
        "frames": frames,
        "actions": list(cfg.actions),
        "styles": list(cfg.styles),
    }


def _cycle(items: list[str], n: int) -> list[str]:
    return [items[k % len(items)] for k in range(n)]


def _run_speeds(gen: Any, styles: tuple[str, ...], seeds: int, seed: int, frames: int) -> dict[str, Any]:
    """Speed (m/s, after the first second) of run captions on an untimed straight route."""
    sets = {
        "templates": [c for s in styles for c in captions_for_bandai("run", s, n=seeds, seed=seed)[:seeds]],
        "other_wordings": [w for s in styles for w in _cycle(heldout_captions("run", s), seeds)]
        + [c for c in RUN_CAPTIONS for _ in range(seeds)],
    }
    out: dict[str, Any] = {}
    frames = max(frames, 100)  # at least 4 s of running after the first second
    for name, texts in sets.items():
        motions = gen.generate_batch(texts, UNTIMED_ROUTE, frames, seed)
        speeds = [speed_and_cadence(m.joints)[0] for m in motions]
        out[name] = {
            **_summary(speeds),
            f"share_at_least_{RUN_SPEED}": float(np.mean(np.array(speeds) >= RUN_SPEED)),
        }
    return out


def format_recognition(results: dict[str, Any]) -> str:
    """The table as Markdown, then the turn, run and wave measures."""
    lines = [
        "| | action recognised | style recognised | right (action, style) among the top 3 | clips |",
        "|---|---|---|---|---|",
    ]
    for row, r in results["table"].items():
        clips = r.get("clips", "")
        lines.append(f"| {row} | {r['action']:.2f} | {r['style']:.2f} | {r['pair_top3']:.2f} | {clips} |")
    spec = results["specific"]
    lines.append("")
    for name in ("real held-out takes", *CAPTION_SETS):
        s = spec.get(name, {})
        parts = []
        for action in ("walk-turn-left", "walk-turn-right"):
            if action in s:
                t = s[action]["turn_deg_named_way"]
                parts.append(
                    f"{action} {t['mean']:.0f} deg ({t['min']:.0f} to {t['max']:.0f}; "
                    f"{s[action]['share_60_120']:.0%} in 60-120)"
                )
        for action in ("wave-left-hand", "wave-right-hand"):
            if action in s:
                parts.append(f"{action}: named hand highest {s[action]['named_hand_highest']:.0%}")
        lines.append(f"{name}: " + "; ".join(parts))
    runs = spec["runs_untimed_route"]
    for name, r in runs.items():
        if r:
            share = r.get(f"share_at_least_{RUN_SPEED}")
            tail = f", {share:.0%} >= {RUN_SPEED} m/s" if share is not None else ""
            lines.append(f"run speed, {name}: {r['mean']:.2f} m/s ({r['min']:.2f} to {r['max']:.2f}){tail}")
    return "\n".join(lines)


def run_captions(args: Any, command: str) -> dict[str, Any]:
    """Load the classifier and the generator, run :func:`evaluate_recognition`, print, write JSON."""
    import torch

    from motion_env.args import write_json
    from motion_env.generation.generator import MotionGenerator

    torch.set_num_threads(args.threads)
    model, ckpt = load_classifier(args.classifier)
    real = labelled_clips(args.data, args.split)
    gen = MotionGenerator.from_pretrained(args.model, caption_reader=args.caption_reader)
    t0 = time.perf_counter()
    results = evaluate_recognition(
        gen, model, real, args.seeds, args.seed, log=lambda s: print(s, flush=True)
    )
    results.update(
        command=command,
        split=args.split,
        classifier={"path": str(args.classifier or "shipped"), "metrics": ckpt.get("metrics")},
        caption_reader=args.caption_reader or "default",
        seconds=round(time.perf_counter() - t0, 1),
    )
    print()
    print(format_recognition(results))
    if args.json:
        write_json(Path(args.json), results)
    return results
