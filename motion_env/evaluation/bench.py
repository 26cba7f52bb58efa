"""Latency and throughput of the generator and the environment (``motion-env bench``).

What is measured (the definitions of ``docs/metrics.md``):

- clip latency: wall time of :meth:`MotionGenerator.generate` for a 200-frame clip with a caption
  and timed waypoints, batch 1, after warm-up; median and 90th percentile of ``runs`` runs, each
  with its own seed;
- streaming throughput: frames per second summed over the batch, for :meth:`MotionGenerator.stream`
  with B = 1, 16, 64 characters (each on its own route), after the first step (which rolls the
  controller's look-ahead);
- environment step: wall time of ``env.step`` of ``motion_env/Waypoints-v0`` (one frame per step),
  median and 99th percentile over ``env_steps`` steps, in two cases: the agent issuing the route
  target (a character following its route), and a learner's case, a new random target (normalised
  action, no follow switch) every step;
- controller roll-out: milliseconds per frame of the path controller's closed loop alone
  (:meth:`PathController.run <motion_env.models.controller.PathController.run>`, 200 frames, each
  character on its own timed route) at B = 1 and 64 characters, on each of its frame backends
  (numpy and torch on the CPU: where ``frame_backend="auto"`` switches from one to the other);
- GPT decoding: milliseconds per token of the body GPT's sampling alone
  (:meth:`TokenGPT.generate <motion_env.models.gpt.TokenGPT.generate>`, 50 tokens, the window
  sliding) at B = 1 and 64 characters, on each of its step backends (:attr:`TokenGPT.step_backend`);
- vector-env throughput: env steps per second of the natively batched vector env
  (``vectorization_mode="vector_entry_point"``, one frame per step) with N = 1, 16, 64 characters,
  over ``vector_steps`` steps after a warm-up, in the same two cases.

Speed on a shared machine: the machine this runs on may be busy, and its speed drifts by 2x within
a day. Between the parts of every measurement (each run of the clip, the controller and the GPT;
:data:`PARTS` chunks of the stream's, the env's and the vector env's steps) the bench times a fixed
calibration workload (:func:`calibration_s`: a GRU cell (128 -> 384) stepped 200 times plus 50
blocks of 32x192 @ 192x768 @ 768x192 matmuls at batch 1, one thread; about
:data:`REFERENCE_CALIBRATION_S` on the project's 2-core machine when it is quiet) and reports each
number also as its quiet-machine equivalent: each part's times x reference / the mean of the
calibrations on its two sides (rates the other way), summarised as the raw ones are
(:class:`Calibration`). Before/after comparisons use the equivalents.

On a machine with more runnable threads than cores, wall time also counts the time this process
waits for a core, which the calibration beside it can only partly correct. So every measurement
is also taken in CPU time (``time.process_time``: the time this process ran, all its threads) and
scaled by the calibration's own CPU time (``quiet_cpu``); on a quiet machine the two agree, and
under load the CPU-time equivalent is the steadier one.

This is the project's one bench; ``motion-env bench`` runs it and prints a table.
"""

from __future__ import annotations

import inspect
import os
import platform
import time
from typing import Any

import numpy as np
import torch

BENCH_TEXT = "a person walks forward, then turns to the left"
# Timed waypoints of the latency clip: x, z, frame index.
BENCH_WAYPOINTS = np.array([[0.0, 2.5, 50], [2.0, 4.5, 110], [4.0, 4.5, 170]], np.float32)


REFERENCE_CALIBRATION_S = 0.032
"""Seconds :func:`calibration_s` takes on the project's 2-core CPU machine when it is quiet (30-34 ms)."""
PARTS = 5
"""Parts a measurement of many steps is timed in, a calibration after each (:class:`Calibration`)."""
# Result keys that are rates (scaled the other way from times) and keys that are not speeds.
_RATES = ("frames_per_s", "steps_per_s")
_NOT_SPEED = (
    "runs", "frames", "batch", "steps", "episodes_reset", "num_envs", "calibration_ms", "calibration_cpu_ms"
)  # fmt: skip


def _clock() -> tuple[float, float]:
    """(wall, process CPU) seconds now."""
    return time.perf_counter(), time.process_time()


