"""Write a motion as a BVH on the canonical skeleton (centimetres, ZXY Euler angles, the motion's
frame rate) and/or as a reference for the replay's MuJoCo humanoid (.npz: qpos, root position and
quaternion, local joint quaternions (w, x, y, z), foot contacts). The formats are described in
docs/conventions.md, 'Export'.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from motion_env.cli.common import CommandError, add_overwrite, check_new_file, check_suffix

__all__ = ["add_export", "run_export"]


_EXPORT_HELP = "write a motion (.npz or BVH) as a BVH and/or a robot-ready .npz for the MuJoCo humanoid"


def add_export(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("export", help=_EXPORT_HELP, description=__doc__)
    p.add_argument("file", help="a .npz written by Motion.save, or a .bvh / .bvh.gz file")
    p.add_argument("--bvh", default=None, help="BVH file to write (.bvh, or .bvh.gz to compress it)")
    p.add_argument("--humanoid-npz", default=None, help="humanoid reference to write (.npz)")
    p.add_argument(
        "--mass",
        type=float,
        default=70.0,
        help="body mass of the humanoid in kg (default 70; --humanoid-npz)",
    )
    add_overwrite(p)
    p.set_defaults(run=run_export)


def run_export(args: argparse.Namespace) -> int:
    if args.bvh is None and args.humanoid_npz is None:
        raise CommandError("nothing to write: give --bvh and/or --humanoid-npz")
    if not (args.mass > 0):
        raise CommandError(f"--mass must be a positive number of kg, got {args.mass}")
    # Check the outputs before loading, so that a typo fails at once.
    if args.bvh is not None:
        if not Path(args.bvh).name.lower().endswith((".bvh", ".bvh.gz")):
            raise CommandError(f"--bvh {args.bvh}: must end in .bvh or .bvh.gz")
        check_new_file(args.bvh, args.overwrite, "--bvh")
    if args.humanoid_npz is not None:
        check_suffix(args.humanoid_npz, (".npz",), "--humanoid-npz")
        check_new_file(args.humanoid_npz, args.overwrite, "--humanoid-npz")
    src = Path(args.file)
    if not src.is_file():
        raise FileNotFoundError(f"no motion file at {src}")

    from motion_env.io.bvh_write import save_bvh
    from motion_env.io.load import load_motion

    motion = load_motion(src)
    what = f"{motion.num_frames} frames at {motion.fps:g} fps"
    if args.bvh is not None:
        print(f"wrote {save_bvh(motion, args.bvh)} (BVH, {what}, centimetres, ZXY Euler angles)")
    if args.humanoid_npz is not None:
        from motion_env.replay.export import save_humanoid_npz

        path = save_humanoid_npz(motion, args.humanoid_npz, mass=args.mass)
        print(f"wrote {path} (humanoid reference, {what})")
    return 0
