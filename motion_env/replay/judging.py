"""What every replay report shares: failing frame ranges and their words, one check's entry, the
verdict, and the report as text.

:func:`motion_env.replay.evaluate` (the humanoid) and :func:`motion_env.replay.robot.evaluate_robot`
(a robot's ``qpos``) build their reports from these, so both have the same shape: ``plausible``,
``judged``, ``min_frames``, ``summary``, ``failed`` and, per check, ``value``, ``threshold``,
``unit``, ``passed``, ``frames``, ``worst_frame``, ``message``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Inclusive (first, last) frame ranges where `mask` (T,) is true."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), (np.flatnonzero(edges == -1) - 1).tolist()))


def span(ranges: list[tuple[int, int]], fps: float, limit: int = 4) -> str:
    """Frame ranges in words: 'frames 3-7 (0.15-0.40 s), frame 9 (0.45 s)' (at most `limit`)."""

    def one(a: int, b: int) -> str:
        if a == b:
            return f"frame {a} ({a / fps:.2f} s)"
        return f"frames {a}-{b} ({a / fps:.2f}-{(b + 1) / fps:.2f} s)"

    text = ", ".join(one(a, b) for a, b in ranges[:limit])
    return text + (f" and {len(ranges) - limit} more stretches" if len(ranges) > limit else "")


def sentence(what: str, allowed: str, worst: int, ranges: list, fps: float) -> str:
    """A check's message: what it found at its `worst` frame, what is `allowed`, and where it
    fails (`ranges` of frames, none when it passes)."""
    if not ranges:
        return f"fine: at worst (frame {worst}) {what}; allowed {allowed}"
    return f"{what} (allowed {allowed}) at {span(ranges, fps)}"


def check_entry(signal: np.ndarray, threshold: float, unit: str, message: Callable[[list], str]) -> dict:
    """One check of a report: the per-frame `signal` (T,) against `threshold`; `message(ranges)`
    words it, given the failing frame ranges."""
    ranges = runs(signal > threshold)
    return {
        "value": float(signal.max()) if len(signal) else 0.0,
        "threshold": float(threshold),
        "unit": unit,
        "passed": not ranges,
        "frames": [[a, b] for a, b in ranges],
        "worst_frame": int(np.argmax(signal)) if len(signal) else 0,
        "message": message(ranges),
    }


def verdict(checks: dict[str, dict], num_frames: int, need: int, fps: float) -> dict:
    """The verdict keys of a report from its `checks`: ``plausible``, ``judged``, ``min_frames``,
    ``summary``, ``failed``. A clip of fewer than `need` frames (the replay's
    :func:`~motion_env.replay.plausibility.min_frames`) is not judged."""
    failed = [n for n, c in checks.items() if not c["passed"]]
    judged = num_frames >= need
    problems = "; ".join(checks[n]["message"] for n in failed)
    if not judged:
        summary = f"too short to judge: {num_frames} frames, at least {need} needed ({need / fps:.1f} s)"
        summary += f"; failing even so: {problems}" if failed else ""
    else:
        summary = "not plausible: " + problems if failed else "plausible: every check passed"
    return {
        "plausible": (not failed) if judged else None,
        "judged": judged,
        "min_frames": need,
        "summary": summary,
        "failed": failed,
    }


def judge_checks(
    names: tuple[str, ...],
    signals: dict[str, np.ndarray],
    thresholds: dict[str, float],
    units: dict[str, str],
    fps: float,
    nothing_found: dict[str, str],
    findings: Callable[[str, int, float, float], tuple[str, str]],
) -> dict[str, dict]:
    """The ``checks`` of a report: :func:`check_entry` of each named signal, in the order of `names`.

    A check whose signal is 0 on every frame says ``nothing_found[name]`` where there is one;
    otherwise ``findings(name, worst, value, threshold)`` words what it found at its worst frame
    (``(what, allowed)``, made a :func:`sentence`).
    """

    def message(name: str, ranges: list) -> str:
        worst = int(np.argmax(signals[name]))
        value = float(signals[name][worst])
        if value == 0.0 and name in nothing_found:
            return nothing_found[name]
        what, allowed = findings(name, worst, value, thresholds[name])
        return sentence(what, allowed, worst, ranges, fps)

    return {
        name: check_entry(
            signals[name], thresholds[name], units[name], lambda ranges, name=name: message(name, ranges)
        )
        for name in names
    }


def report_head(checks: dict[str, dict], num_frames: int, fps: float, need: int, mass: float) -> dict:
    """The first keys of a report: the :func:`verdict`'s, then ``frames``, ``fps``,
    ``duration_s`` and ``mass_kg``."""
    return {
        **verdict(checks, num_frames, need, fps),
        "frames": num_frames,
        "fps": fps,
        "duration_s": num_frames / fps,
        "mass_kg": mass,
    }


def _verdict(result: dict) -> str:
    """The verdict line of :func:`format_report`."""
    failed = ", ".join(result["failed"])
    if not result.get("judged", True):
        need = result["min_frames"]
        return (
            f"verdict: CANNOT BE JUDGED (too short: {result['frames']} frames, at least {need} "
            f"needed, {need / result['fps']:.1f} s)" + (f"; failing even so: {failed}" if failed else "")
        )
    return "verdict: PLAUSIBLE" if result["plausible"] else f"verdict: NOT PLAUSIBLE (failed: {failed})"


def format_report(result: dict, title: str | None = None) -> str:
    """A report of :func:`~motion_env.replay.evaluate` (or of
    :func:`~motion_env.replay.robot.evaluate_robot`) as readable lines of text."""
    head = f"{title}: " if title else ""
    body = f"robot {result['robot']}" if "robot" in result else "humanoid"
    lines = [
        f"{head}{result['frames']} frames, {result['duration_s']:.2f} s at {result['fps']:g} fps, "
        f"{body} of {result['mass_kg']:g} kg"
        + (
            f" (resampled from {result['resampled_from_fps']:g} fps)"
            if "resampled_from_fps" in result
            else ""
        ),
        _verdict(result),
    ]
    if result.get("fit_error"):
        fit = result["fit_error"]
        lines.append(
            f"fit: the humanoid's joints are {fit['mean_cm']:.1f} cm from the motion's on "
            f"average (at most {fit['max_cm']:.1f} cm, {fit['worst_joint']})"
        )
    for name, c in result["checks"].items():
        mark = ("ok  " if result.get("judged", True) else "--  ") if c["passed"] else "FAIL"
        lines.append(f"  [{mark}] {name:<16} {c['message']}")
    if result.get("tracking"):
        lines.append(f"tracking (not part of the verdict): {result['tracking']['message']}")
    if result.get("video"):
        lines.append(f"video: {result['video']}")
    return "\n".join(lines)
