#!/usr/bin/env python
"""Joint control and objectives of a generator (definitions in docs/metrics.md, "Joint control").

python scripts/evaluate_control.py --data data/mocap --json out/control.json        # the shipped model
python scripts/evaluate_control.py --data data/mocap --split val --space logits     # choosing settings

The same as `motion-env eval control` (same options).
"""

from __future__ import annotations

import argparse
import sys

from motion_env.cli.evaluate import add_control_options
from motion_env.evaluation.control import run_control


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_control_options(parser)
    parser.add_argument("--threads", type=int, default=1, help="torch CPU threads (default 1)")
    run_control(parser.parse_args(argv), " ".join(["python scripts/evaluate_control.py", *argv]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
