"""The `motion-env` command line.

Each subcommand has a small `_add_<name>` function that declares its arguments and a `_run_<name>`
function that calls the library; the heavy modules are imported only by the command that needs
them, so `motion-env --help` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence


def _add_show(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("show", help="draw a motion (.npz or BVH) as a stick-figure video and a path plot")
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument("--out", default=None, help="video to write (.mp4 or .gif); default: FILE stem + .mp4")
    p.add_argument("--plot", default=None, help="also write a top-down plot of the root path (.png)")
    p.set_defaults(run=_run_show)


def _run_show(args: argparse.Namespace) -> int:
    raise NotImplementedError("motion-env show is being built (issue 2)")


def _add_data(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("data", help="build training datasets")
    dsub = p.add_subparsers(dest="data_command", required=True)
    b = dsub.add_parser("build", help="BVH folders -> a HumanML3D-layout dataset directory")
    b.add_argument("sources", nargs="+", help="folders searched recursively for .bvh / .bvh.gz files")
    b.add_argument("--out", required=True, help="output directory (must be empty or not exist)")
    b.set_defaults(run=_run_data_build)


def _run_data_build(args: argparse.Namespace) -> int:
    raise NotImplementedError("motion-env data build is being built (issue 2)")


def _add_train(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help="train one model of the generator")
    p.set_defaults(run=_run_train)


def _run_train(args: argparse.Namespace) -> int:
    raise NotImplementedError("motion-env train is being built (issue 3)")


def _add_generate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("generate", help="text + waypoints -> a motion (.npz) and a video")
    p.set_defaults(run=_run_generate)


def _run_generate(args: argparse.Namespace) -> int:
    raise NotImplementedError("motion-env generate is being built (issue 3)")


def _add_bench(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="latency and throughput of the generator and the environment")
    p.set_defaults(run=_run_bench)


def _run_bench(args: argparse.Namespace) -> int:
    raise NotImplementedError("motion-env bench is being built (issue 3)")


def _add_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help="MuJoCo physical-plausibility report for a motion")
    p.set_defaults(run=_run_replay)


def _run_replay(args: argparse.Namespace) -> int:
    raise NotImplementedError("motion-env replay is being built (issue 5)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="motion-env", description="Text- and path-controllable human motion as a Gymnasium env."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for add in (_add_show, _add_data, _add_train, _add_generate, _add_bench, _add_replay):
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.run(args) or 0)
    except (FileNotFoundError, ValueError) as exc:
        # User errors (bad file, bad argument) get one readable line, not a traceback.
        print(f"motion-env {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
