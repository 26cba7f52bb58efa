"""Caption recognition: does a generated clip show the action and style its caption names?
(``motion-env eval captions``; :func:`run_recognition`.)

For every (action, style) the classifier knows (:mod:`motion_env.models.classifier`), the
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
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.data.captions.bandai import captions_for_bandai
from motion_env.evaluation.captions import RUN_CAPTIONS, heldout_captions
from motion_env.evaluation.metrics import check_settings, heading_change, speed_and_cadence
from motion_env.models.classifier import classify, load_classifier
from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.training.classifier import LabelledClip, labelled_clips

__all__ = [
    "CAPTION_SETS",
    "RecognitionResult",
    "RecognitionSettings",
    "evaluate_recognition",
    "recognition_scores",
    "run_recognition",
]

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


def _caption_clips(
    gen: Any, cfg: Any, name: str, frames: dict[str, int], seeds: int, seed: int
) -> tuple[dict[tuple[str, str], list[np.ndarray]], dict[str, list[str]]]:
    """The clips of one caption set, keyed by (action, style), and the captions used per action."""
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
    return clips, texts_used


def _per_label(cfg: Any, pa: np.ndarray, ps: np.ndarray, a_true: list[int], s_true: list[int]) -> dict:
    """Accuracy per action and per style, and the action each named action is most often called."""
    a_true_arr, s_true_arr = np.array(a_true), np.array(s_true)
    calls = pa.argmax(1)
    return {
        "action": {a: float((calls[a_true_arr == i] == i).mean()) for i, a in enumerate(cfg.actions)},
        "style": {s: float((ps.argmax(1)[s_true_arr == i] == i).mean()) for i, s in enumerate(cfg.styles)},
        "most_often_called": {
            a: cfg.actions[int(np.bincount(calls[a_true_arr == i], minlength=len(cfg.actions)).argmax())]
            for i, a in enumerate(cfg.actions)
        },
    }


def _real_reference(real: list[LabelledClip]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The real takes' turn and wave measures, and their run speeds."""
    real_by_key: dict[tuple[str, str], list[np.ndarray]] = defaultdict(list)
    for c in real:
        real_by_key[(c.action, c.style or "")].append(c.joints)
    runs = [speed_and_cadence(c.joints)[0] for c in real if c.action == "run" and len(c.joints) > 25]
    return _specific(real_by_key), (_summary(runs) if runs else {})