def calibration_times() -> tuple[float, float]:
    """(wall, CPU) seconds of the fixed calibration workload (see the module docstring), on one thread."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        gen = torch.Generator().manual_seed(0)
        cell = torch.nn.GRUCell(128, 384)
        w1, w2 = torch.randn(192, 768, generator=gen), torch.randn(768, 192, generator=gen)
        x, h, y = torch.randn(1, 128, generator=gen), torch.zeros(1, 384), torch.randn(32, 192, generator=gen)
        start = _clock()
        with torch.no_grad():
            for _ in range(200):
                h = cell(x, h)
            for _ in range(50):
                y = torch.relu(y @ w1) @ w2 * 1e-2 + y
        end = _clock()
        return end[0] - start[0], end[1] - start[1]
    finally:
        torch.set_num_threads(threads)


def calibration_s() -> float:
    """Wall seconds of the fixed calibration workload (see the module docstring), on one thread."""
    return calibration_times()[0]


def _scaled(result: dict[str, Any], scale: float) -> dict[str, float]:
    """The speeds of a result dict as quiet-machine equivalents: times x scale, rates / scale."""
    quiet = {}
    for key, value in result.items():
        if isinstance(value, int | float) and not isinstance(value, bool) and key not in _NOT_SPEED:
            quiet[key] = value / scale if key in _RATES else value * scale
    return quiet


class Calibration:
    """The calibration workload timed between the parts of one measurement (its runs, or chunks
    of its steps): each part is scaled to a quiet machine by the mean of the calibrations on its
    two sides, the nearest estimate of the machine's speed while that part ran. One pair of
    calibrations around a whole measurement let a burst of load on either side scale every part
    by it: eight repeats of the clip's ten runs on the loaded 2-core machine gave quiet-machine
    equivalents of 150-201 ms (coefficient of variation 10.6 %) that way, 143-175 ms (5.5 %) with a
    calibration between runs."""

    def __init__(self) -> None:
        self._times = [calibration_times()]  # (wall, CPU) seconds, one more than the parts

    def part_done(self) -> None:
        """A part of the measurement has been timed: the calibration after it."""
        self._times.append(calibration_times())

    def factors(self) -> tuple[np.ndarray, np.ndarray]:
        """(wall, CPU) quiet-machine factors of each part (reference / calibration): times are
        multiplied by them, rates divided."""
        t = np.asarray(self._times if len(self._times) > 1 else self._times * 2)
        beside = (t[1:] + t[:-1]) / 2
        return REFERENCE_CALIBRATION_S / beside[:, 0], REFERENCE_CALIBRATION_S / beside[:, 1]

    def summaries(
        self, summary: Any, wall: list[float], cpu: list[float], part: list[int] | np.ndarray
    ) -> dict[str, Any]:
        """`summary` (per-sample times -> a dict of speeds) of the measurement's wall and CPU
        samples, each of part `part[i]`, as quiet-machine equivalents: ``quiet``, ``quiet_cpu``,
        and the calibrations' means (``calibration_ms``, ``calibration_cpu_ms``)."""
        wall_f, cpu_f = self.factors()
        at = np.asarray(part, dtype=np.int64)
        t = np.asarray(self._times)
        return {
            "calibration_ms": float(t[:, 0].mean() * 1000.0),
            "calibration_cpu_ms": float(t[:, 1].mean() * 1000.0),
            "quiet": summary(np.asarray(wall) * wall_f[at]),
            "quiet_cpu": summary(np.asarray(cpu) * cpu_f[at]),
        }


def calibrated(measure: Any, *args: Any, **kwargs: Any) -> dict[str, Any]:
    """Run ``measure(*args, **kwargs)`` (a dict of times in ms and rates, with the same in CPU time
    under ``cpu``) with the calibration workload beside it; the dict gains ``calibration_ms`` and
    ``calibration_cpu_ms``, ``quiet`` (each speed as its quiet-machine equivalent) and
    ``quiet_cpu`` (the same from CPU times). A measure that takes a ``calibration`` keyword is
    given a :class:`Calibration` and times one between its parts (this module's measures);
    another is scaled by the calibrations before and after it."""
    if "calibration" in inspect.signature(measure).parameters:
        return measure(*args, calibration=Calibration(), **kwargs)
    w0, c0 = calibration_times()
    result = measure(*args, **kwargs)
    w1, c1 = calibration_times()
    calib, calib_cpu = (w0 + w1) / 2, (c0 + c1) / 2
    out = {**result, "calibration_ms": calib * 1000.0, "calibration_cpu_ms": calib_cpu * 1000.0}
    out["quiet"] = _scaled(result, REFERENCE_CALIBRATION_S / calib)
    if "cpu" in result:
        out["quiet_cpu"] = _scaled(result["cpu"], REFERENCE_CALIBRATION_S / calib_cpu)
    return out


