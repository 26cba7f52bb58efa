"""How fast the limbs move in the environment, next to real walks (issue: "a wrist moves 0.52 m in
one frame during a leisurely walk").

A character of ``motion_env/Waypoints-v0`` (absolute actions, one frame a step, the agent sending
the route target) walks a four-waypoint route from a caption; per seed: the pelvis's median speed,
the wrists' median / 99th-percentile / largest speed and the largest distance any joint moves in
one frame. With ``--data``, the same for the split's real walks (``motion-env data build``).

    python scripts/env_limb_speeds.py --seeds 4 --data data/mocap
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import torch

import motion_env  # noqa: F401  (registers the environments)
from motion_env.motion.skeleton import FPS, JOINT_INDEX

ROUTE = [[0.0, 3.0], [3.0, 6.0], [6.0, 6.0], [6.0, 0.0]]
WRISTS = [JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"]]


def speeds(joints: np.ndarray) -> str:
    """One line of speeds (m/s) of a (T, 22, 3) motion."""
    v = np.linalg.norm(np.diff(joints, axis=0), axis=-1) * FPS  # (T - 1, 22)
    wrist = v[:, WRISTS].max(1)
    return (
        f"pelvis median {np.median(v[:, 0]):.2f} m/s; wrists median {np.median(wrist):.2f}, "
        f"p99 {np.percentile(wrist, 99):.2f}, max {wrist.max():.2f} m/s; "
        f"largest per-frame move of any joint {v.max() / FPS:.3f} m"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=4, help="episodes (one per seed)")
    parser.add_argument("--text", default="a person walks leisurely", help="the caption")
    parser.add_argument("--steps", type=int, default=300, help="steps per episode at most")
    parser.add_argument("--data", default=None, help="a built dataset: also print its real walks")
    parser.add_argument("--split", default="test", help="the split the real walks come from")
    parser.add_argument(
        "--weights", default=None, help="generator weights (default: shipped; random: the test model)"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    from motion_env.generation.generator import MotionGenerator

    env = gym.make(
        "motion_env/Waypoints-v0",
        generator=MotionGenerator.from_pretrained(args.weights),
        action_mode="absolute",
        frames_per_step=1,
    )
    for seed in range(args.seeds):
        _, info = env.reset(seed=seed, options={"text": args.text, "waypoints": ROUTE})
        frames = [info["joints"].copy()]
        for _ in range(args.steps):
            _, _, terminated, truncated, info = env.step(np.asarray(info["route_target"], np.float32))
            frames.append(info["joints"].copy())
            if terminated or truncated:
                break
        print(f"env, seed {seed} ({len(frames)} frames): {speeds(np.stack(frames))}")
    env.close()
    if args.data:
        from motion_env.evaluation.naturalness import naturalness_takes

        for take in naturalness_takes(args.data, args.split).get("walk", []):
            print(f"real {take.name}: {speeds(take.joints)}")


if __name__ == "__main__":
    main()
