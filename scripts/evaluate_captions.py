#!/usr/bin/env python
"""Caption recognition (issue #11): generated clips judged by an action/style classifier of real takes.

python scripts/evaluate_captions.py --data data/mocap --json out/captions.json      # the shipped model
python scripts/evaluate_captions.py --data data/mocap --split val --model my_weights  # choosing models

For each (action, style) the classifier knows, clips from the project's caption templates and
from held-out new wordings (no waypoints; runs also on an untimed route); prints the table
(action / style recognised, right pair among the top 3, chance) and the turn, run and wave
measures. The same as `motion-env eval captions` (same options). Definitions in
motion_env/evaluation/recognition.py.
"""

from __future__ import annotations

import argparse
import sys

from motion_env.cli.common import CommandError
from motion_env.cli.evaluate import add_captions_options, check_captions_options


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_captions_options(parser)
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    args = parser.parse_args(argv)
    if args.threads < 1:
        parser.error(f"--threads must be >= 1, got {args.threads}")
    try:
        check_captions_options(args)
    except CommandError as exc:
        parser.error(str(exc))

    from motion_env.evaluation.recognition import run_captions

    run_captions(args, " ".join(["python scripts/evaluate_captions.py", *argv]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
