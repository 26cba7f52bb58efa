"""How much the pelvis of a standing body sways: held-out takes of the actions done on the spot
(waves, raised hands, goodbyes) made again as ``motion-env eval natural`` makes them (the take's
caption, from its start, along its own root path), against the real takes.

Per clip, the 99th percentile of the pelvis's horizontal acceleration and of its vertical one (a
bob; m/s^2); the script prints the median and the 90th percentile over the clips of each side.
Whole clips by default, ``--stage streamed`` frame by frame as the environments emit them.

    python scripts/measure_standing_sway.py --data data/mocap --seeds 2
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from motion_env.evaluation.naturalness import make_again, naturalness_takes
from motion_env.generation.generator import MotionGenerator
from motion_env.motion.skeleton import FPS

STANDING = ("wave", "raise", "bye")  # the actions (label prefixes) done without travelling


def pelvis_sway(joints: np.ndarray) -> tuple[float, float]:
    """99th percentiles of the pelvis's horizontal and vertical acceleration (m/s^2) of (T, 22, 3)
    joints."""
    accel = np.diff(np.asarray(joints, np.float64)[:, 0], 2, axis=0) * FPS**2
    return (
        float(np.percentile(np.linalg.norm(accel[:, [0, 2]], axis=-1), 99)),
        float(np.percentile(np.abs(accel[:, 1]), 99)),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, help="HumanML3D-layout dataset (motion-env data build)")
    parser.add_argument("--split", default="test", help="held-out split (test or val)")
    parser.add_argument("--seeds", type=int, default=2, help="generator seeds per take (0 .. N-1)")
    parser.add_argument("--takes", type=int, default=7, help="takes per action")
    parser.add_argument("--stage", default="generated", choices=("generated", "streamed"))
    parser.add_argument("--weights", default=None, help="weights folder (default: the shipped model)")
    args = parser.parse_args()
    if args.seeds < 1 or args.takes < 1:
        parser.error(f"--seeds and --takes must be >= 1, got {args.seeds} and {args.takes}")
    torch.set_num_threads(1)
    gen = MotionGenerator.from_pretrained(args.weights)
    takes = naturalness_takes(args.data, args.split)
    made, real = [], []
    for action in sorted(a for a in takes if a.startswith(STANDING)):
        for take in takes[action][: args.takes]:
            real.append(pelvis_sway(take.joints))
            for seed in range(args.seeds):
                made.append(pelvis_sway(make_again(gen, take, seed, args.stage)))
    for name, values in (("made again", made), ("real takes", real)):
        for axis, column in (("horizontal", 0), ("vertical", 1)):
            v = np.asarray(values)[:, column]
            print(
                f"{name:<11} {len(v):4d} clips: pelvis {axis} acceleration p99, median "
                f"{np.median(v):.2f}, 90th percentile {np.percentile(v, 90):.2f} m/s^2"
            )


if __name__ == "__main__":
    main()
