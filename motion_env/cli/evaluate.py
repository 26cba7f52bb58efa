"""`motion-env eval`: evaluations of a generator on held-out takes of a built dataset.

- ``eval control``: joint control and objectives (:mod:`motion_env.evaluation.control`);
- ``eval captions``: does a generated clip show the action and style its caption names, judged by
  a classifier of real takes (:mod:`motion_env.evaluation.recognition`);
- ``eval natural``: how natural generated motion is next to the real takes, per action
  (:mod:`motion_env.evaluation.naturalness`).

Each command parses its options into the evaluation's settings dataclass, loads the generator,
calls the library, prints the tables and writes ``--json``; the library neither parses, prints nor
sets threads.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from motion_env.cli.common import (
    CommandError,
    add_caption_reader,
    add_overwrite,
    add_threads,
    add_weights,
    check_new_file,
    set_threads,
)

__all__ = ["add_eval"]

_CONTROL_HELP = "joint targets and objectives: errors, skating, pops, bones, speed (docs/metrics.md)"
_CAPTIONS_HELP = "captions: action/style recognised by a classifier of real takes, template vs new wordings"
_NATURAL_HELP = (
    "naturalness per action: replay plausibility, acceleration, jerk, pops, skating and classifier "
    "Fréchet distance of held-out takes made again, next to the real takes (docs/metrics.md)"
)
_DATA_HELP = "HumanML3D-layout dataset (motion-env data build)"
_SPLIT_HELP = "held-out split: test (to report) or val (to choose)"
_CLASSIFIER_HELP = (
    "classifier checkpoint (default: motion_env/weights/classifier.pt; motion-env train classifier)"
)


def _add_control_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--max-clips", type=int, default=10, help="held-out takes per setting (default 10)")
    p.add_argument("--objective-repeats", type=int, default=4, help="cases per objective (0 skips them)")
    p.add_argument(
        "--space", choices=("latent", "logits", "none"), default=None,
        help="what the refinement optimises (default: the generator's RefineConfig)",
    )  # fmt: skip
    p.add_argument("--steps", type=int, default=None, help="refinement steps (default: the generator's)")
    p.add_argument("--seed", type=int, default=0)
    add_weights(p)


def _add_captions_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--seeds", type=int, default=4, help="clips per (action, style) and caption set (default 4)"
    )
    p.add_argument("--seed", type=int, default=0)
    add_weights(p)
    p.add_argument("--classifier", default=None, help=_CLASSIFIER_HELP)
    add_caption_reader(p)


def _add_natural_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--per-action", type=int, default=7, help="takes made again per action (default 7)")
    p.add_argument("--seed", type=int, default=0, help="choice of takes, real halves, generator seed")
    p.add_argument(
        "--stage", choices=("generated", "streamed", "vqvae", "real-path"), default="generated",
        help="generated: the whole generator along the takes' paths; streamed: the same requests frame "
        "by frame, as the stream and the environments make them; vqvae: the real takes through the "
        "VQ-VAE alone, on their real root paths (what the tokenizer changes); real-path: the "
        "generator's tokens along the takes' real root paths, no path controller (what the GPT adds)",
    )  # fmt: skip
    add_weights(p)
    p.add_argument("--classifier", default=None, help=_CLASSIFIER_HELP)
    p.add_argument(
        "--actions", default=None, type=lambda text: tuple(a.strip() for a in text.split(",")),
        help="only these actions, comma-separated (e.g. run,walk): their rows are those of a run "
        "over every action; default every action with 3 takes or more",
    )  # fmt: skip
    add_caption_reader(p)


def _check_dataset(args: argparse.Namespace) -> None:
    """The dataset, split, weights and classifier named exist (CommandError naming the flag)."""
    if not (Path(args.data) / "index.csv").is_file():
        raise CommandError(f"--data {args.data}: no index.csv there (build one with motion-env data build)")
    if not (Path(args.data) / f"{args.split}.txt").is_file():
        raise CommandError(f"--split {args.split}: no {args.split}.txt in {args.data}")
    if args.model is not None and not Path(args.model).is_dir():
        raise CommandError(f"--model/--weights {args.model}: no generator weights directory there")
    if getattr(args, "classifier", None) is not None and not Path(args.classifier).is_file():
        raise CommandError(f"--classifier {args.classifier}: no such file")


def add_eval(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("eval", help="evaluations of the generator")
    esub = p.add_subparsers(dest="eval_command", required=True)
    for name, help_text, add_options, run in (
        ("control", _CONTROL_HELP, _add_control_options, run_eval_control),
        ("captions", _CAPTIONS_HELP, _add_captions_options, run_eval_captions),
        ("natural", _NATURAL_HELP, _add_natural_options, run_eval_natural),
    ):
        c = esub.add_parser(name, help=help_text, description=help_text)
        c.add_argument("--data", required=True, help=_DATA_HELP)
        c.add_argument("--split", default="test", help=_SPLIT_HELP)
        add_options(c)
        c.add_argument("--json", default=None, help="also write the results to this JSON file")
        add_threads(c)
        add_overwrite(c)
        c.set_defaults(run=run)


def _echo(args: argparse.Namespace, command: str, flags: tuple[str, ...]) -> str:
    """The command line that reproduces the results (recorded in the JSON)."""
    values = {k: getattr(args, k) for k in flags if getattr(args, k) is not None}
    given = (
        f"--{k.replace('_', '-')} {','.join(v) if isinstance(v, tuple) else v}" for k, v in values.items()
    )
    return " ".join([f"motion-env eval {command}", *given])


def _write_result(args: argparse.Namespace, result: Any, flags: tuple[str, ...]) -> None:
    """``--json``: the command line that reproduces the results, the results, and the caption
    reader the generator was loaded with (where the command has the option)."""
    from motion_env.args import write_json

    data = {"command": _echo(args, args.eval_command, flags), **result.to_dict()}
    if hasattr(args, "caption_reader"):
        data["caption_reader"] = args.caption_reader or "default"
    write_json(args.json, data)


def _prepare(args: argparse.Namespace) -> None:
    """The checks every eval command makes before anything heavy loads, then the threads."""
    if args.json:
        check_new_file(args.json, args.overwrite, "--json")
    set_threads(args.threads)


def _generator(args: argparse.Namespace) -> Any:
    from motion_env.generation.generator import MotionGenerator

    return MotionGenerator.from_pretrained(args.model, caption_reader=getattr(args, "caption_reader", None))


def _print(line: str) -> None:
    print(line, flush=True)


def run_eval_control(args: argparse.Namespace) -> int:
    import dataclasses

    _prepare(args)
    from motion_env.evaluation.control import CONTROL_HEAD, ControlSettings, run_control

    settings = ControlSettings(args.data, args.split, args.max_clips, args.objective_repeats, args.seed)
    gen = _generator(args)
    changes = {k: v for k, v in (("space", args.space), ("steps", args.steps)) if v is not None}
    gen.refine_config = dataclasses.replace(gen.refine_config, **changes)
    print(CONTROL_HEAD, flush=True)
    result = run_control(gen, settings, log=_print)
    print()
    print(result.format())
    if args.json:
        flags = ("data", "split", "max_clips", "objective_repeats", "space", "steps", "seed", "model")
        _write_result(args, result, flags)
    return 0


def run_eval_captions(args: argparse.Namespace) -> int:
    _check_dataset(args)
    _prepare(args)
    from motion_env.evaluation.recognition import RecognitionSettings, run_recognition

    settings = RecognitionSettings(args.data, args.split, args.seeds, args.seed, args.classifier)
    gen = _generator(args)
    result = run_recognition(gen, settings, log=_print)
    print()
    print(result.format())
    if args.json:
        _write_result(args, result, ("data", "split", "seeds", "seed", "model", "classifier"))
    return 0


def run_eval_natural(args: argparse.Namespace) -> int:
    _check_dataset(args)
    _prepare(args)
    from motion_env.evaluation.naturalness import NaturalnessSettings, evaluate_naturalness

    settings = NaturalnessSettings(
        args.data, args.split, args.per_action, args.seed, args.stage, classifier=args.classifier,
        actions=args.actions,
    )  # fmt: skip
    gen = _generator(args)
    result = evaluate_naturalness(gen, settings)
    print(result.format())
    if args.json:
        _write_result(
            args, result, ("data", "split", "per_action", "seed", "stage", "model", "classifier", "actions")
        )
    return 0
