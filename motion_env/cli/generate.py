"""`motion-env generate` (caption + route -> a motion file, a video, a plot) and `motion-env bench`.

`generate` checks everything it can before it loads a model, in this order, so that a typo fails
in a fraction of a second: the file names (suffixes, files in the way), the route, start, clip
length, seed and the feasibility of the timed waypoints (:func:`check_batch_request`, no model
needed), then the device; only then does it load the weights.
"""

from __future__ import annotations

import argparse

from motion_env.cli.common import (
    CommandError,
    add_caption_reader,
    add_overwrite,
    add_threads,
    add_weights,
    check_device,
    check_model_choice,
    check_new_file,
    check_suffix,
    load_generator,
    set_threads,
)

__all__ = ["add_bench", "add_generate"]


def add_generate(sub: argparse._SubParsersAction) -> None:
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
    p.add_argument("--out", default="motion.npz", help="motion file to write (.npz; default motion.npz)")
    p.add_argument("--video", default=None, help="also render a stick-figure video (.mp4 or .gif)")
    p.add_argument("--plot", default=None, help="also draw a top-down plot of the path (.png)")
    add_overwrite(p)
    infeasible = "timed waypoints faster than a person: an error (raise) or retimed with a warning (warn)"
    p.add_argument("--infeasible", choices=("raise", "warn"), default="raise", help=infeasible)
    add_weights(p)
    p.add_argument(
        "--random-model",
        action="store_true",
        help="use tiny UNTRAINED random weights (for testing the plumbing)",
    )
    add_caption_reader(p)
    p.add_argument("--device", default="cpu", help="torch device (default cpu)")
    add_threads(p)
    p.set_defaults(run=run_generate)


def _parse_start(text: str | None) -> list[float] | None:
    if text is None:
        return None
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise CommandError(f"--start {text!r} must be 'x,z,heading' numbers") from None


def _check_outputs(args: argparse.Namespace) -> None:
    """The files `generate` writes: the right suffixes (so three different files), none in the way."""
    check_suffix(args.out, (".npz",), "--out", hint=" (a motion is saved as .npz; --video writes a video)")
    outputs = [("--out", args.out)]
    if args.video is not None:
        from motion_env.render.video import check_video_path

        try:
            check_video_path(args.video)
        except ValueError as exc:
            raise CommandError(f"--video {exc}") from None
        outputs.append(("--video", args.video))
    if args.plot is not None:
        check_suffix(args.plot, (".png",), "--plot", hint=" (the path plot is a PNG)")
        outputs.append(("--plot", args.plot))
    for flag, path in outputs:
        check_new_file(path, args.overwrite, flag)


def _check_request(args: argparse.Namespace) -> list[list[float]] | None:
    """The route, start, clip length and seed, checked as the generator will check them."""
    from motion_env.args import parse_waypoints
    from motion_env.generation.request import check_request, check_text

    check_text(args.text, "--text")
    waypoints = None if args.waypoints is None else parse_waypoints(args.waypoints)
    start = _parse_start(args.start)
    try:
        check_request(args.text, waypoints, args.frames, args.seed, start, args.infeasible)
    except ValueError as exc:
        # The library names its keyword argument; here it is an option.
        raise ValueError(str(exc).replace("infeasible='warn'", "--infeasible warn")) from None
    return waypoints


def run_generate(args: argparse.Namespace) -> int:
    check_model_choice(args)
    _check_outputs(args)
    waypoints = _check_request(args)
    start = _parse_start(args.start)
    gen = load_generator(args, [args.text])
    motion = gen.generate(
        args.text, waypoints, num_frames=args.frames, seed=args.seed, start=start, infeasible=args.infeasible
    )
    out = motion.save(args.out)
    print(f"wrote {out} ({motion.num_frames} frames, {motion.duration:.1f} s)")
    if args.video or args.plot:
        from motion_env.render import plot_path, render_video

        if args.video:
            print(f"wrote {render_video(motion, args.video)}")
        if args.plot:
            print(f"wrote {plot_path(motion, args.plot)}")
    return 0


def add_bench(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="latency and throughput of the generator and the environment")
    add_weights(p)
    p.add_argument("--random-model", action="store_true", help="benchmark tiny UNTRAINED random weights")
    p.add_argument("--device", default="cpu", help="torch device (default cpu)")
    p.add_argument("--runs", type=int, default=10, help="timed runs of the 200-frame clip (after warm-up)")
    p.add_argument("--frames", type=int, default=200, help="frames per clip")
    p.add_argument("--batch-sizes", default="1,16,64", help="streaming batch sizes for throughput")
    p.add_argument("--stream-frames", type=int, default=100, help="frames streamed per throughput run")
    p.add_argument("--env-steps", type=int, default=1000, help="environment steps timed (0: skip the env)")
    p.add_argument("--num-envs", default="1,16,64", help="vector-env sizes for throughput")
    p.add_argument("--vector-steps", type=int, default=200, help="timed steps per vector-env run (0: skip)")
    add_threads(p)
    p.add_argument("--json", default=None, help="also write the results to this JSON file")
    add_overwrite(p)
    p.set_defaults(run=run_bench)


def _int_list(text: str, flag: str) -> list[int]:
    try:
        return [int(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise CommandError(f"{flag} {text!r} must be whole numbers separated by commas") from None


def run_bench(args: argparse.Namespace) -> int:
    sizes = _int_list(args.batch_sizes, "--batch-sizes")
    num_envs = _int_list(args.num_envs, "--num-envs")
    if args.json:
        check_new_file(args.json, args.overwrite, "--json")
    check_device(args.device)
    set_threads(args.threads)

    from motion_env.args import write_json
    from motion_env.evaluation.bench import format_results, run_bench

    results = run_bench(
        model=args.model, random_model=args.random_model, device=args.device, runs=args.runs,
        num_frames=args.frames, batch_sizes=sizes, stream_frames=args.stream_frames,
        env_steps=args.env_steps, threads=args.threads, num_envs=num_envs, vector_steps=args.vector_steps,
    )  # fmt: skip
    print(format_results(results))
    if args.json:
        write_json(args.json, results)
    return 0
