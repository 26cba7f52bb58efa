"""How physically plausible are generated motions? Replay clips of the shipped model in MuJoCo.

Generates 5 captions x N seeds (10 s clips, timed routes where the caption travels) and prints
how many `motion_env.replay.evaluate` judges plausible and which checks fail.

    python scripts/replay_generated.py --seeds 4
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

import torch

from motion_env.cli.common import add_caption_reader
from motion_env.generation.generator import MotionGenerator
from motion_env.replay import evaluate

CASES = (
    ("a person walks forward", [[0, 3, 60], [0, 6, 120], [0, 9, 180]]),
    ("a person walks and turns left", [[0, 2, 40], [2, 4, 100], [4, 4, 160]]),
    ("a person runs", [[0, 6, 40], [0, 12, 80], [0, 18, 120]]),
    ("a person waves with the left hand", None),
    ("an elderly person walks slowly", [[0, 2, 60], [1, 4, 140]]),
)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    add_caption_reader(parser)
    parser.add_argument("--seeds", type=int, default=4, help="clips per caption")
    parser.add_argument("--json", default=None, help="also write the per-clip verdicts here")
    args = parser.parse_args()
    torch.set_num_threads(1)
    gen = MotionGenerator.from_pretrained(args.model, caption_reader=args.caption_reader)
    rows, fails = [], Counter()
    for text, waypoints in CASES:
        for seed in range(args.seeds):
            report = evaluate(gen.generate(text, waypoints=waypoints, num_frames=200, seed=seed))
            fails.update(report["failed"])
            rows.append(
                {"text": text, "seed": seed, "plausible": report["plausible"], "failed": report["failed"]}
            )
            print(f"{text:36s} seed {seed}: {'plausible' if report['plausible'] else report['failed']}")
    passed = sum(r["plausible"] for r in rows)
    print(f"plausible: {passed}/{len(rows)}; failed checks: {dict(fails)}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(
                {"plausible": passed, "clips": len(rows), "failed": dict(fails), "rows": rows}, f, indent=1
            )


if __name__ == "__main__":
    main()
