"""`motion-env bench`'s measurements at the sizes a GPU is for, on any torch device.

Every code path runs once small first (a broken path shows its traceback in seconds and the other
measurements still run), then: the 200-frame clip at batch 1, the stream at B = 1 ... 4,096, one
env in each of the bench's agents, the native vector env at N = 64 ... 4,096 (fewer timed steps
for larger N), a profile of the largest vector env's steps (where the time goes: the host's
Python and numpy against the device's kernels), and the same machine's CPU at one thread for
scale. Each result is written to the JSON file as soon as it is measured; measurements past the
time budget are skipped, so a run on a lent machine with a hard time limit returns what it had.

    python scripts/bench_device.py --device cuda --json out/gpu_bench.json
    python scripts/bench_device.py --device cpu --num-envs 64,256 --batch-sizes 1,64 --budget 60
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import pstats
import subprocess
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from motion_env.evaluation import bench
from motion_env.generation.generator import MotionGenerator


class Run:
    """Measurements by name into one JSON file, each written as soon as it is taken."""

    def __init__(self, path: Path, device: str, budget_s: float) -> None:
        self.path, self.device, self.budget_s, self.t0 = path, device, budget_s, time.time()
        self.results: dict[str, Any] = {"device": device, "hardware": bench.hardware()}
        try:
            self.results["nvidia_smi"] = subprocess.run(
                ["nvidia-smi", "-L"], capture_output=True, text=True, timeout=30
            ).stdout
        except (OSError, subprocess.SubprocessError):
            pass

    def measure(self, name: str, fn: Callable[..., Any], *args: Any, always: bool = False, **kw: Any) -> None:
        if not always and time.time() - self.t0 > self.budget_s:
            print(f"{name}: skipped (past the {self.budget_s:.0f} s budget)", flush=True)
            return
        t = time.time()
        try:
            if self.device.startswith("cuda"):
                torch.cuda.synchronize()
            result = fn(*args, **kw)
            print(f"{name} [{time.time() - t:.1f} s] {json.dumps(result)[:300]}", flush=True)
        except Exception:  # noqa: BLE001  (one broken path must not lose the other numbers)
            result = {"error": traceback.format_exc()}
            print(f"{name}: ERROR\n{result['error']}", flush=True)
        self.results[name] = result
        self.path.write_text(json.dumps(self.results, indent=1))


def vector(generator: MotionGenerator, num_envs: int, steps: int, warmup: int, agent: str) -> dict[str, Any]:
    """:func:`bench.vector_throughput` with the calibration beside it."""
    return bench.calibrated(bench.vector_throughput, generator, num_envs, steps, warmup, agent=agent)


def profile(generator: MotionGenerator, num_envs: int, agent: str, steps: int = 5) -> dict[str, Any]:
    """The vector env's throughput under cProfile, with the 30 costliest functions (own time)."""
    prof = cProfile.Profile()
    prof.enable()
    result = bench.vector_throughput(generator, num_envs, steps=steps, warmup=2, agent=agent)
    prof.disable()
    text = io.StringIO()
    pstats.Stats(prof, stream=text).sort_stats("tottime").print_stats(30)
    print(text.getvalue()[:6000], flush=True)
    return {**result, "profile": text.getvalue()[:8000]}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--device", default="cuda")
    p.add_argument("--model", default=None, help="weights directory (default: the shipped model)")
    p.add_argument("--batch-sizes", default="1,64,256,1024,4096", help="stream batch sizes")
    p.add_argument("--num-envs", default="64,256,1024,4096", help="vector-env sizes")
    p.add_argument("--clip-runs", type=int, default=20, help="timed runs of the 200-frame clip")
    p.add_argument("--env-steps", type=int, default=500, help="steps of one env per agent")
    p.add_argument("--budget", type=float, default=300.0, help="seconds after which measurements are skipped")
    p.add_argument("--no-cpu", action="store_true", help="skip the same machine's CPU at one thread")
    p.add_argument("--json", type=Path, default=Path("bench_device.json"))
    args = p.parse_args()
    torch.set_num_threads(1)
    run = Run(args.json, args.device, args.budget)
    gen = MotionGenerator.from_pretrained(args.model, device=args.device)
    gen.encode_text([bench.BENCH_TEXT])  # the text encoder loads outside the timings
    agents = bench.bench_agents(gen)
    # Every path once, small (also the device's warm-up: kernels load, caches allocate).
    run.measure("smoke_clip", bench.time_clip, gen, 1, 200, 1, always=True)
    run.measure("smoke_stream", bench.time_stream, gen, 2, 10, always=True)
    for agent in agents:
        run.measure(f"smoke_env_{agent}", bench.time_env, gen, 10, agent=agent, always=True)
        run.measure(f"smoke_vector_{agent}", bench.vector_throughput, gen, 4, 3, 2, agent=agent, always=True)
    run.measure("clip", bench.calibrated, bench.time_clip, gen, args.clip_runs, 200)
    for b in (int(v) for v in args.batch_sizes.split(",")):
        run.measure(f"stream_{b}", bench.calibrated, bench.time_stream, gen, b, 100)
    for agent in agents:
        run.measure(f"env_{agent}", bench.calibrated, bench.time_env, gen, args.env_steps, agent=agent)
    sizes = [int(v) for v in args.num_envs.split(",")]
    for n in sizes:
        steps, warmup = (100, 10) if n <= 256 else (40, 5) if n <= 1024 else (20, 5)
        for agent in agents:
            run.measure(f"vector_{n}_{agent}", vector, gen, n, steps, warmup, agent)
    run.measure(f"profile_{sizes[-1]}_learner_4", profile, gen, sizes[-1], "learner_4")
    if not args.no_cpu and args.device != "cpu":
        cpu = MotionGenerator.from_pretrained(args.model, device="cpu")
        cpu.encode_text([bench.BENCH_TEXT])
        run.measure("cpu_clip", bench.calibrated, bench.time_clip, cpu, 5, 200)
        for n, steps in ((64, 30), (1024, 10)):
            run.measure(f"cpu_vector_{n}_learner_4", vector, cpu, n, steps, 2, "learner_4")
    print(f"total {time.time() - run.t0:.0f} s; results in {args.json}")


if __name__ == "__main__":
    main()
