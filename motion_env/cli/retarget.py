"""Retarget a motion onto a humanoid robot (Unitree G1, Booster T1, or any humanoid MJCF): scaled to
the robot's size, feet on the floor, every joint inside 90 % of its range (--soft-limit). Writes
the project's files (.csv: one row of MuJoCo qpos per frame, root quaternion w, x, y, z, named in
the header; .npz: root_pos, root_rot x, y, z, w, dof_pos, fps, joint_names) or the files motion
trackers read (--format mjlab: mjlab's tracking npz at 50 fps; gmr: GMR's .pkl; lafan_csv: no
header, quaternion x, y, z, w, 30 fps, as mjlab's csv_to_npz and Unitree's LAFAN1 release read).
--show-mapping prints which robot frame follows which human joint. Needs the optional mink package
(pip install -c constraints.txt -e ".[robots]").
"""

from __future__ import annotations

import argparse
from pathlib import Path

from motion_env.cli.common import CommandError, add_overwrite, check_new_file, check_suffix

__all__ = ["add_retarget", "run_retarget"]

_RETARGET_HELP = (
    "retarget a motion (.npz or BVH) onto a humanoid robot: MuJoCo qpos, or mjlab / GMR / LAFAN-style files"
)
_FORMATS = ("csv", "npz", "mjlab", "gmr", "lafan_csv")
_SUFFIX = {"csv": ".csv", "npz": ".npz", "mjlab": ".npz", "gmr": ".pkl", "lafan_csv": ".csv"}


def add_retarget(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("retarget", help=_RETARGET_HELP, description=__doc__)
    p.add_argument("file", nargs="?", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument(
        "--robot", default="unitree_g1",
        help="unitree_g1 (default), booster_t1, a mapping table (.json) or a humanoid MJCF (.xml)",
    )  # fmt: skip
    p.add_argument("--out", default=None, help="robot motion to write (.csv, .npz or .pkl)")
    p.add_argument(
        "--format", choices=_FORMATS, default=None,
        help="file format (default: by the suffix of --out: .csv csv, .npz npz, .pkl gmr); mjlab "
        "writes .npz, lafan_csv .csv",
    )  # fmt: skip
    p.add_argument(
        "--fps", type=float, default=None,
        help="frame rate of the robot motion (default 50; 30 for --format lafan_csv)",
    )  # fmt: skip
    p.add_argument(
        "--soft-limit", type=float, default=0.9,
        help="share of each joint's range, about its centre, the motion stays inside (default 0.9)",
    )  # fmt: skip
    p.add_argument(
        "--show-mapping", action="store_true",
        help="print which robot frame follows which human joint (alone: print it and stop)",
    )  # fmt: skip
    p.add_argument("--video", default=None, help="also render the robot to this .mp4 (or .gif)")
    add_overwrite(p)
    p.set_defaults(run=run_retarget)


def _check_args(args: argparse.Namespace) -> str | None:
    """Check the outputs before any work, so that a typo fails at once; the format to write."""
    if args.out is None:
        raise CommandError("--out is required (the robot motion to write)")
    if args.file is None:
        raise CommandError("give the motion FILE to retarget (or only --show-mapping)")
    fmt = args.format
    suffixes = (_SUFFIX[fmt],) if fmt else (".csv", ".npz", ".pkl")
    check_suffix(args.out, suffixes, "--out", hint=f" (format {fmt})" if fmt else "")
    check_new_file(args.out, args.overwrite, "--out")
    if args.video is not None:
        check_suffix(args.video, (".mp4", ".gif"), "--video")
        check_new_file(args.video, args.overwrite, "--video")
    if args.fps is not None and not args.fps > 0:
        raise CommandError(f"--fps must be a positive number, got {args.fps}")
    if not 0 < args.soft_limit <= 1:
        raise CommandError(f"--soft-limit must be in (0, 1], got {args.soft_limit}")
    if not Path(args.file).is_file():
        raise FileNotFoundError(f"no motion file at {args.file}")
    return fmt


def run_retarget(args: argparse.Namespace) -> int:
    import os

    fmt = None if args.show_mapping and args.file is None and args.out is None else _check_args(args)
    # Offscreen rendering needs this before mujoco is imported (EGL works on CPU through Mesa).
    os.environ.setdefault("MUJOCO_GL", "egl")
    from motion_env.args import require

    require("mink", "robots")  # imports mujoco
    from motion_env.io.load import load_motion
    from motion_env.retarget import load_robot, retarget
    from motion_env.retarget.files import DEFAULT_FPS, infer_format
    from motion_env.retarget.table import describe_table

    robot = load_robot(args.robot)  # an unknown name or a model that is not a humanoid fails here
    if args.show_mapping:
        print(describe_table(robot.table))
        if args.file is None and args.out is None:
            return 0
    motion = load_motion(args.file)
    # lafan_csv is written at 30 fps by default: retarget at 50 and let the file resample.
    result = retarget(motion, robot.key, fps=args.fps or 50.0, soft_limit=args.soft_limit)
    hands = [k for k, name in enumerate(result.residual_names) if name.endswith("wrist")]
    feet = [k for k, name in enumerate(result.residual_names) if name.endswith("ankle")]
    path = result.save(args.out, fmt, fps=args.fps)
    fmt = infer_format(path, fmt)
    rate = args.fps or DEFAULT_FPS.get(fmt, result.fps)
    frames = int((result.num_frames - 1) * rate / result.fps + 1e-6) + 1  # as the file resamples
    what = f"{robot.name}, {frames} frames at {rate:g} fps, format {fmt}"
    if hands and feet:
        what += (
            f"; hands {100 * result.residuals[:, hands].mean():.1f} cm, feet "
            f"{100 * result.residuals[:, feet].mean():.1f} cm from their targets on average"
        )
    print(f"wrote {path} ({what})")
    if args.video is not None:
        from motion_env.retarget.video import render_robot_video

        try:
            print(f"wrote {render_robot_video(result, args.video)} (video of {robot.name})")
        except RuntimeError as exc:  # no offscreen OpenGL: say so in one line
            raise CommandError(str(exc)) from None
    return 0