def _with_quiet(
    result: dict[str, Any],
    summary: Any,
    wall: list[float],
    cpu: list[float],
    part: list[int] | np.ndarray,
    calibration: Calibration | None,
) -> dict[str, Any]:
    """`result` with its speeds (``summary`` of the wall samples) and their CPU-time twins under
    ``cpu``, and with a calibration their quiet-machine equivalents."""
    out = {**result, **summary(np.asarray(wall)), "cpu": summary(np.asarray(cpu))}
    if calibration is not None:
        out.update(calibration.summaries(summary, wall, cpu, part))
    return out


def _percentiles(values: list[float], qs: tuple[int, ...]) -> dict[str, float]:
    arr = np.asarray(values, dtype=np.float64)
    out = {"median": float(np.median(arr))}
    out.update({f"p{q}": float(np.percentile(arr, q)) for q in qs})
    out["min"] = float(arr.min())
    out["mean"] = float(arr.mean())
    return out


def time_clip(
    generator: Any,
    runs: int = 10,
    num_frames: int = 200,
    warmup: int = 2,
    calibration: Calibration | None = None,
) -> dict[str, Any]:
    """Latency (ms) of one clip with caption and waypoints, batch 1: median, p90, min, mean (and
    the same in CPU time under ``cpu``); with a `calibration`, one between runs."""
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    for i in range(warmup):
        generator.generate(BENCH_TEXT, BENCH_WAYPOINTS, num_frames=num_frames, seed=1000 + i)
    times, cpu = [], []
    for i in range(runs):
        w0, c0 = _clock()
        generator.generate(BENCH_TEXT, BENCH_WAYPOINTS, num_frames=num_frames, seed=i)
        w1, c1 = _clock()
        times.append((w1 - w0) * 1000.0)
        cpu.append((c1 - c0) * 1000.0)
        if calibration is not None:
            calibration.part_done()
    return _with_quiet(
        {"runs": runs, "frames": num_frames},
        lambda v: _percentiles(v, (90,)),
        times,
        cpu,
        np.arange(runs),
        calibration,
    )


def _per_unit(
    model: Any,
    attr: str,
    backend: str,
    call: Any,
    units: int,
    runs: int,
    key: str,
    batch: int,
    calibration: Calibration | None = None,
) -> dict:
    """Milliseconds per unit (frame, token) of `runs` calls ``call(run)`` (run = 1..runs) of `units`
    units each, after ``call(0)`` (a warm-up), with ``model.<attr>`` (a backend switch) set to
    `backend` and put back after; the median under `key`, wall and CPU time (with a
    `calibration`, one after each call)."""
    saved = getattr(model, attr)
    setattr(model, attr, backend)
    times, cpu = [], []
    try:
        for run in range(runs + 1):
            w0, c0 = _clock()
            call(run)
            w1, c1 = _clock()
            if run:
                times.append((w1 - w0) * 1000.0 / units)
                cpu.append((c1 - c0) * 1000.0 / units)
            if calibration is not None:
                calibration.part_done()
    finally:
        setattr(model, attr, saved)
    return _with_quiet(
        {"batch": batch, "backend": backend},
        lambda v: {key: float(np.median(v))},
        times,
        cpu,
        np.arange(1, runs + 1),  # part 0 is the warm-up
        calibration,
    )


def time_controller(
    generator: Any,
    batch: int,
    backend: str,
    frames: int = 200,
    runs: int = 5,
    calibration: Calibration | None = None,
) -> dict:
    """Milliseconds per frame of the path controller's roll-out alone for `batch` characters on
    frame backend `backend` ("numpy" or "torch", :attr:`PathController.frame_backend`): the median
    of `runs` roll-outs of `frames` frames after one warm-up."""
    controller = generator.pipeline.controller
    text = torch.as_tensor(generator.encode_text([BENCH_TEXT] * batch), device=controller.device)
    state = controller.init_state(text, _routes(batch))
    with torch.no_grad():
        return _per_unit(
            controller, "frame_backend", backend, lambda run: controller.run(state, frames), frames, runs,
            "ms_per_frame", batch, calibration,
        )  # fmt: skip


