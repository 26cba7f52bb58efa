"""The `motion-env` command line.

Each subcommand has a small `_add_<name>` function that declares its arguments and a `_run_<name>`
function that calls the library; the heavy modules are imported only by the command that needs
them, so `motion-env --help` stays fast.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from motion_env.data.captions import DEFAULT_NUM_CAPTIONS


def _add_show(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("show", help="draw a motion (.npz or BVH) as a stick-figure video and a path plot")
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument(
        "--out",
        default=None,
        help="video to write (.mp4 or .gif); default: <FILE stem>.mp4 in the current directory",
    )
    p.add_argument("--plot", default=None, help="also write a top-down plot of the root path (.png)")
    p.add_argument(
        "--camera", choices=("follow", "fixed"), default="follow",
        help="follow the character, or one fixed view of the whole route (default: follow)",
    )  # fmt: skip
    p.add_argument("--fps", type=float, default=None, help="video frame rate (default: the motion's)")
    p.add_argument("--title", default=None, help="caption shown on the video (default: the motion's text)")
    p.set_defaults(run=_run_show)


def _run_show(args: argparse.Namespace) -> int:
    from pathlib import Path

    from motion_env.io.load import load_motion
    from motion_env.render import VIDEO_SUFFIXES, plot_path, render_video

    src = Path(args.file)
    if args.out is None:
        # The current directory, not the source's: mocap often sits in a read-only data folder.
        stem = src.name[: -len(".bvh.gz")] if src.name.lower().endswith(".bvh.gz") else src.stem
        out = Path(stem + ".mp4")
    else:
        out = Path(args.out)
    # Check the outputs before loading, so that a typo fails at once.
    if out.suffix.lower() not in VIDEO_SUFFIXES:
        raise ValueError(f"--out {out}: unknown video type {out.suffix!r} (expected one of {VIDEO_SUFFIXES})")
    if args.plot is not None and Path(args.plot).suffix.lower() != ".png":
        raise ValueError(f"--plot {args.plot}: the path plot is written as a .png")
    motion = load_motion(src)
    # A clip without a caption (a BVH) is titled with its file name.
    title = args.title if args.title is not None else motion.text or src.name
    video = render_video(motion, out, fps=args.fps, title=title, camera=args.camera)
    print(f"wrote {video} ({motion.num_frames} frames, {motion.duration:.1f} s)")
    if args.plot is not None:
        print(f"wrote {plot_path(motion, args.plot, title=title)}")
    return 0


def _add_data(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("data", help="build training datasets")
    dsub = p.add_subparsers(dest="data_command", required=True)
    b = dsub.add_parser(
        "build",
        help="BVH folders -> a HumanML3D-layout dataset directory",
        description="Import every .bvh / .bvh.gz under the given folders onto the canonical skeleton "
        "and write a HumanML3D-layout dataset (new_joints/, new_joint_vecs/, texts/, train/val/test.txt, "
        "Mean.npy, Std.npy) with captions made from the file names (Bandai Namco labels, CMU-INDEX.md "
        "descriptions, or the file-name words; a <stem>.txt next to a BVH file gives its captions).",
    )
    b.add_argument("sources", nargs="+", help="folders searched recursively for .bvh / .bvh.gz files")
    b.add_argument("--out", required=True, help="output directory (must be empty or not exist)")
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
    b.set_defaults(run=_run_data_build)


def _run_data_build(args: argparse.Namespace) -> int:
    from motion_env.data.build import build_dataset

    try:
        summary = build_dataset(
            args.sources,
            args.out,
            mirror=not args.no_mirror,
            workers=args.workers,
            captions_per_clip=args.captions,
            seed=args.seed,
            min_seconds=args.min_seconds,
            cmu_index=args.cmu_index,
        )
    except FileExistsError as exc:
        print(f"motion-env data build: error: {exc}", file=sys.stderr)
        return 2
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
}


def _train_config_class(model: str) -> type:
    import importlib

    module, name, _ = _TRAINERS[model]
    return getattr(importlib.import_module(module), name)


class _TrainParser(argparse.ArgumentParser):
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


def _add_train(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train",
        help="train one model of the generator (VQ-VAE, then GPT; controller any time)",
        description="Train one model of the generator. Each model's options are its trainer's settings "
        "(motion-env train MODEL --help lists them with their defaults).",
    )
    models = p.add_subparsers(dest="model", required=True, metavar="MODEL", parser_class=_TrainParser)
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
        m.set_defaults(run=_run_train)


def _run_train(args: argparse.Namespace) -> int:
    import dataclasses
    import json
    from pathlib import Path

    if not Path(args.data).is_dir():
        raise FileNotFoundError(f"no dataset directory at {args.data}")
    config_class = _train_config_class(args.model)
    config = config_class(**{f.name: getattr(args, f.name) for f in dataclasses.fields(config_class)})
    if args.model == "vqvae":
        from motion_env.training.vqvae import train_vqvae

        metrics = train_vqvae(args.data, args.out, config)
    elif args.model == "gpt":
        from motion_env.training.gpt import train_gpt

        if args.vqvae is None:
            raise ValueError("training the gpt needs --vqvae CKPT (the trained VQ-VAE)")
        metrics = train_gpt(args.data, args.vqvae, args.out, config)
    else:
        from motion_env.training.controller import train_controller

        metrics = train_controller(args.data, args.out, config)
    print(json.dumps({"model": args.model, "checkpoint": str(args.out), **metrics}, indent=2))
    return 0


def _add_generate(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("generate", help="text + waypoints -> a motion (.npz) and a video")
    p.add_argument("--text", required=True, help='caption, e.g. "a person walks slowly"')
    p.add_argument(
        "--waypoints",
        default=None,
        help='"x,z,t;x,z,t": metres, optional frame index (20 fps); ";"-separated',
    )
    p.add_argument("--frames", type=int, default=200, help="frames to generate (20 fps; default 200 = 10 s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (same seed, same motion)")
    p.add_argument("--start", default=None, help='"x,z,heading" of the first frame (default "0,0,0")')
    p.add_argument("--out", default="motion.npz", help="motion file to write (.npz)")
    p.add_argument("--video", default=None, help="also render a stick-figure video (.mp4 or .gif)")
    p.add_argument("--plot", default=None, help="also draw a top-down plot of the path (.png)")
    p.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    p.add_argument(
        "--random-model",
        action="store_true",
        help="use tiny UNTRAINED random weights (for testing the plumbing)",
    )
    p.add_argument("--device", default="cpu", help="torch device")
    p.set_defaults(run=_run_generate)


def _run_generate(args: argparse.Namespace) -> int:
    from motion_env.args import parse_waypoints
    from motion_env.generation.generator import MotionGenerator

    waypoints = None if args.waypoints is None else parse_waypoints(args.waypoints)
    start = None
    if args.start is not None:
        try:
            start = [float(v) for v in args.start.split(",")]
        except ValueError as exc:
            raise ValueError(f"--start {args.start!r} must be 'x,z,heading' numbers") from exc
    if args.random_model and args.model is not None:
        raise ValueError("give either --model or --random-model, not both")
    if args.random_model:
        gen = MotionGenerator.random(seed=args.seed, device=args.device)
    else:
        gen = MotionGenerator.from_pretrained(args.model, device=args.device)
    motion = gen.generate(args.text, waypoints, num_frames=args.frames, seed=args.seed, start=start)
    out = motion.save(args.out)
    print(f"wrote {out} ({motion.num_frames} frames, {motion.duration:.1f} s)")
    if args.video or args.plot:
        from motion_env.render import plot_path, render_video

        if args.video:
            print(f"wrote {render_video(motion, args.video)}")
        if args.plot:
            print(f"wrote {plot_path(motion, args.plot)}")
    return 0


def _add_bench(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="latency and throughput of the generator and the environment")
    p.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    p.add_argument("--random-model", action="store_true", help="benchmark tiny UNTRAINED random weights")
    p.add_argument("--device", default="cpu", help="torch device")
    p.add_argument("--runs", type=int, default=10, help="timed runs of the 200-frame clip (after warm-up)")
    p.add_argument("--frames", type=int, default=200, help="frames per clip")
    p.add_argument("--batch-sizes", default="1,16,64", help="streaming batch sizes for throughput")
    p.add_argument("--stream-frames", type=int, default=100, help="frames streamed per throughput run")
    p.add_argument("--env-steps", type=int, default=1000, help="environment steps timed (0: skip the env)")
    p.add_argument("--num-envs", default="1,16,64", help="vector-env sizes for throughput")
    p.add_argument("--vector-steps", type=int, default=200, help="timed steps per vector-env run (0: skip)")
    p.add_argument(
        "--threads", type=int, default=1,
        help="torch CPU threads (default 1: the models' small sequential steps run faster on one thread)",
    )  # fmt: skip
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    p.set_defaults(run=_run_bench)


def _run_bench(args: argparse.Namespace) -> int:
    from motion_env.args import write_json
    from motion_env.evaluation.bench import format_results, run_bench

    sizes = [int(v) for v in args.batch_sizes.split(",") if v.strip()]
    results = run_bench(
        model=args.model, random_model=args.random_model, device=args.device, runs=args.runs,
        num_frames=args.frames, batch_sizes=sizes, stream_frames=args.stream_frames,
        env_steps=args.env_steps, threads=args.threads,
        num_envs=[int(v) for v in args.num_envs.split(",") if v.strip()], vector_steps=args.vector_steps,
    )  # fmt: skip
    print(format_results(results))
    if args.json:
        write_json(args.json, results)
    return 0


def _add_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay",
        help="MuJoCo physical-plausibility report for a motion",
        description="Replay a motion (.npz or BVH) on a MuJoCo humanoid and report what is physically "
        "wrong: floor penetration, floating, foot skating, limbs through each other, joint limits, "
        "speeds, accelerations and the root force the floor cannot supply.",
    )
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--video", default=None, help="also render the replay to this .mp4 (or .gif)")
    p.add_argument("--mass", type=float, default=70.0, help="body mass of the humanoid in kg (default 70)")
    p.add_argument("--track", action="store_true", help="also simulate PD tracking (reported only)")
    p.add_argument("--thresholds", default=None, help="calibration JSON (default: the shipped one)")
    p.set_defaults(run=_run_replay)


def _run_replay(args: argparse.Namespace) -> int:
    import json
    import os

    # Offscreen rendering needs this before mujoco is imported (EGL works on CPU through Mesa).
    os.environ.setdefault("MUJOCO_GL", "egl")
    from motion_env.io.load import load_motion
    from motion_env.replay import evaluate_detailed, format_report

    if not (args.mass > 0):
        raise ValueError(f"--mass must be a positive number of kg, got {args.mass}")
    if args.video:
        from motion_env.render.video import check_video_path

        check_video_path(args.video)  # a typo fails before the replay, not after it
    motion = load_motion(args.file)
    m, result = evaluate_detailed(motion, args.mass, args.thresholds, track=args.track)
    if args.video:
        from motion_env.render.humanoid import render_humanoid_video

        try:
            result["video"] = str(render_humanoid_video(m, result, args.video))
        except RuntimeError as exc:  # no offscreen OpenGL: say so in one line
            print(f"motion-env replay: error: {exc}", file=sys.stderr)
            return 2
    print(json.dumps(result, indent=2) if args.json else format_report(result, title=args.file))
    return 0


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
    except KeyboardInterrupt:
        print(f"motion-env {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