def evaluate_recognition(
    gen: Any,
    model: Any,
    real: list[LabelledClip],
    seeds: int = 2,
    seed: int = 0,
    log: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """The table (real takes, template captions, other wordings, chance) and the specific measures.

    Args:
        gen: a :class:`~motion_env.generation.generator.MotionGenerator`.
        model: a trained :class:`~motion_env.models.classifier.MotionClassifier`.
        real: labelled held-out takes (their lengths set the clip length per action; they are
            also scored, as the "real held-out takes" row).
        seeds: clips per caption (template captions: one caption per seed, each different).
        seed: the base seed of the generator.
        log: called with a line per caption set as it is done (None: silent).
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
    per_label: dict[str, Any] = {}
    specific: dict[str, Any] = {}
    t0 = time.perf_counter()
    for name in CAPTION_SETS:
        clips, texts_used = _caption_clips(gen, cfg, name, frames, seeds, seed)
        keys = [k for k, js in clips.items() for _ in js]
        pa, ps = classify(model, [j for js in clips.values() for j in js])
        a_true, s_true = [a_index[a] for a, _ in keys], [s_index[s] for _, s in keys]
        row = (
            "generated, the project's own caption templates"
            if name == "templates"
            else "generated, other wordings"
        )
        table[row] = recognition_scores(pa, ps, a_true, s_true)
        per_label[name] = {**_per_label(cfg, pa, ps, a_true, s_true), "captions": texts_used}
        specific[name] = _specific(clips)
        if log is not None:
            log(
                f"{row}: action {table[row]['action']:.2f} style {table[row]['style']:.2f} "
                f"top-3 {table[row]['pair_top3']:.2f} ({len(keys)} clips, {time.perf_counter() - t0:.0f} s)"
            )
    table["chance"] = {
        "action": 1.0 / len(cfg.actions),
        "style": 1.0 / len(cfg.styles),
        "pair_top3": min(1.0, 3.0 / (len(cfg.actions) * len(cfg.styles))),
    }
    specific["real held-out takes"], real_runs = _real_reference(real)
    specific["runs_untimed_route"] = _run_speeds(gen, cfg.styles, seeds, seed, frames.get("run", 120))
    specific["runs_untimed_route"]["real held-out takes"] = real_runs
    return {
        "table": table,
        "per_label": per_label,
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


@dataclass
class RecognitionSettings:
    """What :func:`run_recognition` evaluates.

    Attributes:
        data: a dataset built by ``motion-env data build`` (``index.csv`` and the splits).
        split: the held-out split: "test" to report, "val" to choose between models.
        seeds: clips per (action, style) and caption set.
        seed: the generator's base seed and the choice of template captions.
        classifier: the classifier checkpoint that judges (None: the shipped one).
    """

    data: str | Path
    split: str = "test"
    seeds: int = 4
    seed: int = 0
    classifier: str | Path | None = None

    def __post_init__(self) -> None:
        check_settings(self, seeds=1, seed=0)


@dataclass
class RecognitionResult:
    """What :func:`run_recognition` measured.

    Attributes:
        table: per row (real held-out takes, templates, other wordings, chance) the scores of
            :func:`recognition_scores`.
        per_label: per caption set, accuracy per action and style, the action most often called,
            the captions used.
        specific: turn angles, one-hand waves and run speeds (module docstring).
        frames: clip length per action; actions, styles: the classifier's labels.
        split: the split of the real takes.
        classifier: the classifier's path ("shipped" for the default) and its training metrics.
        seconds: wall time of the evaluation (the loading of the models aside).
    """

    table: dict[str, Any]
    per_label: dict[str, Any]
    specific: dict[str, Any]
    frames: dict[str, int]
    actions: list[str]
    styles: list[str]
    split: str
    classifier: dict[str, Any]
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        """The results as JSON-ready data."""
        return asdict(self)

    def format(self) -> str:
        """The table as Markdown, then the turn, run and wave measures."""
        lines = [
            "| | action recognised | style recognised | right (action, style) among the top 3 | clips |",
            "|---|---|---|---|---|",
        ]
        for row, r in self.table.items():
            clips = r.get("clips", "")
            lines.append(f"| {row} | {r['action']:.2f} | {r['style']:.2f} | {r['pair_top3']:.2f} | {clips} |")
        lines.append("")
        for name in ("real held-out takes", *CAPTION_SETS):
            s = self.specific.get(name, {})
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
        for name, r in self.specific["runs_untimed_route"].items():
            if r:
                share = r.get(f"share_at_least_{RUN_SPEED}")
                tail = f", {share:.0%} >= {RUN_SPEED} m/s" if share is not None else ""
                lines.append(
                    f"run speed, {name}: {r['mean']:.2f} m/s ({r['min']:.2f} to {r['max']:.2f}){tail}"
                )
        return "\n".join(lines)


def run_recognition(
    gen: Any, settings: RecognitionSettings, log: Callable[[str], None] | None = None
) -> RecognitionResult:
    """Load the classifier and the labelled held-out takes, and run :func:`evaluate_recognition`.

    Args:
        gen: a :class:`~motion_env.generation.generator.MotionGenerator`.
        settings: the data, split, clips per caption, seed and classifier.
        log: called with a line per caption set as it is done (None: silent).
    """
    model, ckpt = load_classifier(settings.classifier)
    real = labelled_clips(settings.data, settings.split)
    t0 = time.perf_counter()
    results = evaluate_recognition(gen, model, real, settings.seeds, settings.seed, log=log)
    return RecognitionResult(
        **results,
        split=settings.split,
        classifier={"path": str(settings.classifier or "shipped"), "metrics": ckpt.get("metrics")},
        seconds=round(time.perf_counter() - t0, 1),
    )