def time_gpt(
    generator: Any,
    batch: int,
    backend: str,
    tokens: int = 50,
    runs: int = 5,
    calibration: Calibration | None = None,
) -> dict:
    """Milliseconds per token of the body GPT's sampling alone for `batch` characters on step
    backend `backend` ("numpy" or "torch", :attr:`TokenGPT.step_backend`): the median of `runs`
    generations of `tokens` tokens (the bench caption, path features of a steady walk) after one
    warm-up."""
    gpt = generator.pipeline.gpt
    text = torch.as_tensor(generator.encode_text([BENCH_TEXT] * batch), device=gpt.head.weight.device)
    path = torch.zeros(batch, tokens, gpt.config.path_dim, device=text.device)
    path[..., 1] = 0.25  # forward, about a walk's pace per token

    def generate(run: int) -> None:
        gens = [torch.Generator().manual_seed(run * batch + b) for b in range(batch)]
        gpt.generate(text, path, tokens, gens)

    return _per_unit(gpt, "step_backend", backend, generate, tokens, runs, "ms_per_token", batch, calibration)


def _routes(batch: int) -> list[np.ndarray]:
    """A different timed route per character (fanned out around the start)."""
    routes = []
    for b in range(batch):
        angle = 2 * np.pi * b / max(batch, 1)
        d = np.array([np.sin(angle), np.cos(angle)])
        side = np.array([d[1], -d[0]])
        pts = [2.5 * d, 5.0 * d + 1.5 * side, 7.5 * d]
        routes.append(np.array([[p[0], p[1], 50 * (k + 1)] for k, p in enumerate(pts)], np.float32))
    return routes


def _part_of(step: int, steps: int) -> int:
    """The part (0 .. PARTS - 1) that step `step` of `steps` falls in (:class:`Calibration`)."""
    return step * min(PARTS, steps) // steps


def _end_of_part(step: int, steps: int, calibration: Calibration | None) -> None:
    """A calibration after step `step` of `steps` where it ends its part."""
    if calibration is not None and (step == steps - 1 or _part_of(step + 1, steps) != _part_of(step, steps)):
        calibration.part_done()


def time_stream(
    generator: Any, batch: int, frames: int = 100, calibration: Calibration | None = None
) -> dict[str, Any]:
    """Streaming throughput of `batch` characters: frames/s (all characters) and ms per step()
    (with a `calibration`, one after the first step and after each of PARTS parts of the rest)."""
    if batch < 1 or frames < 1:
        raise ValueError(f"batch and frames must be >= 1, got {batch} and {frames}")
    stream = generator.stream([BENCH_TEXT] * batch, _routes(batch), seed=0)
    # Seconds of each step; the first (which rolls the controller's look-ahead and decodes the
    # first token) is reported apart, and is part 0.
    times, cpu = [], []
    for step in range(frames + 1):
        w0, c0 = _clock()
        stream.step()
        w1, c1 = _clock()
        times.append(w1 - w0)
        cpu.append(c1 - c0)
        if step == 0 and calibration is not None:
            calibration.part_done()
        elif step:
            _end_of_part(step - 1, frames, calibration)

    def summary(values: np.ndarray) -> dict[str, float]:
        steps = values[1:]
        return {
            "frames_per_s": batch * frames / max(float(np.sum(steps)), 1e-9),
            "step_ms_median": float(np.median(steps) * 1000.0),
            "step_ms_p99": float(np.percentile(steps, 99) * 1000.0),
            "first_step_ms": float(values[0] * 1000.0),
        }

    parts = [0] + [1 + _part_of(step, frames) for step in range(frames)]
    return _with_quiet({"batch": batch, "frames": frames}, summary, times, cpu, parts, calibration)


