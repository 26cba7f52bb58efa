"""Speed of the environments: per-step latency of Waypoints-v0 and frames per second of the vector env.

    python -m motion_env.envs.bench                      # the shipped model, CPU
    python -m motion_env.envs.bench --random-model       # tiny random weights (plumbing only)
    python -m motion_env.envs.bench --num-envs 1 16 64 --steps 1000 --json bench.json

Latency is wall time of ``env.step`` (one frame per step) after a warm-up, over ``steps`` steps of
one episode that follows a random route (no resets inside the timed window): median and 99th
percentile, as PRODUCT.md defines it. Throughput is frames emitted per second by the natively
batched vector env over ``steps`` steps, for each N.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch


def step_latency(
    generator: Any, steps: int = 1000, warmup: int = 50, frames_per_step: int = 1, seed: int = 0
) -> dict[str, float]:
    """Per-step wall time (ms) of one Waypoints-v0 env that keeps following its route.

    Returns median, p99, mean and max over `steps` timed steps after `warmup` untimed ones.
    """
    env = gym.make(
        "motion_env/Waypoints-v0",
        generator=generator,
        frames_per_step=frames_per_step,
        terminate_on_arrival=False,
        max_episode_steps=steps + warmup + 1,
    )
    _, info = env.reset(seed=seed)
    times = np.zeros(steps)
    for t in range(warmup + steps):
        start = time.perf_counter()
        _, _, _, _, info = env.step(info["route_target"])
        if t >= warmup:
            times[t - warmup] = time.perf_counter() - start
    env.close()
    ms = times * 1000.0
    return {
        "steps": steps,
        "frames_per_step": frames_per_step,
        "median_ms": float(np.median(ms)),
        "p99_ms": float(np.percentile(ms, 99)),
        "mean_ms": float(ms.mean()),
        "max_ms": float(ms.max()),
    }


def vector_throughput(
    generator: Any, num_envs: int, steps: int = 200, warmup: int = 20, seed: int = 0
) -> dict:
    """Frames per second of the batched vector env with `num_envs` characters (one frame per step)."""
    envs = gym.make_vec(
        "motion_env/Waypoints-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        generator=generator,
        terminate_on_arrival=False,
        max_episode_steps=steps + warmup + 1,
    )
    _, infos = envs.reset(seed=seed)
    for _ in range(warmup):
        _, _, _, _, infos = envs.step(infos["route_target"])
    start = time.perf_counter()
    for _ in range(steps):
        _, _, _, _, infos = envs.step(infos["route_target"])
    elapsed = time.perf_counter() - start
    envs.close()
    return {
        "num_envs": num_envs,
        "steps": steps,
        "ms_per_step": 1000.0 * elapsed / steps,
        "frames_per_s": num_envs * steps / elapsed,
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    parser.add_argument("--random-model", action="store_true", help="tiny random weights instead")
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--steps", type=int, default=1000, help="timed steps of the latency run")
    parser.add_argument("--vector-steps", type=int, default=200, help="timed steps per vector run")
    parser.add_argument("--num-envs", type=int, nargs="*", default=[1, 16, 64])
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch threads (default 1: fastest for per-frame ops; 0 = torch's)",
    )
    parser.add_argument("--json", default=None, help="also write the results to this file")
    args = parser.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)

    from motion_env.generation.generator import MotionGenerator

    if args.random_model:
        generator = MotionGenerator.random(seed=0, device=args.device)
    else:
        generator = MotionGenerator.from_pretrained(args.model, device=args.device)
    result: dict[str, Any] = {
        "model": "random (untrained)" if args.random_model else (args.model or "shipped"),
        "device": args.device,
        "torch_threads": torch.get_num_threads(),
        "cpu": platform.processor() or platform.machine(),
        "latency": step_latency(generator, steps=args.steps),
        "throughput": [vector_throughput(generator, n, steps=args.vector_steps) for n in args.num_envs],
    }
    lat = result["latency"]
    print(f"model: {result['model']}, device {args.device}, torch threads {result['torch_threads']}")
    print(f"env.step latency over {lat['steps']} steps: median {lat['median_ms']:.2f} ms, ", end="")
    print(f"p99 {lat['p99_ms']:.2f} ms")
    for row in result["throughput"]:
        n, fps, ms = row["num_envs"], row["frames_per_s"], row["ms_per_step"]
        print(f"vector env N={n:3d}: {fps:9.1f} frames/s ({ms:.2f} ms/step)")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
