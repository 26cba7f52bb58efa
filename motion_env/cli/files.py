"""`motion-env show` (a motion file as a stick-figure video and a path plot) and `motion-env replay`
(the MuJoCo plausibility report of a motion file). Neither uses torch."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from motion_env.cli.common import CommandError, add_overwrite, check_new_file, check_suffix

__all__ = ["add_replay", "add_show"]


def add_show(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("show", help="draw a motion (.npz or BVH) as a stick-figure video and a path plot")
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument(
        "--out",
        default=None,
        help="video to write (.mp4 or .gif); default: <FILE stem>.mp4 in the current directory",
    )
    p.add_argument("--plot", default=None, help="also write a top-down plot of the root path (.png)")
    add_overwrite(p)
    p.add_argument(
        "--camera", choices=("follow", "fixed"), default="follow",
        help="follow the character, or one fixed view of the whole route (default: follow)",
    )  # fmt: skip
    p.add_argument("--fps", type=float, default=None, help="video frame rate (default: the motion's)")
    p.add_argument("--title", default=None, help="caption shown on the video (default: the motion's text)")
    p.set_defaults(run=run_show)


def _check_video(path: str | Path, flag: str, overwrite: bool) -> Path:
    from motion_env.render.video import check_video_path

    try:
        check_video_path(path)
    except ValueError as exc:
        raise CommandError(f"{flag} {exc}") from None
    return check_new_file(path, overwrite, flag)


def run_show(args: argparse.Namespace) -> int:
    src = Path(args.file)
    if args.out is None:
        # The current directory, not the source's: mocap often sits in a read-only data folder.
        stem = src.name[: -len(".bvh.gz")] if src.name.lower().endswith(".bvh.gz") else src.stem
        out = Path(stem + ".mp4")
    else:
        out = Path(args.out)
    # Check the outputs before loading, so that a typo fails at once.
    _check_video(out, "--out", args.overwrite)
    if args.plot is not None:
        check_suffix(args.plot, (".png",), "--plot", hint=" (the path plot is a PNG)")
        check_new_file(args.plot, args.overwrite, "--plot")
    if not src.is_file():
        raise FileNotFoundError(f"no motion file at {src}")

    from motion_env.io.load import load_motion
    from motion_env.render import plot_path, render_video

    motion = load_motion(src)
    # A clip without a caption (a BVH) is titled with its file name.
    title = args.title if args.title is not None else motion.text or src.name
    video = render_video(motion, out, fps=args.fps, title=title, camera=args.camera)
    print(f"wrote {video} ({motion.num_frames} frames, {motion.duration:.1f} s)")
    if args.plot is not None:
        print(f"wrote {plot_path(motion, args.plot, title=title)}")
    return 0


_REPLAY_HELP = "MuJoCo physical-plausibility report for a motion"
_REPLAY_DESCRIPTION = (
    "Replay a motion (.npz or BVH) on a MuJoCo humanoid and report what is physically wrong: floor "
    "penetration, floating, foot skating, limbs through each other, joint limits, speeds, "
    "accelerations and the root force the floor cannot supply. With --robot, retarget it onto a "
    "humanoid robot (50 fps) first and judge the robot's qpos on the robot's own model (joint ranges, "
    "floor, floating, foot skating, self-collision, root force). Exit code 0 whatever the verdict, "
    "unless --strict."
)


def add_replay(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("replay", help=_REPLAY_HELP, description=_REPLAY_DESCRIPTION)
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.add_argument("--video", default=None, help="also render the replay to this .mp4 (or .gif)")
    add_overwrite(p)
    p.add_argument(
        "--mass", type=float, default=None,
        help="body mass of the humanoid in kg (default 70; not with --robot)",
    )  # fmt: skip
    p.add_argument(
        "--track", action="store_true", help="also simulate PD tracking (reported only; not with --robot)"
    )
    p.add_argument(
        "--robot", default=None, metavar="NAME_OR_MJCF",
        help="judge the motion retargeted onto this robot instead: unitree_g1, booster_t1, a mapping "
        "table (.json) or a humanoid MJCF (.xml); needs the optional mink package",
    )  # fmt: skip
    p.add_argument("--thresholds", default=None, help="calibration JSON (default: the shipped one)")
    p.add_argument(
        "--strict",
        action="store_true",
        help="exit with code 1 unless the verdict is PLAUSIBLE (not plausible, or too short to judge)",
    )
    p.set_defaults(run=run_replay)


def run_replay(args: argparse.Namespace) -> int:
    import json
    import os

    if args.robot is not None and (args.mass is not None or args.track):
        raise CommandError("--mass and --track are the humanoid's: they do not apply with --robot")
    mass = 70.0 if args.mass is None else args.mass
    if not (mass > 0):
        raise CommandError(f"--mass must be a positive number of kg, got {args.mass}")
    if args.video:
        _check_video(args.video, "--video", args.overwrite)  # a typo fails before the replay, not after it
    if not Path(args.file).is_file():
        raise FileNotFoundError(f"no motion file at {args.file}")
    # Offscreen rendering needs this before mujoco is imported (EGL works on CPU through Mesa).
    os.environ.setdefault("MUJOCO_GL", "egl")
    from motion_env.io.load import load_motion
    from motion_env.replay import evaluate_detailed, format_report

    motion = load_motion(args.file)
    if args.robot is not None:
        result = _replay_robot(motion, args.robot, args.thresholds, args.video)
        title = f"{args.file} on {result['robot']}"
        print(json.dumps(result, indent=2) if args.json else format_report(result, title=title))
        return _strict_exit(args, result)
    m, result = evaluate_detailed(motion, mass, args.thresholds, track=args.track)
    if args.video:
        from motion_env.render.humanoid import render_humanoid_video

        try:
            result["video"] = str(render_humanoid_video(m, result, args.video))
        except RuntimeError as exc:  # no offscreen OpenGL: say so in one line
            raise CommandError(str(exc)) from None
    print(json.dumps(result, indent=2) if args.json else format_report(result, title=args.file))
    return _strict_exit(args, result)


def _replay_robot(motion: Any, robot: str, thresholds: str | None, video: str | None) -> dict:
    """The robot's plausibility report of `motion` retargeted onto `robot` at 50 fps."""
    from motion_env.args import require

    require("mink", "robots")  # imports mujoco
    from motion_env.replay import evaluate_robot
    from motion_env.retarget import load_robot, retarget

    bot = load_robot(robot)  # an unknown name or a model that is not a humanoid fails here
    robot_motion = retarget(motion, bot.key, fps=50)
    result = evaluate_robot(robot_motion.qpos, bot.model, robot_motion.fps, thresholds)
    if video:
        from motion_env.retarget.video import render_robot_video

        try:
            result["video"] = str(render_robot_video(robot_motion, video))
        except RuntimeError as exc:  # no offscreen OpenGL: say so in one line
            raise CommandError(str(exc)) from None
    return result


def _strict_exit(args: argparse.Namespace, result: dict) -> int:
    """1 (saying why) when --strict and the verdict is not PLAUSIBLE, else 0."""
    if args.strict and result.get("plausible") is not True:
        verdict = "too short to judge" if result.get("judged") is False else "NOT PLAUSIBLE"
        print(f"motion-env replay: {verdict} (--strict): exit code 1", file=sys.stderr)
        return 1
    return 0
