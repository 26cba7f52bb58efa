"""Does a clip with joint targets stay as smooth as the same clip without them?

For held-out takes of a split (:func:`motion_env.evaluation.control.control_cases`), the
generator makes each take's clip from its caption and start without targets, then again with the
same seed and targets taken from the real take (a wrist at 1 frame, the pelvis at 5 frames, the
head at 25 % of the frames, all six control joints at 2 keyframes). Per controlled clip: its
largest joint acceleration (second difference x fps^2) over that of the clip without targets.
Prints the 50th / 90th percentile and the largest ratio, the share of clips at most 1.25x, the
mean target error, the foot skating of the controlled clips and of the same seeds without targets
(the share of frames with a low foot sliding), and the seconds per controlled clip (with its
quiet-machine equivalent when ``../shared/tools/calib.py`` is there), and the same ratios apart
for the clips whose targets the path without targets already brings within reach
(:func:`~motion_env.generation.root_bending.within_reach`: the same sampled motion, refined) and
for those whose path is steered to the targets (a motion sampled anew on another path: the ratio
then compares two different motions). The steered ones are also compared with the same seed on
the route the targets imply (:func:`~motion_env.generation.root_bending.implied_route`) without
targets, the clip the refinement starts from: what the refinement itself adds.

Then walks under a beam (``HeightLimit`` on the head, 1.3 m, 60 frames, as
``motion-env eval control``'s objectives with a lower beam): foot skating (the share of frames
with a low foot sliding, ``docs/metrics.md``) against the same walk without the limit.

The refinement's settings can be changed with ``--set name=value``.

    python scripts/measure_refine_smoothness.py --data data/mocap --takes 24
    python scripts/measure_refine_smoothness.py --data data/mocap --takes 24 --split val
    python scripts/measure_refine_smoothness.py --data data/mocap --takes 6 --set spread=0
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import torch

import motion_env
from motion_env.evaluation.captions import WALK_CAPTIONS
from motion_env.evaluation.control import control_cases
from motion_env.evaluation.metrics import foot_skating_ratio
from motion_env.generation.root_bending import implied_route, within_reach
from motion_env.motion.skeleton import FPS, JOINT_INDEX
from motion_env.objectives import HeightLimit

SETTINGS = (
    (("right_wrist",), 1),
    (("pelvis",), 5),
    (("head",), 0.25),
    (("pelvis", "left_foot", "right_foot", "head", "left_wrist", "right_wrist"), 2),
)
BEAM = 1.3
"""Metres: the head's HeightLimit of the beam walks."""


def largest_acceleration(joints: np.ndarray) -> float:
    return float(np.abs(np.diff(joints, 2, axis=0)).max() * FPS**2)


def targets_of(
    joints: np.ndarray, names: tuple[str, ...], count: float, rng: np.random.Generator
) -> np.ndarray:
    """(T, 22, 3) targets: the real take's `names` joints at `count` frames (a share when < 1)."""
    t_len = len(joints)
    n = max(1, round(count * t_len)) if count < 1 else int(count)
    frames = np.sort(rng.choice(np.arange(1, t_len), n, replace=False))
    out = np.full((t_len, 22, 3), np.nan, np.float32)
    for name in names:
        out[frames, JOINT_INDEX[name]] = joints[frames, JOINT_INDEX[name]]
    return out


def _calibration():
    """calib.calibration_s and quiet_equivalent from ../shared/tools, or None when absent."""
    tools = Path(__file__).resolve().parents[2] / "shared" / "tools"
    if not (tools / "calib.py").exists():
        return None
    sys.path.insert(0, str(tools))
    import calib

    return calib


def _ratios(r: np.ndarray) -> str:
    if not len(r):
        return "none"
    return (
        f"p50 {np.percentile(r, 50):.2f}, p90 {np.percentile(r, 90):.2f}, max {r.max():.2f}, "
        f"share <= 1.25x {np.mean(r <= 1.25):.2f} ({len(r)} clips)"
    )


