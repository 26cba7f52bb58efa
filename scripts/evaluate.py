#!/usr/bin/env python
"""Evaluate a generator: route following, foot skating, caption steering (motion_env/evaluation/suite.py).

python scripts/evaluate.py --data data/mocap --json out/eval.json            # the shipped model
python scripts/evaluate.py --data data/mocap --model runs/weights --max-clips 32
"""

from __future__ import annotations

import argparse
import sys

import torch

from motion_env.args import write_json
from motion_env.cli.common import add_caption_reader
from motion_env.evaluation.suite import evaluate_generator, format_results
from motion_env.generation.generator import MotionGenerator


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--data", default=None, help="HumanML3D-layout dataset (its test split); omit: synthetic only"
    )
    parser.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    add_caption_reader(parser)
    parser.add_argument("--random-model", action="store_true", help="evaluate tiny UNTRAINED random weights")
    parser.add_argument("--max-clips", type=int, default=64, help="held-out takes to evaluate")
    parser.add_argument("--split", default="test", help="held-out split: test (to report) or val (to choose)")
    parser.add_argument(
        "--steering-seeds", type=int, default=4, help="clips per caption for the steering numbers"
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-stream", action="store_true", help="skip the streaming evaluation")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--threads", type=int, default=None, help="torch CPU threads")
    parser.add_argument("--json", default=None, help="write the results here")
    args = parser.parse_args(argv)
    if args.threads is not None:
        torch.set_num_threads(args.threads)
    gen = MotionGenerator.from_pretrained(
        "random" if args.random_model else args.model, device=args.device, caption_reader=args.caption_reader
    )
    results = evaluate_generator(
        gen, args.data, max_clips=args.max_clips, seed=args.seed, stream=not args.no_stream,
        steering_seeds=args.steering_seeds, split=args.split,
    )  # fmt: skip
    results["command"] = " ".join(
        ["python", "scripts/evaluate.py", *(argv if argv is not None else sys.argv[1:])]
    )
    print(format_results(results))
    if args.json:
        write_json(args.json, results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
