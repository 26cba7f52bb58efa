"""`motion-env eval control`: joint control and objectives on held-out takes (the evaluation of
:mod:`motion_env.evaluation.control`; ``scripts/evaluate_control.py`` is the same with the same
options)."""

from __future__ import annotations

import argparse

from motion_env.cli.common import add_overwrite, add_threads, check_new_file, set_threads

__all__ = ["add_control_options", "add_eval"]

_CONTROL_HELP = "joint targets and objectives: errors, skating, pops, bones, speed (docs/metrics.md)"


def add_control_options(p: argparse.ArgumentParser) -> None:
    """The options of ``motion-env eval control`` and ``scripts/evaluate_control.py``."""
    p.add_argument("--data", required=True, help="HumanML3D-layout dataset (motion-env data build)")
    p.add_argument("--split", default="test", help="held-out split: test (to report) or val (to choose)")
    p.add_argument("--max-clips", type=int, default=10, help="held-out takes per setting (default 10)")
    p.add_argument("--objective-repeats", type=int, default=4, help="cases per objective (0 skips them)")
    p.add_argument(
        "--space", choices=("latent", "logits", "none"), default=None,
        help="what the refinement optimises (default: the generator's RefineConfig)",
    )  # fmt: skip
    p.add_argument("--steps", type=int, default=None, help="refinement steps (default: the generator's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    p.add_argument("--json", default=None, help="also write the results to this JSON file")


def add_eval(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="evaluations of the generator")
    esub = p.add_subparsers(dest="eval_command", required=True)
    c = esub.add_parser("control", help=_CONTROL_HELP, description=_CONTROL_HELP)
    add_control_options(c)
    add_threads(c)
    add_overwrite(c)
    c.set_defaults(run=run_eval_control)


def run_eval_control(args: argparse.Namespace) -> int:
    if args.json:
        check_new_file(args.json, args.overwrite, "--json")
    set_threads(args.threads)

    from motion_env.evaluation.control import run_control

    run_control(args, "motion-env eval control " + _echo(args))
    return 0


def _echo(args: argparse.Namespace) -> str:
    flags = ("data", "split", "max_clips", "objective_repeats", "space", "steps", "seed", "model")
    return " ".join(
        f"--{k.replace('_', '-')} {getattr(args, k)}" for k in flags if getattr(args, k) is not None
    )