def beam_walks(gen, count: int) -> tuple[float, float, float, float]:
    """(skating under the beam, skating of the same walks without it, largest violation m,
    lowest foot height m in the limited frames) over `count` walks."""
    rng = np.random.default_rng(0)
    skate, free, worst, lowest = [], [], 0.0, np.inf
    route = np.array([[0.0, 3.0, 100], [0.0, 6.0, 190]], np.float32)
    for r in range(count):
        start = int(rng.integers(40, 80))
        limit = HeightLimit("head", max_height=BEAM, frames=(start, start + 60))
        text = WALK_CAPTIONS[r % len(WALK_CAPTIONS)]
        base = gen.generate(text, route, 200, seed=r).joints
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            made = gen.generate(text, route, 200, seed=r, objectives=[limit]).joints
        skate.append(foot_skating_ratio(made))
        free.append(foot_skating_ratio(base))
        worst = max(worst, float(limit.violation(made).max()))
        lowest = min(lowest, float(made[start : start + 60, [7, 8, 10, 11], 1].min()))
    return float(np.mean(skate)), float(np.mean(free)), worst, lowest


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True, help="HumanML3D-layout dataset (motion-env data build)")
    p.add_argument("--takes", type=int, default=6, help="held-out takes (default 6)")
    p.add_argument("--split", default="test", help="split the takes come from (default test; tune on val)")
    p.add_argument("--beams", type=int, default=8, help="walks under the beam (default 8; 0: none)")
    p.add_argument("--weights", default=None, help="generator weights (default: the shipped model)")
    p.add_argument("--set", action="append", default=[], help="RefineConfig field=value (repeatable)")
    p.add_argument("--per-clip", action="store_true", help="also print each controlled clip's ratio")
    args = p.parse_args()
    torch.set_num_threads(1)
    gen = motion_env.MotionGenerator.from_pretrained(args.weights)
    changes = {k: type(getattr(gen.refine_config, k))(v) for k, v in (s.split("=", 1) for s in args.set)}
    gen.refine_config = dataclasses.replace(gen.refine_config, **changes)
    calib = _calibration()
    rng = np.random.default_rng(0)
    ratios, errors, reach, seconds, quiet, skating, own = [], [], [], [], [], [], []
    for take in control_cases(args.data, args.takes, split=args.split):
        t_len = len(take.joints)
        free = gen.generate(take.text, num_frames=t_len, seed=0, start=take.start).joints
        path = free[:, 0, [0, 2]]
        for names, count in SETTINGS:
            targets = targets_of(take.joints, names, count, rng)
            c0 = calib.calibration_s() if calib else None
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # misses are measured below
                made = gen.generate(
                    take.text, num_frames=t_len, seed=0, start=take.start, joint_targets=targets
                )
            seconds.append(time.perf_counter() - t0)
            if calib:
                quiet.append(calib.quiet_equivalent(seconds[-1], (c0 + calib.calibration_s()) / 2))
            known = ~np.isnan(targets[..., 0])
            errors.append(float(np.linalg.norm(made.joints[known] - targets[known], axis=-1).mean()))
            ratios.append(largest_acceleration(made.joints) / largest_acceleration(free))
            skating.append((foot_skating_ratio(made.joints), foot_skating_ratio(free)))
            reach.append(within_reach(targets, path))
            if not reach[-1]:  # the same seed on the route the targets imply, without them
                routed = gen.generate(
                    take.text, implied_route(targets), t_len, seed=0, start=take.start
                ).joints
                own.append(largest_acceleration(made.joints) / largest_acceleration(routed))
            if args.per_clip:
                how = "within reach" if reach[-1] else f"steered; {own[-1]:.2f} against the route alone"
                print(
                    f"  {take.name[:44]:<44} {'+'.join(names) if len(names) < 6 else 'all six':<14} "
                    f"x{count:<5} ratio {ratios[-1]:.2f} ({how}), error {errors[-1] * 100:.2f} cm"
                )
    r, near = np.array(ratios), np.array(reach)
    speed = f"{np.mean(seconds):.2f} s per controlled clip"
    if quiet:
        speed += f" ({np.mean(quiet):.2f} s quiet-machine equivalent)"
    print(
        f"{gen.refine_config}\n{args.split} split, {len(r)} controlled clips: largest acceleration / "
        f"same seed without targets: {_ratios(r)}; mean target error {np.mean(errors) * 100:.2f} cm; "
        f"{speed}\n  foot skating {np.mean([s for s, _ in skating]):.3f}, the same seeds without targets "
        f"{np.mean([f for _, f in skating]):.3f}\n  targets within reach of the path without them "
        f"(same motion, refined): "
        f"{_ratios(r[near])}\n  path steered to the targets (a motion sampled anew): {_ratios(r[~near])}\n"
        f"    the same, against the same seed on the route the targets imply, without them (what the "
        f"refinement adds): {_ratios(np.array(own))}\n  all clips, each against the clip the refinement "
        f"starts from (without targets, on the same route): {_ratios(np.concatenate([r[near], own]))}"
    )
    if args.beams > 0:
        skate, free_skate, worst, lowest = beam_walks(gen, args.beams)
        print(
            f"{args.beams} walks under a {BEAM} m beam (head HeightLimit, 60 frames): foot skating "
            f"{skate:.3f}, the same walks without it {free_skate:.3f}; largest violation "
            f"{worst * 100:.2f} cm; lowest foot in the limit {lowest * 100:.1f} cm"
        )


if __name__ == "__main__":
    main()
