"""`motion-env eval control`: joint control and objectives on held-out takes (the evaluation of
:mod:`motion_env.evaluation.control`; ``scripts/evaluate_control.py`` is the same with the same
options). `motion-env eval captions`: does a generated clip show the action and style its caption
names, judged by a classifier of real takes (:mod:`motion_env.evaluation.recognition`;
``scripts/evaluate_captions.py``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from motion_env.cli.common import (
    CommandError,
    add_caption_reader,
    add_overwrite,
    add_threads,
    check_new_file,
    set_threads,
)

__all__ = ["add_captions_options", "add_control_options", "add_eval", "check_captions_options"]

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


_CAPTIONS_HELP = (
    "captions: action/style recognised by a classifier of real takes, template vs new wordings (issue #11)"
)


def add_captions_options(p: argparse.ArgumentParser) -> None:
    """The options of ``motion-env eval captions`` and ``scripts/evaluate_captions.py``."""
    p.add_argument("--data", required=True, help="HumanML3D-layout dataset (motion-env data build)")
    p.add_argument("--split", default="test", help="held-out split: test (to report) or val (to choose)")
    p.add_argument(
        "--seeds", type=int, default=4, help="clips per (action, style) and caption set (default 4)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--model", default=None, help="generator weights directory (default: the shipped model)")
    p.add_argument(
        "--classifier", default=None,
        help="classifier checkpoint (default: motion_env/weights/classifier.pt; scripts/train_classifier.py)",
    )  # fmt: skip
    add_caption_reader(p)
    p.add_argument("--json", default=None, help="also write the results to this JSON file")


def check_captions_options(args: argparse.Namespace) -> None:
    """Argument checks made before anything heavy loads (CommandError with the flag's name)."""
    if args.seeds < 1:
        raise CommandError(f"--seeds must be >= 1, got {args.seeds}")
    if not (Path(args.data) / "index.csv").is_file():
        raise CommandError(f"--data {args.data}: no index.csv there (build one with motion-env data build)")
    if not (Path(args.data) / f"{args.split}.txt").is_file():
        raise CommandError(f"--split {args.split}: no {args.split}.txt in {args.data}")
    if args.model is not None and not Path(args.model).is_dir():
        raise CommandError(f"--model {args.model}: no generator weights directory there")
    if args.classifier is not None and not Path(args.classifier).is_file():
        raise CommandError(f"--classifier {args.classifier}: no such file")


def add_eval(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="evaluations of the generator")
    esub = p.add_subparsers(dest="eval_command", required=True)
    c = esub.add_parser("control", help=_CONTROL_HELP, description=_CONTROL_HELP)
    add_control_options(c)
    add_threads(c)
    add_overwrite(c)
    c.set_defaults(run=run_eval_control)
    k = esub.add_parser("captions", help=_CAPTIONS_HELP, description=_CAPTIONS_HELP)
    add_captions_options(k)
    add_threads(k)
    add_overwrite(k)
    k.set_defaults(run=run_eval_captions)


def run_eval_control(args: argparse.Namespace) -> int:
    if args.json:
        check_new_file(args.json, args.overwrite, "--json")
    set_threads(args.threads)

    from motion_env.evaluation.control import run_control

    run_control(args, "motion-env eval control " + _echo(args))
    return 0


def run_eval_captions(args: argparse.Namespace) -> int:
    check_captions_options(args)
    if args.json:
        check_new_file(args.json, args.overwrite, "--json")
    set_threads(args.threads)

    from motion_env.evaluation.recognition import run_captions

    flags = ("data", "split", "seeds", "seed", "model", "classifier")
    echo = " ".join(f"--{k} {getattr(args, k)}" for k in flags if getattr(args, k) is not None)
    run_captions(args, "motion-env eval captions " + echo)
    return 0


def _echo(args: argparse.Namespace) -> str:
    flags = ("data", "split", "max_clips", "objective_repeats", "space", "steps", "seed", "model")
    return " ".join(
        f"--{k.replace('_', '-')} {getattr(args, k)}" for k in flags if getattr(args, k) is not None
    )
