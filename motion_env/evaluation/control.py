"""Joint control and objectives (``motion-env eval control``; :func:`run_control`).

The OmniControl protocol on our held-out takes (definitions in ``docs/metrics.md``, "Joint
control"): targets are the real take's own joints — pelvis, left foot, right foot, head, left
wrist, right wrist (the feet are the toe joints, OmniControl's) — one joint at a time at 1 frame,
5 frames, 25 % of the frames and every frame, plus all six joints at 2 keyframes. The character
starts where the take starts; the caption is the take's, in words the training captions never
use; there is no route (the targets alone say where to go). Per setting: mean error (cm), the
share of targets and of clips missed by more than 50 cm, foot skating against the real takes,
the largest per-frame joint jump against the real take's, the largest bone-length change, and
seconds per clip. The objectives run on synthetic cases (:func:`objective_cases`).
:func:`run_control` runs both on a generator with :class:`ControlSettings` and returns a
:class:`ControlResult`; the refinement settings are the generator's (``gen.refine_config``).
"""

from __future__ import annotations

import dataclasses
import os
import platform
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.data.dataset import read_index
from motion_env.evaluation.captions import WALK_CAPTIONS, WAVE_RIGHT, heldout_caption
from motion_env.evaluation.metrics import MISS, check_settings, foot_skating_ratio
from motion_env.motion.kinematics import bone_lengths
from motion_env.motion.skeleton import BONE_LENGTHS, FOOT_JOINTS, JOINT_INDEX
from motion_env.motion.trajectory import root_path_from_joints

__all__ = [
    "CONTROL_HEAD",
    "CONTROL_JOINTS",
    "DENSITIES",
    "ControlResult",
    "ControlSettings",
    "control_cases",
    "evaluate_control",
    "evaluate_objectives",
    "objective_cases",
    "off_the_floor",
    "run_control",
]

CONTROL_JOINTS = ("pelvis", "left_foot", "right_foot", "head", "left_wrist", "right_wrist")
DENSITIES = ("1 frame", "5 frames", "25 %", "all frames")
MAX_FRAMES = 200  # takes are cut to 10 s: the speed target is per 200-frame clip
OFF_FLOOR = (0.3, 10)
"""A take whose lowest foot joint is over 0.3 m above the floor for at least 10 frames (0.5 s) is
off the floor (climbing, hanging from a bar): its targets ask for a body held up by something the
generator does not have, so the overall error is also given without such takes."""


@dataclass
class Take:
    """A held-out take: its real joints (T, 22, 3), caption and start (x, z, heading)."""

    name: str
    text: str
    joints: np.ndarray
    start: np.ndarray


def control_cases(
    data_dir: str | Path, max_clips: int = 10, split: str = "test", seed: int = 0
) -> list[Take]:
    """Up to `max_clips` takes of `split` with at least 60 frames, cut to MAX_FRAMES (random, seeded)."""
    from motion_env.data.dataset import read_split

    data_dir = Path(data_dir)
    index = read_index(data_dir)
    clips = [c for c in read_split(data_dir, split) if len(c.joints) >= 60 and ":" not in c.name]
    rng = np.random.default_rng(seed)
    if len(clips) > max_clips:
        clips = [clips[i] for i in sorted(rng.choice(len(clips), max_clips, replace=False))]
    takes = []
    for clip in clips:
        joints = np.asarray(clip.joints[:MAX_FRAMES], np.float32)
        row = index.get(clip.name, {})
        text = heldout_caption(row.get("label", ""), row.get("style", ""), clip.captions[0])
        takes.append(Take(clip.name, text, joints, root_path_from_joints(joints)[0].copy()))
    return takes


def _frames(density: str, num_frames: int, rng: np.random.Generator) -> np.ndarray:
    if density == "all frames":
        return np.arange(num_frames)
    count = {"1 frame": 1, "5 frames": 5, "2 keyframes": 2}.get(density) or max(1, round(0.25 * num_frames))
    return np.sort(rng.choice(np.arange(1, num_frames), count, replace=False))


def settings() -> list[tuple[str, tuple[str, ...], str]]:
    """(name, joints, density) of every setting: each joint at each density, then all six at 2 keyframes."""
    out = [(f"{j} / {d}", (j,), d) for d in DENSITIES for j in CONTROL_JOINTS]
    return out + [("all six / 2 keyframes", CONTROL_JOINTS, "2 keyframes")]


