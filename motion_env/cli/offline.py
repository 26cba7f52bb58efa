"""`motion-env data build` (BVH folders -> a training dataset) and `motion-env train <model>`.

`data build` follows the rule of every command for outputs that exist: it refuses, unless
``--overwrite``. `train --out` is the exception by design: an existing checkpoint is resumed from
(`--no-resume` starts over), see :mod:`motion_env.training.loop`.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

from motion_env.cli.common import CommandError, CommandParser, add_threads, set_threads

__all__ = ["add_data", "add_train"]


_BUILD_HELP = "BVH folders -> a HumanML3D-layout dataset directory"
_BUILD_DESCRIPTION = (
    "Import every .bvh / .bvh.gz under the given folders onto the canonical skeleton and write a "
    "HumanML3D-layout dataset (new_joints/, new_joint_vecs/, texts/, train/val/test.txt, Mean.npy, "
    "Std.npy) with captions made from the file names (Bandai Namco labels, CMU-INDEX.md descriptions, "
    "or the file-name words; a <stem>.txt next to a BVH file gives its captions)."
)


def add_data(sub: argparse._SubParsersAction) -> None:
    from motion_env.data.captions import DEFAULT_NUM_CAPTIONS

    p = sub.add_parser("data", help="build training datasets")
    dsub = p.add_subparsers(dest="data_command", required=True)
    b = dsub.add_parser("build", help=_BUILD_HELP, description=_BUILD_DESCRIPTION)
    b.add_argument("sources", nargs="+", help="folders searched recursively for .bvh / .bvh.gz files")
    b.add_argument(
        "--out", required=True, help="output directory (must be empty or not exist, unless --overwrite)"
    )
    b.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an existing dataset directory (one that `data build` wrote); the old one is "
        "kept until the new one is complete",
    )
    b.add_argument("--workers", type=int, default=2, help="import processes (default: 2)")
    b.add_argument("--no-mirror", action="store_true", help="do not add mirrored copies of the takes")
    b.add_argument(
        "--captions",
        type=int,
        default=DEFAULT_NUM_CAPTIONS,
        help=f"captions per clip (default: {DEFAULT_NUM_CAPTIONS})",
    )
    b.add_argument("--seed", type=int, default=0, help="seed of the caption wording (default: 0)")
    b.add_argument(
        "--min-seconds", type=float, default=1.0, help="skip takes shorter than this (default: 1.0)"
    )
    b.add_argument("--cmu-index", default=None, help="CMU-INDEX.md to use (default: found next to the files)")
    b.set_defaults(run=run_data_build)


def _set_aside(out: Path, overwrite: bool) -> Path | None:
    """An existing, non-empty `out`: refused, or (with `overwrite`) renamed aside; the new name."""
    if not out.exists() or (out.is_dir() and not any(out.iterdir())):
        return None
    if not overwrite:
        raise CommandError(
            f"{out} exists and is not empty: nothing was written (pass --overwrite to replace it)"
        )
    if not (out.is_dir() and (out / "summary.json").is_file() and (out / "new_joint_vecs").is_dir()):
        raise CommandError(
            f"--overwrite: {out} is not a dataset written by `motion-env data build` (no summary.json, "
            "new_joint_vecs/); not replacing it"
        )
    aside = out.with_name(f".{out.name}.replaced")
    if aside.exists():
        shutil.rmtree(aside)
    out.rename(aside)
    return aside


def run_data_build(args: argparse.Namespace) -> int:
    from motion_env.data.build import build_dataset

    out = Path(args.out).expanduser()
    aside = _set_aside(out, args.overwrite)
    try:
        summary = build_dataset(
            args.sources,
            out,
            mirror=not args.no_mirror,
            workers=args.workers,
            captions_per_clip=args.captions,
            seed=args.seed,
            min_seconds=args.min_seconds,
            cmu_index=args.cmu_index,
        )
    except BaseException:
        if aside is not None and not out.exists():
            aside.rename(out)  # nothing lost: the old dataset is back where it was
        raise
    if aside is not None:
        shutil.rmtree(aside)
    print(summary.format())
    return 0


# `train <model>`: each model's trainer module, its config dataclass, and what it trains.
_TRAINERS = {
    "vqvae": ("motion_env.training.vqvae", "VQVAETrainConfig", "the motion VQ-VAE (train it first)"),
    "gpt": ("motion_env.training.gpt", "GPTTrainConfig", "the token GPT, on the tokens of a trained VQ-VAE"),
    "controller": (
        "motion_env.training.controller",
        "ControllerTrainConfig",
        "the path controller (needs no other model)",
    ),
    "lookahead": (
        "motion_env.training.lookahead",
        "LookaheadTrainConfig",
        "the stream's look-ahead head, distilled from a weights folder's controller (then "
        "models.checkpoint.export_checkpoint into that folder as lookahead.pt)",
    ),
    "caption-adapter": (
        "motion_env.training.caption_adapter",
        "CaptionAdapterTrainConfig",
        "the caption adapter of a caption reader (text only: other wordings -> what the GPT and "
        "controller know)",
    ),
    "pace": (
        "motion_env.training.pace",
        "PaceTrainConfig",
        "the pace regressor (caption -> the takes' speed: untimed routes at the caption's pace; "
        "reads the weights folder's controller space and caption adapter)",
    ),
    "classifier": (
        "motion_env.training.classifier",
        "ClassifierTrainConfig",
        "the action/style classifier of real takes (the judge of eval captions and eval natural)",
    ),
}


def _train_config_class(model: str) -> type:
    import importlib

    module, name, _ = _TRAINERS[model]
    return getattr(importlib.import_module(module), name)


class TrainParser(CommandParser):
    """The parser of `train <model>`: its options are made from the trainer's config dataclass (one
    per field) when it is first used, so only `motion-env train` imports the trainers."""

    def __init__(self, *args, model: str, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._model, self._config_added = model, False

    def _add_config(self) -> None:
        if not self._config_added:
            from motion_env.args import add_dataclass_arguments

            self._config_added = True
            add_dataclass_arguments(self, _train_config_class(self._model))

    def parse_known_args(self, args=None, namespace=None):
        self._add_config()
        return super().parse_known_args(args, namespace)

    def format_usage(self) -> str:
        self._add_config()
        return super().format_usage()

    def format_help(self) -> str:
        self._add_config()
        return super().format_help()


_TRAIN_HELP = "train one model (the generator's VQ-VAE, then GPT; the others any time)"
_TRAIN_DESCRIPTION = (
    "Train one model of the generator, or the classifier that judges it. Each model's options are "
    "its trainer's settings (motion-env train MODEL --help lists them with their defaults). An "
    "existing --out checkpoint is resumed from."
)


def add_train(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("train", help=_TRAIN_HELP, description=_TRAIN_DESCRIPTION)
    models = p.add_subparsers(dest="model", required=True, metavar="MODEL", parser_class=TrainParser)
    for model, (_, _, what) in _TRAINERS.items():
        m = models.add_parser(model, help=what, description=f"Train {what}.", model=model)
        m.add_argument(
            "--data", required=True, help="HumanML3D-layout dataset directory (motion-env data build)"
        )
        m.add_argument("--out", required=True, help="checkpoint to write (resumed from when it exists)")
        if model == "gpt":
            m.add_argument(
                "--vqvae", default=None, help="the trained VQ-VAE checkpoint that tokenises the data"
            )
        add_threads(m)
        m.set_defaults(run=run_train)


def run_train(args: argparse.Namespace) -> int:
    import dataclasses
    import json

    if not Path(args.data).is_dir():
        raise FileNotFoundError(f"no dataset directory at {args.data}")
    config_class = _train_config_class(args.model)
    config = config_class(**{f.name: getattr(args, f.name) for f in dataclasses.fields(config_class)})
    if args.model == "gpt" and args.vqvae is None:
        raise CommandError("training the gpt needs --vqvae CKPT (the trained VQ-VAE)")
    set_threads(args.threads)
    if args.model == "vqvae":
        from motion_env.training.vqvae import train_vqvae

        metrics = train_vqvae(args.data, args.out, config)
    elif args.model == "gpt":
        from motion_env.training.gpt import train_gpt

        metrics = train_gpt(args.data, args.vqvae, args.out, config)
    elif args.model == "controller":
        from motion_env.training.controller import train_controller

        metrics = train_controller(args.data, args.out, config)
    elif args.model == "lookahead":
        from motion_env.training.lookahead import train_lookahead

        metrics = train_lookahead(args.data, args.out, config)
    elif args.model == "pace":
        from motion_env.training.pace import train_pace

        metrics = train_pace(args.data, args.out, config)
    elif args.model == "classifier":
        from motion_env.training.classifier import train_classifier

        metrics = train_classifier(args.data, args.out, config)
    else:
        from motion_env.training.caption_adapter import train_caption_adapter

        metrics = train_caption_adapter(args.data, args.out, config)
    print(json.dumps({"model": args.model, "checkpoint": str(args.out), **metrics}, indent=2))
    return 0