# The ways an agent drives the env in the bench: following its route (world points, the route
# target), or learning (a new random normalised target every step, no follow switch), at one frame
# a step or at the env's default of 4 (what a learner trains with); with a look-ahead head in the
# weights, the learner also with the exact look-ahead (the head's before).
AGENTS = {
    "route": {"action_mode": "absolute", "frames_per_step": 1},
    "learner": {"action_mode": "normalized", "follow_action": False, "frames_per_step": 1},
    "learner_4": {"action_mode": "normalized", "follow_action": False, "frames_per_step": 4},
    "learner_exact": {
        "action_mode": "normalized",
        "follow_action": False,
        "frames_per_step": 1,
        "lookahead": "exact",
    },
}
AGENT_LABELS = {
    "route": "following the route",
    "learner": "new target each step",
    "learner_4": "new target each step, 4 frames a step",
    "learner_exact": "new target each step, exact look-ahead",
}


def bench_agents(generator: Any) -> list[str]:
    """The agents of :data:`AGENTS` worth timing on `generator` (the exact look-ahead differs
    from the learner's only when the weights have a look-ahead head)."""
    has_head = generator.pipeline.lookahead is not None
    return [a for a in AGENTS if a != "learner_exact" or has_head]


def _agent_action(agent: str, info: dict, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    if agent == "route":
        return np.asarray(info["route_target"], np.float32)
    return rng.uniform(-1.0, 1.0, shape).astype(np.float32)


def time_env(
    generator: Any, steps: int = 1000, agent: str = "route", calibration: Calibration | None = None
) -> dict[str, Any]:
    """Per-step latency (ms) of motion_env/Waypoints-v0 over `steps` steps: median, p99 (resets
    excluded); `agent` is "route" or "learner" (see :data:`AGENTS`); with a `calibration`, one
    after each of PARTS parts of the steps."""
    import gymnasium as gym

    import motion_env  # noqa: F401  (registers the environments)

    env = gym.make("motion_env/Waypoints-v0", generator=generator, **AGENTS[agent])
    options = {"text": BENCH_TEXT, "waypoints": [[0.0, 3.0], [3.0, 6.0], [6.0, 6.0], [6.0, 0.0]]}
    _, info = env.reset(seed=0, options=options)
    rng = np.random.default_rng(0)
    times, cpu, resets = [], [], 0
    while len(times) < steps:
        action = _agent_action(agent, info, rng, env.action_space.shape)
        w0, c0 = _clock()
        _, _, terminated, truncated, info = env.step(action)
        w1, c1 = _clock()
        times.append((w1 - w0) * 1000.0)
        cpu.append((c1 - c0) * 1000.0)
        _end_of_part(len(times) - 1, steps, calibration)
        if terminated or truncated:
            resets += 1
            _, info = env.reset(options=options)
    env.close()

    def summary(values: np.ndarray) -> dict[str, float]:
        out = _percentiles(values, (90, 99))
        return {**out, "steps_per_s": 1000.0 / max(out["mean"], 1e-9)}

    parts = [_part_of(step, steps) for step in range(steps)]
    result = {"steps": steps, "episodes_reset": resets, "agent": agent}
    return _with_quiet(result, summary, times, cpu, parts, calibration)


def vector_throughput(
    generator: Any,
    num_envs: int,
    steps: int = 200,
    warmup: int = 20,
    seed: int = 0,
    agent: str = "route",
    calibration: Calibration | None = None,
) -> dict:
    """Env steps per second of the batched vector env with `num_envs` characters (``steps_per_s``;
    ``frames_per_s`` counts the frames, the same at one frame a step); `agent` is a key of
    :data:`AGENTS`; with a `calibration`, one after each of PARTS parts of the steps."""
    import gymnasium as gym

    import motion_env  # noqa: F401  (registers the environments)

    envs = gym.make_vec(
        "motion_env/Waypoints-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        generator=generator,
        terminate_on_arrival=False,
        max_episode_steps=steps + warmup + 1,
        **AGENTS[agent],
    )
    _, infos = envs.reset(seed=seed)
    rng = np.random.default_rng(seed)
    shape = envs.action_space.shape
    for _ in range(warmup):
        _, _, _, _, infos = envs.step(_agent_action(agent, infos, rng, shape))
    if calibration is not None:
        calibration.part_done()  # part 0: the warm-up
    elapsed, cpu = [0.0] * min(PARTS, steps), [0.0] * min(PARTS, steps)  # seconds of each part
    for step in range(steps):
        w0, c0 = _clock()
        _, _, _, _, infos = envs.step(_agent_action(agent, infos, rng, shape))
        w1, c1 = _clock()
        part = _part_of(step, steps)
        elapsed[part] += w1 - w0
        cpu[part] += c1 - c0
        _end_of_part(step, steps, calibration)
    envs.close()
    frames = AGENTS[agent]["frames_per_step"]

    def rates(seconds: np.ndarray) -> dict[str, float]:
        total = max(float(np.sum(seconds)), 1e-9)
        return {
            "ms_per_step": 1000.0 * total / steps,
            "steps_per_s": num_envs * steps / total,
            "frames_per_s": num_envs * steps * frames / total,
        }

    result = {"num_envs": num_envs, "agent": agent, "steps": steps}
    return _with_quiet(result, rates, elapsed, cpu, np.arange(1, len(elapsed) + 1), calibration)


def hardware() -> dict[str, Any]:
    """What the numbers were measured on."""
    info: dict[str, Any] = {
        "cpu": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "torch": torch.__version__,
        "python": platform.python_version(),
    }
    if torch.cuda.is_available():
        info["gpu"] = torch.cuda.get_device_name(0)
    return info


def run_bench(
    model: str | None = None,
    random_model: bool = False,
    device: str = "cpu",
    runs: int = 10,
    num_frames: int = 200,
    batch_sizes: tuple[int, ...] | list[int] = (1, 16, 64),
    stream_frames: int = 100,
    env_steps: int = 1000,
    threads: int | None = None,
    num_envs: tuple[int, ...] | list[int] = (1, 16, 64),
    vector_steps: int = 200,
) -> dict[str, Any]:
    """Every measurement of this module on one generator; a JSON-ready dict."""
    from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator

    if threads is not None:
        torch.set_num_threads(int(threads))
    gen = MotionGenerator.from_pretrained(RANDOM_MODEL if random_model else model, device=device)
    gen.encode_text([BENCH_TEXT])  # load the text encoder outside the timings
    results: dict[str, Any] = {
        "model": gen.name,
        "untrained": gen.untrained,
        "device": str(device),
        "hardware": hardware(),
        "parameters": gen.num_parameters(),
        "clip_latency_ms": calibrated(time_clip, gen, runs, num_frames),
        "stream": [calibrated(time_stream, gen, b, stream_frames) for b in batch_sizes],
        "stream_lookahead_frames": gen.path_horizon,
        "control_delay_frames": gen.rate,
    }
    if torch.device(device).type == "cpu":  # the numpy backend runs on the CPU only
        results["controller"] = [
            calibrated(time_controller, gen, b, backend) for b in (1, 64) for backend in ("numpy", "torch")
        ]
        results["gpt"] = [
            calibrated(time_gpt, gen, b, backend) for b in (1, 64) for backend in ("numpy", "torch")
        ]
    agents = bench_agents(gen)
    results["lookahead"] = "head" if "learner_exact" in agents else "exact"
    if env_steps > 0:
        for agent in agents:
            key = "env_step_ms" if agent == "route" else f"env_step_ms_{agent}"
            results[key] = calibrated(time_env, gen, env_steps, agent=agent)
    if vector_steps > 0:
        results["vector_env"] = [
            calibrated(vector_throughput, gen, n, steps=vector_steps, agent=agent)
            for agent in agents
            for n in num_envs
        ]
    return results


def _row(
    label: str,
    median: float,
    tail: float | None,
    unit: str,
    digits: int = 1,
    quiet: tuple[float | None, float | None] = (None, None),
) -> str:
    tail_text = "" if tail is None else f"{tail:.{digits}f}"
    quiet_text, cpu_text = ("" if q is None else f"{q:.{digits}f}" for q in quiet)
    return f"{label:<44}{median:>10.{digits}f}{tail_text:>10}{quiet_text:>12}{cpu_text:>12}{unit:>10}"


def _quiet(result: dict[str, Any], key: str) -> tuple[float | None, float | None]:
    """(wall-time, CPU-time) quiet-machine equivalents of one speed of a result."""
    return result.get("quiet", {}).get(key), result.get("quiet_cpu", {}).get(key)


def format_results(results: dict[str, Any]) -> str:
    """A plain-text table of :func:`run_bench`'s results."""
    hw = results["hardware"]
    head = f"model: {results['model']}{' (UNTRAINED)' if results['untrained'] else ''}"
    head += f"   device: {results['device']}   cpu: {hw['cpu']} x{hw['cpu_count']}"
    head += f", torch threads {hw['torch_threads']}" + (f"   gpu: {hw['gpu']}" if "gpu" in hw else "")
    columns = (
        f"{'measurement':<44}{'median':>10}{'p90/p99':>10}{'quiet equiv.':>12}{'cpu equiv.':>12}{'unit':>10}"
    )
    lines = [head, "", columns]
    c = results["clip_latency_ms"]
    label = f"clip latency ({c['frames']} frames, batch 1, {c['runs']} runs)"
    lines.append(_row(label, c["median"], c["p90"], "ms", quiet=_quiet(c, "median")))
    for s in results["stream"]:
        b = s["batch"]
        lines.append(
            _row(f"stream step, B={b} (mean over frames)", 1000.0 * b / s["frames_per_s"], None, "ms", 2)
        )
        lines.append(
            _row(f"stream step, B={b} (median, p99)", s["step_ms_median"], s["step_ms_p99"], "ms", 2)
        )
        lines.append(
            _row(
                f"stream throughput, B={b}", s["frames_per_s"], None, "frames/s", 0, _quiet(s, "frames_per_s")
            )
        )
    for row in results.get("controller", []):
        label = f"controller roll-out, B={row['batch']}, {row['backend']}"
        lines.append(_row(label, row["ms_per_frame"], None, "ms/frame", 3, _quiet(row, "ms_per_frame")))
    for row in results.get("gpt", []):
        label = f"GPT decoding, B={row['batch']}, {row['backend']}"
        lines.append(_row(label, row["ms_per_token"], None, "ms/token", 3, _quiet(row, "ms_per_token")))
    for agent, label in AGENT_LABELS.items():
        env = results.get("env_step_ms" if agent == "route" else f"env_step_ms_{agent}")
        if env:
            lines.append(
                _row(f"env step, {label} (p99)", env["median"], env["p99"], "ms", 2, _quiet(env, "p99"))
            )
            rate = env.get("steps_per_s", 0.0)
            lines.append(_row(f"env steps/s, {label}", rate, None, "steps/s", 0, _quiet(env, "steps_per_s")))
    for row in results.get("vector_env", []):
        n, agent = row["num_envs"], row.get("agent", "route")
        label = (
            AGENT_LABELS.get(agent, agent)
            .replace("the route", "routes")
            .replace("target each step", "targets")
        )
        # Results of before the steps/frames split have frames only (one frame a step).
        key = "steps_per_s" if "steps_per_s" in row else "frames_per_s"
        lines.append(_row(f"vector env, N={n}, {label}", row[key], None, "steps/s", 0, _quiet(row, key)))
        if row["frames_per_s"] != row[key]:
            lines.append(
                _row(
                    f"vector env, N={n}, {label}",
                    row["frames_per_s"],
                    None,
                    "frames/s",
                    0,
                    _quiet(row, "frames_per_s"),
                )
            )
    lines.append(
        f"streaming: the controller runs {results['stream_lookahead_frames']} frames ahead (paid on the "
        f"first step); a new caption/route acts within {results['control_delay_frames']} frames"
    )
    calib = [r["calibration_ms"] for r in _measurements(results)]
    if calib:
        lines.append(
            f"quiet equiv.: the number on a quiet machine (calibration workload {min(calib):.0f}-"
            f"{max(calib):.0f} ms here beside the measurements, {REFERENCE_CALIBRATION_S * 1000:.0f} ms "
            "when quiet; the p99 column's equivalent for env steps)"
        )
    calib_cpu = [r["calibration_cpu_ms"] for r in _measurements(results) if "calibration_cpu_ms" in r]
    if calib_cpu:
        lines.append(
            f"cpu equiv.: the same from this process's CPU time (calibration {min(calib_cpu):.0f}-"
            f"{max(calib_cpu):.0f} ms of CPU): steadier when the machine has more runnable threads than cores"
        )
    return "\n".join(lines)


def _measurements(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Every calibrated measurement of a results dict."""
    rows = [results.get("clip_latency_ms")] + [v for k, v in results.items() if k.startswith("env_step_ms")]
    rows += list(results.get("stream", [])) + list(results.get("vector_env", []))
    rows += list(results.get("controller", []))
    return [r for r in rows if r and "calibration_ms" in r]