def off_the_floor(joints: np.ndarray) -> bool:
    """Whether a take's body is held up off the floor (:data:`OFF_FLOOR`): (T, 22, 3) joints."""
    height, frames = OFF_FLOOR
    up = np.asarray(joints)[:, list(FOOT_JOINTS), 1].min(axis=1) > height
    return bool(len(up) >= frames and np.convolve(up, np.ones(frames, int), "valid").max() >= frames)


def _max_jump(joints: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(joints, axis=0), axis=-1).max()) if len(joints) > 1 else 0.0


def _bone_change(joints: np.ndarray) -> float:
    """Largest relative change of a bone's length from the canonical one, over frames (%)."""
    lengths = bone_lengths(joints)[:, 1:]
    return float(np.abs(lengths / BONE_LENGTHS[1:] - 1).max() * 100)


@dataclass
class _Row:
    errors: list[np.ndarray] = field(default_factory=list)
    skate: list[float] = field(default_factory=list)
    real_skate: list[float] = field(default_factory=list)
    jump_ratio: list[float] = field(default_factory=list)
    jump: list[float] = field(default_factory=list)
    real_jump: list[float] = field(default_factory=list)
    bones: list[float] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        flat = np.concatenate(self.errors) if self.errors else np.zeros(0)
        real = float(np.mean(self.real_skate))
        return {
            "clips": len(self.seconds),
            "targets": int(flat.size),
            "mean_error_cm": float(flat.mean() * 100) if flat.size else 0.0,
            "max_error_cm": float(flat.max() * 100) if flat.size else 0.0,
            "target_miss_rate": float((flat > MISS).mean()) if flat.size else 0.0,
            "clip_miss_rate": float(np.mean([e.max(initial=0.0) > MISS for e in self.errors])),
            "foot_skating": float(np.mean(self.skate)),
            "real_foot_skating": real,
            "skating_ratio": float(np.mean(self.skate)) / real if real > 0 else float("nan"),
            "max_jump_ratio": float(np.max(self.jump_ratio)),
            "mean_jump_ratio": float(np.mean(self.jump_ratio)),
            "clips_jump_over_1_25": float(np.mean(np.array(self.jump_ratio) > 1.25)),
            "max_jump_cm": float(np.max(self.jump) * 100),
            "real_max_jump_cm": float(np.max(self.real_jump) * 100),
            "max_bone_change_pct": float(np.max(self.bones)),
            "seconds_per_clip": float(np.mean(self.seconds)),
            "max_seconds_per_clip": float(np.max(self.seconds)),
        }


def evaluate_control(gen: Any, takes: list[Take], seed: int = 0, log: Any = None) -> dict[str, Any]:
    """Every setting of :func:`settings` on every take; per setting the numbers of the module docstring.

    The "no targets" row generates the same takes without targets (the generator's own skating
    and jumps on these captions, for comparison).
    """
    rng = np.random.default_rng(seed)
    results: dict[str, Any] = {"settings": {}}
    baseline = _Row()
    gen.generate(takes[0].text, num_frames=20, seed=seed)  # warm-up: the text encoder loads
    for take in takes:
        t0 = time.perf_counter()
        m = gen.generate(take.text, num_frames=len(take.joints), seed=seed, start=take.start)
        _record(baseline, m.joints, take, np.zeros(0), time.perf_counter() - t0)
    results["no targets"] = baseline.summary()
    if log is not None:
        log(_fmt_row("no targets", results["no targets"]))
    on_floor = [not off_the_floor(take.joints) for take in takes]
    setting_rows = []
    for name, joint_names, density in settings():
        row = _Row()
        setting_rows.append(row)
        for take in takes:
            t_len = len(take.joints)
            targets = np.full((t_len, 22, 3), np.nan, np.float32)
            frames = _frames(density, t_len, rng)
            for j in joint_names:
                targets[frames, JOINT_INDEX[j]] = take.joints[frames, JOINT_INDEX[j]]
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # misses are measured below
                m = gen.generate(
                    take.text, num_frames=t_len, seed=seed, start=take.start, joint_targets=targets
                )
            seconds = time.perf_counter() - t0
            known = ~np.isnan(targets[..., 0])
            errors = np.linalg.norm(m.joints[known] - targets[known], axis=-1)
            _record(row, m.joints, take, errors, seconds)
        results["settings"][name] = row.summary()
        if log is not None:
            log(_fmt_row(name, results["settings"][name]))
    flat_mean = np.average(
        [r["mean_error_cm"] for r in results["settings"].values()],
        weights=[r["targets"] for r in results["settings"].values()],
    )
    results["overall"] = {
        "mean_error_cm": float(flat_mean),
        "mean_of_settings_cm": float(np.mean([r["mean_error_cm"] for r in results["settings"].values()])),
        "worst_setting_cm": float(max(r["mean_error_cm"] for r in results["settings"].values())),
        "target_miss_rate": float(max(r["target_miss_rate"] for r in results["settings"].values())),
        "max_jump_ratio": float(max(r["max_jump_ratio"] for r in results["settings"].values())),
        "max_skating_ratio": float(max(r["skating_ratio"] for r in results["settings"].values())),
        "max_bone_change_pct": float(max(r["max_bone_change_pct"] for r in results["settings"].values())),
        "max_seconds_per_clip": float(max(r["max_seconds_per_clip"] for r in results["settings"].values())),
        "takes_off_the_floor": [t.name for t, floor in zip(takes, on_floor) if not floor],
    }
    # The same errors without the takes off the floor: per setting, then over all their targets.
    kept = [[e for e, floor in zip(row.errors, on_floor) if floor] for row in setting_rows]
    per_setting = [np.concatenate(e) if e else np.zeros(0) for e in kept]
    flat = np.concatenate(per_setting) if per_setting else np.zeros(0)
    results["overall"]["on_the_floor_mean_error_cm"] = float(flat.mean() * 100) if flat.size else 0.0
    results["overall"]["on_the_floor_worst_setting_cm"] = float(
        max((e.mean() * 100 for e in per_setting if e.size), default=0.0)
    )
    return results


