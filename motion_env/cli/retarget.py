"""Retarget a motion onto a humanoid robot (Unitree G1, Booster T1, or any humanoid MJCF): scaled to
the robot's size, feet on the floor, every joint inside its range. Writes one row of MuJoCo qpos
per frame (.csv: root x, y, z, quaternion w, x, y, z, then the joints, named in the header) or
GMR's fields (.npz: root_pos, root_rot in xyzw order, dof_pos, fps, joint_names). Needs the
optional mink package (pip install 'motion-env[robots]').
"""

from __future__ import annotations

import argparse
from pathlib import Path

from motion_env.cli.common import CommandError, add_overwrite, check_new_file, check_suffix

__all__ = ["add_retarget", "run_retarget"]


_RETARGET_HELP = "retarget a motion (.npz or BVH) onto a humanoid robot: MuJoCo qpos as .csv or .npz"


def add_retarget(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("retarget", help=_RETARGET_HELP, description=__doc__)
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument(
        "--robot", default="unitree_g1",
        help="unitree_g1 (default), booster_t1, a mapping table (.json) or a humanoid MJCF (.xml)",
    )  # fmt: skip
    p.add_argument("--out", required=True, help="robot motion to write (.csv or .npz)")
    p.add_argument("--fps", type=float, default=50.0, help="frame rate of the robot motion (default 50)")
    p.add_argument("--video", default=None, help="also render the robot to this .mp4 (or .gif)")
    add_overwrite(p)
    p.set_defaults(run=run_retarget)


def run_retarget(args: argparse.Namespace) -> int:
    import os

    # Check the outputs before any work, so that a typo fails at once.
    check_suffix(args.out, (".csv", ".npz"), "--out")
    check_new_file(args.out, args.overwrite, "--out")
    if args.video is not None:
        check_suffix(args.video, (".mp4", ".gif"), "--video")
        check_new_file(args.video, args.overwrite, "--video")
    if not args.fps > 0:
        raise CommandError(f"--fps must be a positive number, got {args.fps}")
    if not Path(args.file).is_file():
        raise FileNotFoundError(f"no motion file at {args.file}")

    # Offscreen rendering needs this before mujoco is imported (EGL works on CPU through Mesa).
    os.environ.setdefault("MUJOCO_GL", "egl")
    from motion_env.args import require

    require("mink", "robots")  # imports mujoco
    from motion_env.io.load import load_motion
    from motion_env.retarget import load_robot, retarget

    robot = load_robot(args.robot)  # an unknown name or a model that is not a humanoid fails here
    motion = load_motion(args.file)
    result = retarget(motion, robot.key, fps=args.fps)
    hands = [k for k, name in enumerate(result.residual_names) if name.endswith("wrist")]
    feet = [k for k, name in enumerate(result.residual_names) if name.endswith("ankle")]
    what = f"{robot.name}, {result.num_frames} frames at {result.fps:g} fps"
    if hands and feet:
        what += (
            f"; hands {100 * result.residuals[:, hands].mean():.1f} cm, feet "
            f"{100 * result.residuals[:, feet].mean():.1f} cm from their targets on average"
        )
    print(f"wrote {result.save(args.out)} ({what})")
    if args.video is not None:
        from motion_env.retarget.video import render_robot_video

        try:
            print(f"wrote {render_robot_video(result, args.video)} (video of {robot.name})")
        except RuntimeError as exc:  # no offscreen OpenGL: say so in one line
            raise CommandError(str(exc)) from None
    return 0
