#!/usr/bin/env python
"""Load a G1 clip saved with format="mjlab" into mjlab's own G1 tracking env; reset and step it.

The proof that the export is what mjlab's tracker reads: mjlab's ``MotionCommand`` loads the file,
its reset writes the clip's first frame onto the simulated robot (reference state initialisation),
and the env steps. The script checks, and prints as JSON:

- the file's joint and body names against the env's robot (same names, same order);
- after the reset, how far the robot's joints and tracked bodies are from the clip's frame: mjlab
  writes the root and the joints (positions and velocities) from the file, and its simulation
  computes the bodies' poses and velocities; they agree with the file's when the export follows
  mjlab's conventions (largest absolute difference, rad, m, rad/s, m/s);
- the env stepping --steps times with zero actions (the robot holds its default pose, so it drifts
  from the clip and the episode may end: what a tracker learns to avoid), the terminations seen and
  the tracking errors mjlab reports;
- with --against, the file against what mjlab's own converter wrote for the same clip (its
  ``csv_to_npz`` on our ``lafan_csv`` export at the same rate, or wbc-mjlab's ``data_to_npz`` on our
  ``gmr`` pickle): the largest difference per array over the frames both have. The converters
  leave out the clip's last frame and take one-sided differences on their own last one, so the
  velocities are compared on every common frame but that one.

Runs in a venv with mjlab (it brings its own mujoco; see docs/robots.md), on warp's CPU device:

    # the main venv: a generated walk, retargeted onto the G1, saved for mjlab
    motion-env generate --text "a person walks forward" --waypoints "0,3" --frames 120 --out walk.npz
    motion-env retarget walk.npz --robot unitree_g1 --format mjlab --out walk_g1.npz
    # the mjlab venv
    . .venv-mjlab/bin/activate
    WANDB_MODE=disabled python scripts/check_trackers.py walk_g1.npz --json runs/check_trackers.json
    # and against mjlab's own converter (it writes /tmp/motion.npz)
    # (walk_g1_50.csv: motion-env retarget ... --format lafan_csv --fps 50, in the main venv)
    WANDB_MODE=disabled python -m mjlab.scripts.csv_to_npz --input-file walk_g1_50.csv --output-name walk_g1 \
        --input-fps 50 --output-fps 50 --device cpu
    python scripts/check_trackers.py walk_g1.npz --against /tmp/motion.npz
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("WANDB_MODE", "disabled")  # mjlab imports wandb; nothing is logged here


def _args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("motion", type=Path, help='a G1 clip saved with format="mjlab" (.npz)')
    p.add_argument("--steps", type=int, default=25, help="env steps with zero actions (default 25, 0.5 s)")
    p.add_argument("--num-envs", type=int, default=2, help="parallel envs (default 2)")
    p.add_argument("--device", default="cpu", help="torch and warp device (default cpu)")
    p.add_argument("--json", type=Path, default=None, help="also write the report here")
    help_against = "the same clip as mjlab's csv_to_npz (or wbc-mjlab's data_to_npz) wrote it (.npz)"
    p.add_argument("--against", type=Path, default=None, help=help_against)
    return p.parse_args(argv)


def _check_names(data: dict, robot: Any) -> dict:
    """The file's names against the env's robot, or SystemExit naming the first difference."""
    for key, names in (("joint_names", robot.joint_names), ("body_names", robot.body_names)):
        if key in data and [str(n) for n in data[key]] != list(names):
            raise SystemExit(f"{key} in the file differ from mjlab's G1: {list(data[key])} vs {list(names)}")
    return {"joints": len(robot.joint_names), "bodies": len(robot.body_names)}


def _reset_errors(env: Any, robot: Any, motion: Any, data: dict) -> dict:
    """How far the reset robot (joints; tracked bodies' positions and velocities, as mjlab's
    simulation computes them from the written state) is from the clip's frame."""
    import numpy as np

    # The reset writes frame t onto the robot, then advances the command to t + 1 (its next target).
    frame = np.maximum(motion.time_steps.cpu().numpy() - 1, 0)
    ids = motion.body_indexes.cpu().numpy()
    origins = env.scene.env_origins.cpu().numpy()[:, None]

    def err(sim: Any, key: str, offset: Any = 0.0) -> float:
        ours = data[key][frame][:, ids] if key.startswith("body") else data[key][frame]
        got = sim.cpu().numpy()[:, ids] if key.startswith("body") else sim.cpu().numpy()
        return float(np.abs(got - offset - ours).max())

    return {
        "joint_pos": err(robot.data.joint_pos, "joint_pos"),
        "joint_vel": err(robot.data.joint_vel, "joint_vel"),
        "body_pos_w": err(robot.data.body_link_pos_w, "body_pos_w", origins),
        "body_lin_vel_w": err(robot.data.body_link_lin_vel_w, "body_lin_vel_w"),
        "body_ang_vel_w": err(robot.data.body_link_ang_vel_w, "body_ang_vel_w"),
    }