def _record(row: _Row, joints: np.ndarray, take: Take, errors: np.ndarray, seconds: float) -> None:
    row.errors.append(errors)
    row.skate.append(foot_skating_ratio(joints))
    row.real_skate.append(foot_skating_ratio(take.joints))
    row.jump_ratio.append(_max_jump(joints) / max(_max_jump(take.joints), 1e-6))
    row.jump.append(_max_jump(joints))
    row.real_jump.append(_max_jump(take.joints))
    row.bones.append(_bone_change(joints))
    row.seconds.append(seconds)


# ----------------------------------------------------------------------------------------------
# Objectives
# ----------------------------------------------------------------------------------------------


@dataclass
class ObjectiveCase:
    """A caption, a route and objectives; what to check."""

    name: str
    kind: str
    text: str
    waypoints: np.ndarray | None
    objectives: list
    num_frames: int = 200


def objective_cases(repeats: int = 4, seed: int = 0) -> list[ObjectiveCase]:
    """KeepOut on a straight route through the circle; HeightLimit on the head (a beam) while walking
    or standing; StayInside a square with a route that ends outside it; a user callable."""
    from motion_env.objectives import HeightLimit, KeepOut, StayInside

    rng = np.random.default_rng(seed)
    cases = []
    for r in range(repeats):
        text = WALK_CAPTIONS[r % len(WALK_CAPTIONS)]
        length = float(rng.uniform(5.0, 7.0))
        side = float(rng.uniform(-0.2, 0.2))
        radius = float(rng.uniform(0.4, 0.8))
        route = np.array([[0.0, length / 2, 80], [0.0, length, 170]], np.float32)
        cases.append(
            ObjectiveCase(
                f"keepout-{r}", "KeepOut", text, route, [KeepOut(center=(side, length / 2), radius=radius)]
            )
        )
        beam = float(rng.uniform(1.35, 1.5))
        start = int(rng.integers(40, 80))
        cases.append(
            ObjectiveCase(
                f"height-{r}", "HeightLimit", text, np.array([[0.0, 3.0, 100], [0.0, 6.0, 190]], np.float32),
                [HeightLimit("head", max_height=beam, frames=(start, start + 60))],
            )
        )  # fmt: skip
        cases.append(
            ObjectiveCase(
                f"inside-{r}", "StayInside", text, np.array([[0.0, 6.0]], np.float32),
                [StayInside([(-1.5, -1.0), (1.5, -1.0), (1.5, 3.0), (-1.5, 3.0)])],
            )
        )  # fmt: skip
        cases.append(
            ObjectiveCase(
                f"callable-{r}", "callable", WAVE_RIGHT[0],
                None, [_right_hand_high],
            )
        )  # fmt: skip
    return cases


def _right_hand_high(joints: Any) -> Any:
    """A user objective: the right wrist at least 30 cm above the head (a raised hand), every frame."""
    return (joints[:, 15, 1] + 0.3 - joints[:, 21, 1]).clamp_min(0.0).pow(2).sum()


