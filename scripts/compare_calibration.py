"""How steady is a quiet-machine equivalent? The bench's 200-frame clip timed repeatedly, each
repeat scaled two ways: by one calibration before and one after its runs (the bench before
session 30), and run by run by the calibrations on each run's two sides (``motion-env bench`` now:
:class:`motion_env.evaluation.bench.Calibration`). The two ways alternate, so they see the same
machine; the one whose equivalents vary less over the repeats is the one to trust under load.

    python scripts/compare_calibration.py --repeats 8
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from motion_env.evaluation.bench import calibrated, time_clip
from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=8, help="repeats of each way (default 8)")
    p.add_argument("--runs", type=int, default=10, help="clips per repeat (default 10)")
    p.add_argument("--weights", default=None, help="weights folder (default: shipped; 'random': untrained)")
    args = p.parse_args()
    for name in ("repeats", "runs"):
        if getattr(args, name) < 1:
            p.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    torch.set_num_threads(1)
    gen = MotionGenerator.from_pretrained(RANDOM_MODEL if args.weights == "random" else args.weights)
    time_clip(gen, runs=1, warmup=2)  # warm-up
    raw, around, beside = [], [], []
    for _ in range(args.repeats):
        # The bench's own clip timing, scaled both ways: a measure without a calibration keyword
        # gets the pair around it (the old way), time_clip itself one between runs.
        old = calibrated(lambda: time_clip(gen, args.runs, warmup=0))
        raw.append(old["median"])
        around.append(old["quiet"]["median"])
        beside.append(calibrated(time_clip, gen, args.runs, warmup=0)["quiet"]["median"])
    print(f"200-frame clip, median of {args.runs} runs, {args.repeats} repeats (ms):")
    for name, values in (
        ("raw (wall time)", raw),
        ("one calibration before and after", around),
        ("a calibration between runs", beside),
    ):
        v = np.asarray(values)
        print(
            f"  {name:<34} median {np.median(v):6.1f}  range {v.min():6.1f}-{v.max():6.1f}  "
            f"coefficient of variation {100 * v.std() / v.mean():4.1f} %"
        )


if __name__ == "__main__":
    main()
