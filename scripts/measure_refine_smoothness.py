"""Does a clip with joint targets stay as smooth as the same clip without them?

For held-out takes of the test split (:func:`motion_env.evaluation.control.control_cases`), the
generator makes each take's clip from its caption and start without targets, then again with the
same seed and targets taken from the real take (a wrist at 1 frame, the pelvis at 5 frames, the
head at 25 % of the frames, all six control joints at 2 keyframes). Per controlled clip: its
largest joint acceleration (second difference x fps^2) over that of the clip without targets.
Prints the 50th / 90th percentile and the largest ratio, the share of clips at most 1.25x, and the
mean target error (the refinement's settings can be changed with ``--set name=value``).

    python scripts/measure_refine_smoothness.py --data data/mocap --takes 6
    python scripts/measure_refine_smoothness.py --data data/mocap --takes 6 --set spread=0
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

import numpy as np
import torch

import motion_env
from motion_env.evaluation.control import control_cases
from motion_env.motion.skeleton import FPS, JOINT_INDEX

SETTINGS = (
    (("right_wrist",), 1),
    (("pelvis",), 5),
    (("head",), 0.25),
    (("pelvis", "left_foot", "right_foot", "head", "left_wrist", "right_wrist"), 2),
)


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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", required=True, help="HumanML3D-layout dataset (motion-env data build)")
    p.add_argument("--takes", type=int, default=6, help="held-out takes (default 6)")
    p.add_argument("--weights", default=None, help="generator weights (default: the shipped model)")
    p.add_argument("--set", action="append", default=[], help="RefineConfig field=value (repeatable)")
    args = p.parse_args()
    torch.set_num_threads(1)
    gen = motion_env.MotionGenerator.from_pretrained(args.weights)
    changes = {k: type(getattr(gen.refine_config, k))(v) for k, v in (s.split("=", 1) for s in args.set)}
    gen.refine_config = dataclasses.replace(gen.refine_config, **changes)
    rng = np.random.default_rng(0)
    ratios, errors = [], []
    for take in control_cases(args.data, args.takes):
        t_len = len(take.joints)
        free = gen.generate(take.text, num_frames=t_len, seed=0, start=take.start).joints
        for names, count in SETTINGS:
            targets = targets_of(take.joints, names, count, rng)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # misses are measured below
                made = gen.generate(
                    take.text, num_frames=t_len, seed=0, start=take.start, joint_targets=targets
                )
            known = ~np.isnan(targets[..., 0])
            errors.append(float(np.linalg.norm(made.joints[known] - targets[known], axis=-1).mean()))
            ratios.append(largest_acceleration(made.joints) / largest_acceleration(free))
    r = np.array(ratios)
    print(
        f"{gen.refine_config}\n{len(r)} controlled clips: largest acceleration / same seed without targets: "
        f"p50 {np.percentile(r, 50):.2f}, p90 {np.percentile(r, 90):.2f}, max {r.max():.2f}, "
        f"share <= 1.25x {np.mean(r <= 1.25):.2f}; mean target error {np.mean(errors) * 100:.2f} cm"
    )


if __name__ == "__main__":
    main()