def evaluate_objectives(gen: Any, cases: list[ObjectiveCase], seed: int = 0) -> dict[str, Any]:
    """Per kind of objective: the largest violation (cm) and the share of clips where it holds (within
    5 mm; the callable: its violation, how far the right wrist stays under the goal), the route
    finished (the pelvis within 50 cm of the last waypoint at the end), foot skating and
    jumps against the same case without the objective, and seconds per clip."""
    out: dict[str, Any] = {}
    for kind in sorted({c.kind for c in cases}):
        viol, held, finished, skate, skate0, jump, jump0, low_feet, seconds = ([] for _ in range(9))
        for case in (c for c in cases if c.kind == kind):
            base = gen.generate(case.text, case.waypoints, case.num_frames, seed=seed)
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                m = gen.generate(
                    case.text, case.waypoints, case.num_frames, seed=seed, objectives=case.objectives
                )
            seconds.append(time.perf_counter() - t0)
            j = m.joints
            obj = case.objectives[0]
            if kind == "callable":
                v = float(np.clip(j[:, 15, 1] + 0.3 - j[:, 21, 1], 0.0, None).max())
            else:
                v = float(obj.violation(j).max())
            viol.append(v * 100)
            held.append(v <= 0.005)
            if case.waypoints is not None and kind != "StayInside":
                finished.append(float(np.linalg.norm(j[-1, 0, [0, 2]] - case.waypoints[-1, :2])) < MISS)
            skate.append(foot_skating_ratio(j))
            skate0.append(foot_skating_ratio(base.joints))
            jump.append(_max_jump(j))
            jump0.append(_max_jump(base.joints))
            if kind == "HeightLimit":
                a, b = obj.frames
                low_feet.append(float(j[a:b, [7, 8, 10, 11], 1].min(axis=1).mean() * 100))
        out[kind] = {
            "clips": len(viol),
            "max_violation_cm": float(np.max(viol)),
            "held_rate": float(np.mean(held)),
            "route_finished_rate": float(np.mean(finished)) if finished else None,
            "foot_skating": float(np.mean(skate)),
            "foot_skating_without": float(np.mean(skate0)),
            "max_jump_m": float(np.max(jump)),
            "max_jump_without_m": float(np.max(jump0)),
            "lowest_foot_cm_in_limit": float(np.mean(low_feet)) if low_feet else None,
            "seconds_per_clip": float(np.mean(seconds)),
        }
    return out


# ----------------------------------------------------------------------------------------------
# Tables
# ----------------------------------------------------------------------------------------------

CONTROL_HEAD = (
    f"{'setting':<28}{'err cm':>8}{'miss>50':>9}{'clips>50':>9}{'skate':>7}{'real':>6}{'x real':>7}"
    f"{'jump x':>8}{'>1.25':>6}{'jump cm':>8}{'real':>6}{'bone %':>8}{'s/clip':>8}{'max s':>7}"
)


def _fmt_row(name: str, r: dict[str, Any]) -> str:
    return (
        f"{name:<28}{r['mean_error_cm']:>8.2f}{r['target_miss_rate']:>9.3f}{r['clip_miss_rate']:>9.3f}"
        f"{r['foot_skating']:>7.3f}{r['real_foot_skating']:>6.3f}{r['skating_ratio']:>7.2f}"
        f"{r['max_jump_ratio']:>8.2f}{r['clips_jump_over_1_25']:>6.2f}{r['max_jump_cm']:>8.1f}"
        f"{r['real_max_jump_cm']:>6.1f}{r['max_bone_change_pct']:>8.2f}{r['seconds_per_clip']:>8.2f}"
        f"{r['max_seconds_per_clip']:>7.2f}"
    )


OBJECTIVES_HEAD = (
    f"{'objective':<14}{'clips':>6}{'max viol cm':>12}{'held':>6}{'route done':>11}{'skate':>7}"
    f"{'without':>8}{'jump m':>8}{'without':>8}{'feet cm':>8}{'s/clip':>8}"
)


def _fmt_objective_row(kind: str, r: dict[str, Any]) -> str:
    done = "-" if r["route_finished_rate"] is None else f"{r['route_finished_rate']:.2f}"
    feet = "-" if r["lowest_foot_cm_in_limit"] is None else f"{r['lowest_foot_cm_in_limit']:.1f}"
    return (
        f"{kind:<14}{r['clips']:>6}{r['max_violation_cm']:>12.2f}{r['held_rate']:>6.2f}{done:>11}"
        f"{r['foot_skating']:>7.3f}{r['foot_skating_without']:>8.3f}{r['max_jump_m']:>8.3f}"
        f"{r['max_jump_without_m']:>8.3f}{feet:>8}{r['seconds_per_clip']:>8.2f}"
    )