def _against(data: dict, path: Path) -> dict:
    """Largest differences between the file and a converter's npz of the same clip (quaternions up
    to sign), or SystemExit naming the file and the array that does not fit."""
    import numpy as np

    if not path.is_file():
        raise SystemExit(f"no converter output at {path}")
    keys = ("joint_pos", "body_pos_w", "body_quat_w", "joint_vel", "body_lin_vel_w", "body_ang_vel_w")
    with np.load(path, allow_pickle=False) as npz:  # names (object arrays) are not read
        theirs = {key: npz[key].astype(np.float64) for key in keys if key in npz.files}
    n = min(len(theirs.get("joint_pos", ())), len(data["joint_pos"]))
    report: dict = {"file": str(path), "frames_compared": n}
    for key in keys:
        if key not in theirs:
            raise SystemExit(f"{path} has no {key}: not a converter's tracking npz")
        if theirs[key].shape[1:] != data[key].shape[1:] or n < 3:
            raise SystemExit(f"{path}: {key} is {theirs[key].shape}; the clip's is {data[key].shape}")
        ours, got = data[key][:n].astype(np.float64), theirs[key][:n]
        diff = np.abs(ours - got)
        if key == "body_quat_w":  # q and -q are the same rotation
            diff = np.minimum(diff.max(-1), np.abs(ours + got).max(-1))
        # velocities: the converter's last frame is a one-sided difference, ours a central one
        report[key] = float(diff[: n - 1].max() if "_vel" in key else diff.max())
    return report


def main(argv: list[str] | None = None) -> int:
    args = _args(argv)
    if not args.motion.is_file():
        raise SystemExit(f"no motion file at {args.motion}")
    import numpy as np
    import torch

    torch.set_num_threads(1)
    from mjlab.envs import ManagerBasedRlEnv
    from mjlab.tasks.tracking.config.g1.env_cfgs import unitree_g1_flat_tracking_env_cfg

    with np.load(args.motion) as npz:
        data = {key: npz[key] for key in npz.files}
    against = _against(data, args.against) if args.against is not None else None
    # play=True: the episode starts at the clip's first frame, without randomised root offsets;
    # no joint noise either, so that the reset robot is exactly the clip's frame.
    cfg = unitree_g1_flat_tracking_env_cfg(play=True)
    cfg.scene.num_envs = args.num_envs
    cfg.commands["motion"].motion_file = str(args.motion)
    cfg.commands["motion"].joint_position_range = (0.0, 0.0)
    start = time.perf_counter()
    env = ManagerBasedRlEnv(cfg=cfg, device=args.device)
    report: dict = {"mjlab_env_s": round(time.perf_counter() - start, 1)}
    robot, motion = env.scene["robot"], env.command_manager.get_term("motion")
    report.update(_check_names(data, robot))
    report["clip_frames"] = int(motion.motion.time_step_total)

    env.reset()
    report["after_reset"] = _reset_errors(env, robot, motion, data)

    zeros = torch.zeros(env.action_space.shape, device=env.device)
    terminated, errors, start = {}, [], time.perf_counter()
    for _ in range(args.steps):
        _, _, done, timeout, _ = env.step(zeros)
        errors.append({k: float(v.mean()) for k, v in motion.metrics.items() if k.startswith("error_")})
        for name in env.termination_manager.active_terms:
            terminated[name] = terminated.get(name, 0) + int(env.termination_manager.get_term(name).sum())
    report["steps"] = args.steps
    report["steps_per_s"] = round(args.steps / (time.perf_counter() - start), 1)
    report["terminations"] = terminated
    report["tracking_error_mean"] = {k: round(float(np.mean([e[k] for e in errors])), 4) for k in errors[0]}
    env.close()
    if against is not None:
        report["against_converter"] = against
    text = json.dumps(report, indent=2)
    print(text)
    if args.json is not None:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
