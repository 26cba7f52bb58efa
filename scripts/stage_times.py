"""Where a token's time goes in one environment: the stream's stages timed one by one.

``motion_env/Waypoints-v0`` driven as ``motion-env bench`` drives it (an agent of
:data:`motion_env.evaluation.bench.AGENTS`: following its route, or a learner sending a new random
target every step, at one frame a step or the learning default of four), each stage's method
wrapped in a wall-clock timer for the timed steps; per token, the milliseconds of each stage
(nested: the path's planning holds the controller's roll-out and the look-ahead head). The
timers cost about a microsecond a call. With ``--calibrate``, the calibration workload beside the
run and each time also as its quiet-machine equivalent. The first line also gives the step's time
outside the tokens (the env's commands, observations and emitted frames). With ``--num-envs N``
(N > 1) the native vector env instead, as the bench drives it (each env its sampled route, no
episode ending): one token is then every env's, each stage one batched call.

    python scripts/stage_times.py --agent learner_4 --steps 300
    python scripts/stage_times.py --agent learner_4 --steps 60 --num-envs 64 --calibrate
"""

from __future__ import annotations

import argparse
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import torch

import motion_env  # noqa: F401  (registers the environments)
from motion_env.evaluation.bench import (
    AGENTS,
    BENCH_TEXT,
    REFERENCE_CALIBRATION_S,
    _agent_action,
    calibration_s,
)
from motion_env.generation.feet import FootPinner
from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator
from motion_env.generation.physics import PhysicsFilter
from motion_env.generation.pipeline import Pipeline
from motion_env.generation.streaming import MotionStream
from motion_env.models.controller import PathController
from motion_env.models.gpt import TokenGPT
from motion_env.models.lookahead import LookaheadHead

# One env as `motion-env bench` times it (time_env): this caption and route, again at every reset.
OPTIONS = {"text": BENCH_TEXT, "waypoints": [[0.0, 3.0], [3.0, 6.0], [6.0, 6.0], [6.0, 0.0]]}
# What a token runs, in order: "label = Class.method", the indented ones inside the one above.
STAGE_TABLE = """
token (all stages) = MotionStream._produce
  2. path: plan = MotionStream._plan_paths
    controller roll-out = PathController.run
    look-ahead head = LookaheadHead.predict
    restore after a new target = MotionStream._restore
  3. tokens = MotionStream._sample_tokens
    GPT step = TokenGPT.step
  4. decode = Pipeline.decode_next
  5. compose = MotionStream._compose
  6. balance = MotionStream._balanced
  6. feet = FootPinner.apply_rows
  6. physics = PhysicsFilter.apply_rows
"""
CLASSES = {
    c.__name__: c
    for c in (MotionStream, PathController, LookaheadHead, TokenGPT, Pipeline, FootPinner, PhysicsFilter)
}


def _stage(line: str) -> tuple[type, str, str]:
    """(class, method, label) of one line of :data:`STAGE_TABLE`."""
    label, target = line.split(" = ")
    cls, method = target.split(".")
    return CLASSES[cls], method, label


STAGES = [_stage(line) for line in STAGE_TABLE.strip("\n").splitlines()]


def timed(totals: defaultdict[str, float], calls: Counter, label: str, method: Callable) -> Callable:
    """`method` with its wall time added to totals[label] and its calls counted."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        start = time.perf_counter()
        try:
            return method(*args, **kwargs)
        finally:
            totals[label] += time.perf_counter() - start
            calls[label] += 1

    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agent", default="learner_4", choices=sorted(AGENTS), help="how the env is driven")
    parser.add_argument("--steps", type=int, default=300, help="timed env steps (after 30 of warm-up)")
    parser.add_argument("--weights", default=None, help="weights folder ('random': untrained)")
    parser.add_argument("--calibrate", action="store_true", help="also quiet-machine equivalents")
    parser.add_argument("--num-envs", type=int, default=1, help="characters: over 1, the native vector env")
    args = parser.parse_args()
    if args.steps < 1:
        parser.error(f"--steps must be >= 1, got {args.steps}")
    if args.num_envs < 1:
        parser.error(f"--num-envs must be >= 1, got {args.num_envs}")
    torch.set_num_threads(1)
    gen = MotionGenerator.from_pretrained(RANDOM_MODEL if args.weights == "random" else args.weights)
    rng = np.random.default_rng(0)
    if args.num_envs == 1:
        env = gym.make("motion_env/Waypoints-v0", generator=gen, **AGENTS[args.agent])
        _, info = env.reset(seed=0, options=OPTIONS)
    else:  # as `motion-env bench` drives the vector env: the sampled routes, no episode ends
        env = gym.make_vec(
            "motion_env/Waypoints-v0",
            num_envs=args.num_envs,
            vectorization_mode="vector_entry_point",
            generator=gen,
            terminate_on_arrival=False,
            max_episode_steps=args.steps + 31,
            **AGENTS[args.agent],
        )
        _, info = env.reset(seed=0)

    def run(steps: int) -> None:
        nonlocal info
        for _ in range(steps):
            _, _, terminated, truncated, info = env.step(
                _agent_action(args.agent, info, rng, env.action_space.shape)
            )
            if args.num_envs == 1 and (terminated or truncated):
                _, info = env.reset(options=OPTIONS)

    run(30)
    totals: defaultdict[str, float] = defaultdict(float)
    calls: Counter = Counter()
    saved = [(cls, name, cls.__dict__.get(name)) for cls, name, _ in STAGES]  # None: inherited
    for cls, name, label in STAGES:
        setattr(cls, name, timed(totals, calls, label, getattr(cls, name)))
    try:
        start = time.perf_counter()
        run(args.steps)
        wall = time.perf_counter() - start
    finally:
        for cls, name, method in saved:
            if method is None:
                delattr(cls, name)  # the parent's method shows through again
            else:
                setattr(cls, name, method)
    scale = REFERENCE_CALIBRATION_S / calibration_s() if args.calibrate else None
    tokens = max(calls["token (all stages)"], 1)
    outside = (wall - totals["token (all stages)"]) / args.steps * 1e3  # the env's own bookkeeping
    print(
        f"{args.agent}, {args.num_envs} env(s): {args.steps} steps, {tokens} tokens, "
        f"{wall / args.steps * 1e3:.2f} ms a step, of which {outside:.2f} outside the tokens"
    )
    print(f"{'stage':<34}{'ms/token':>10}{'quiet equiv.':>14}{'calls/token':>13}")
    for _, _, label in STAGES:
        ms = totals[label] / tokens * 1e3
        quiet = f"{ms * scale:.3f}" if scale else ""
        print(f"{label:<34}{ms:>10.3f}{quiet:>14}{calls[label] / tokens:>13.2f}")


if __name__ == "__main__":
    main()