@dataclass
class ControlSettings:
    """What :func:`run_control` evaluates.

    Attributes:
        data: a dataset built by ``motion-env data build`` (its held-out split).
        split: the held-out split: "test" to report, "val" to choose settings.
        max_clips: held-out takes per setting.
        objective_repeats: cases per objective (0 skips the objectives).
        seed: the choice of takes, the target frames and the generator's seed.
    """

    data: str | Path
    split: str = "test"
    max_clips: int = 10
    objective_repeats: int = 4
    seed: int = 0

    def __post_init__(self) -> None:
        check_settings(self, max_clips=1, objective_repeats=0, seed=0)


@dataclass
class ControlResult:
    """What :func:`run_control` measured (the numbers of the module docstring).

    Attributes:
        no_targets: the takes generated without targets (the generator's own skating and jumps).
        settings: per setting (``"pelvis / 1 frame"``, ...), its numbers.
        overall: errors over all targets and the worst of the settings.
        objectives: per kind of objective, its numbers (None: not run).
        refine: the generator's refinement settings.
        split, takes: the split and the names of its takes.
        machine: CPU, cores, torch threads and version, load average.
        seconds: wall time.
    """

    no_targets: dict[str, Any]
    settings: dict[str, dict[str, Any]]
    overall: dict[str, Any]
    objectives: dict[str, Any] | None
    refine: dict[str, Any]
    split: str
    takes: list[str]
    machine: dict[str, Any]
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        """The results as JSON-ready data (``"no targets"`` as :func:`evaluate_control` names it;
        no ``"objectives"`` when they were not run)."""
        out = dataclasses.asdict(self)
        out["no targets"] = out.pop("no_targets")
        if self.objectives is None:
            del out["objectives"]
        return out

    def format(self) -> str:
        """Plain-text tables: the takes without targets and a row per setting, the overall
        errors, then the objectives (when they were run)."""
        o = self.overall
        lines = [CONTROL_HEAD, _fmt_row("no targets", self.no_targets)]
        lines += [_fmt_row(name, r) for name, r in self.settings.items()]
        lines += [
            "",
            f"overall: mean error {o['mean_error_cm']:.2f} cm over all targets "
            f"({o['mean_of_settings_cm']:.2f} cm "
            f"mean of settings, worst setting {o['worst_setting_cm']:.2f} cm); largest share missed > 50 cm "
            f"{o['target_miss_rate']:.3f}; skating up to {o['max_skating_ratio']:.2f}x real; jumps up to "
            f"{o['max_jump_ratio']:.2f}x the real take's largest; "
            f"bones within {o['max_bone_change_pct']:.2f} %; "
            f"up to {o['max_seconds_per_clip']:.2f} s per clip",
        ]
        if o.get("takes_off_the_floor"):
            lines.append(
                f"without the {len(o['takes_off_the_floor'])} of {len(self.takes)} takes off the floor "
                f"({', '.join(o['takes_off_the_floor'])}: held up by what the generator does not have, "
                f"their targets above any reach): mean error {o['on_the_floor_mean_error_cm']:.2f} cm, "
                f"worst setting {o['on_the_floor_worst_setting_cm']:.2f} cm"
            )
        if self.objectives is not None:
            lines += ["", OBJECTIVES_HEAD]
            lines += [_fmt_objective_row(kind, r) for kind, r in self.objectives.items()]
        return "\n".join(lines)


def run_control(
    gen: Any, settings: ControlSettings, log: Callable[[str], None] | None = None
) -> ControlResult:
    """Joint control on held-out takes, then the objectives, with the generator's refinement.

    Args:
        gen: a :class:`~motion_env.generation.generator.MotionGenerator` (its ``refine_config``
            is used as it is).
        settings: the data, split, takes, objective cases and seed.
        log: called with each table row (:data:`CONTROL_HEAD` is its header) as it is measured.
    """
    import torch

    t0 = time.perf_counter()
    takes = control_cases(settings.data, settings.max_clips, settings.split, settings.seed)
    results = evaluate_control(gen, takes, settings.seed, log=log)
    objectives = None
    if settings.objective_repeats > 0:
        cases = objective_cases(settings.objective_repeats, settings.seed)
        objectives = evaluate_objectives(gen, cases, settings.seed)
    return ControlResult(
        no_targets=results["no targets"],
        settings=results["settings"],
        overall=results["overall"],
        objectives=objectives,
        refine=dataclasses.asdict(gen.refine_config),
        split=settings.split,
        takes=[t.name for t in takes],
        machine={
            "cpu": platform.processor() or platform.machine(),
            "cores": os.cpu_count(),
            "torch_threads": torch.get_num_threads(),
            "torch": torch.__version__,
            "load_average": list(os.getloadavg()),
        },
        seconds=time.perf_counter() - t0,
    )
