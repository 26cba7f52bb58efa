#!/usr/bin/env python
"""Train the action/style classifier that judges caption steering (motion_env.evaluation.classifier).

python scripts/train_classifier.py --data data/mocap     # writes motion_env/weights/classifier.pt
python scripts/train_classifier.py --data data/mocap --out out/classifier.pt --epochs 5

Trains on the train split's real takes (mirrors included), keeps the epoch best on val and
reports val and test accuracy (also stored in the checkpoint's ``metrics``). CPU, one thread:
a few minutes.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import torch

from motion_env.evaluation.classifier import (
    DEFAULT_CLASSIFIER,
    ClassifierConfig,
    TrainSettings,
    save_classifier,
    train_classifier,
)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--data", required=True, help="HumanML3D-layout dataset (motion-env data build)")
    parser.add_argument("--out", default=str(DEFAULT_CLASSIFIER), help="checkpoint to write")
    parser.add_argument("--epochs", type=int, default=TrainSettings.epochs)
    parser.add_argument("--width", type=int, default=ClassifierConfig.width)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    args = parser.parse_args(argv)
    if not (Path(args.data) / "index.csv").is_file():
        parser.error(f"--data {args.data}: no index.csv there (build one with motion-env data build)")
    if args.epochs < 1 or args.width < 1 or args.threads < 1:
        parser.error("--epochs, --width and --threads must be positive")
    torch.set_num_threads(args.threads)
    config = ClassifierConfig(actions=("a", "b"), styles=("a", "b"), width=args.width)
    model, metrics = train_classifier(args.data, config, TrainSettings(epochs=args.epochs, seed=args.seed))
    command = " ".join(["python scripts/train_classifier.py", *(argv if argv is not None else sys.argv[1:])])
    path = save_classifier(args.out, model, metrics=metrics, data=Path(args.data).name, command=command)
    print(json.dumps(metrics, indent=1))
    print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
