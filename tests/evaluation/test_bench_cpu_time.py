"""The bench's CPU-time equivalents: scaled by the calibration's own CPU time, printed beside the
wall-time ones."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from motion_env.evaluation import bench
from motion_env.evaluation.bench import REFERENCE_CALIBRATION_S, calibrated, calibration_times


def test_calibration_gives_wall_and_cpu_time() -> None:
    wall, cpu = calibration_times()
    assert wall > 0 and cpu > 0
    assert bench.calibration_s() > 0


def test_cpu_equivalents_scale_by_the_cpu_calibration(monkeypatch) -> None:
    times = iter([(0.064, 0.048), (0.064, 0.048)])  # wall 2x, CPU 1.5x the quiet reference
    monkeypatch.setattr(bench, "calibration_times", lambda: next(times))
    measured = {"median": 10.0, "steps_per_s": 50.0, "runs": 3, "cpu": {"median": 8.0, "steps_per_s": 60.0}}
    out = calibrated(lambda: measured)
    assert out["calibration_ms"] == pytest.approx(64.0) and out["calibration_cpu_ms"] == pytest.approx(48.0)
    wall_scale, cpu_scale = REFERENCE_CALIBRATION_S / 0.064, REFERENCE_CALIBRATION_S / 0.048
    assert out["quiet"]["median"] == pytest.approx(10.0 * wall_scale)
    assert out["quiet"]["steps_per_s"] == pytest.approx(50.0 / wall_scale)
    assert out["quiet_cpu"]["median"] == pytest.approx(8.0 * cpu_scale)
    assert out["quiet_cpu"]["steps_per_s"] == pytest.approx(60.0 / cpu_scale)
    assert "runs" not in out["quiet"]


def test_each_run_is_scaled_by_the_calibrations_on_its_two_sides(monkeypatch) -> None:
    """A calibration between runs: a run is scaled by the two beside it, not every run by the
    pair around the whole measurement (here that pair alone says a quiet machine)."""
    calibrations = iter([(0.032, 0.016), (0.064, 0.032), (0.064, 0.032), (0.032, 0.016)])
    monkeypatch.setattr(bench, "calibration_times", lambda: next(calibrations))
    ticks = iter([(0.0, 0.0), (0.010, 0.005), (1.0, 1.0), (1.010, 1.005), (2.0, 2.0), (2.010, 2.005)])
    monkeypatch.setattr(bench, "_clock", lambda: next(ticks))  # every run 10 ms (5 ms of CPU)
    generator = SimpleNamespace(generate=lambda *args, **kwargs: None)
    out = calibrated(bench.time_clip, generator, runs=3, warmup=0)
    assert out["median"] == pytest.approx(10.0) and out["cpu"]["median"] == pytest.approx(5.0)
    # the runs lie between calibrations of 32 | 64, 64 | 64 and 64 | 32 ms
    quiet = sorted(10.0 * REFERENCE_CALIBRATION_S / c for c in (0.048, 0.064, 0.048))
    assert out["quiet"]["min"] == pytest.approx(quiet[0])
    assert out["quiet"]["median"] == pytest.approx(quiet[1])
    assert out["quiet_cpu"]["median"] == pytest.approx(5.0 * REFERENCE_CALIBRATION_S / 0.024)
    assert out["calibration_ms"] == pytest.approx(48.0) and out["calibration_cpu_ms"] == pytest.approx(24.0)


def test_many_steps_are_timed_in_parts_that_cover_them_all() -> None:
    for steps in (1, 3, 5, 8, 500):
        parts = [bench._part_of(step, steps) for step in range(steps)]
        assert parts == sorted(parts) and set(parts) == set(range(min(bench.PARTS, steps)))


def test_table_prints_both_equivalents() -> None:
    clip = {"median": 300.0, "p90": 320.0, "runs": 10, "frames": 200, "calibration_ms": 64.0}
    clip.update(calibration_cpu_ms=40.0, quiet={"median": 150.0}, quiet_cpu={"median": 180.0})
    results = {
        "model": "m",
        "untrained": False,
        "device": "cpu",
        "hardware": {"cpu": "x86_64", "cpu_count": 2, "torch_threads": 1},
        "clip_latency_ms": clip,
        "stream": [],
        "stream_lookahead_frames": 20,
        "control_delay_frames": 4,
    }
    text = bench.format_results(results)
    assert "cpu equiv." in text and "180.0" in text and "150.0" in text
    assert "calibration 40-40 ms of CPU" in text


def test_exact_look_ahead_is_timed_beside_the_head(random_generator) -> None:
    """With a look-ahead head the learner is also timed with the exact look-ahead (before/after in
    one run), and the table prints both."""
    assert bench.bench_agents(random_generator) == ["route", "learner", "learner_4"]
    random_generator.pipeline.lookahead = object()  # any head
    try:
        assert bench.bench_agents(random_generator) == ["route", "learner", "learner_4", "learner_exact"]
    finally:
        random_generator.pipeline.lookahead = None
    env = {"median": 1.0, "p99": 9.0, "steps_per_s": 100.0, "calibration_ms": 32.0}
    results = {
        "model": "m", "untrained": False, "device": "cpu",
        "hardware": {"cpu": "x86_64", "cpu_count": 2, "torch_threads": 1},
        "clip_latency_ms": {"median": 1.0, "p90": 1.0, "runs": 1, "frames": 200},
        "stream": [], "stream_lookahead_frames": 20, "control_delay_frames": 4,
        "env_step_ms_learner": env, "env_step_ms_learner_exact": {**env, "steps_per_s": 50.0},
        "vector_env": [{"num_envs": 64, "frames_per_s": 900.0, "agent": "learner_exact"}],
    }  # fmt: skip
    text = bench.format_results(results)
    assert "env steps/s, new target each step, exact look-ahead" in text
    assert "vector env, N=64, new targets, exact look-ahead" in text


@pytest.mark.parametrize(
    ("timer", "model", "switch", "key", "label"),
    [
        (bench.time_controller, "controller", "frame_backend", "ms_per_frame", "controller roll-out"),
        (bench.time_gpt, "gpt", "step_backend", "ms_per_token", "GPT decoding"),
    ],
)
def test_a_model_is_timed_on_both_backends(random_generator, timer, model, switch, key, label) -> None:
    """The controller's roll-out and the GPT's decoding alone, numpy and torch (where "auto"
    switches), the backend setting left as it was, and a row per backend and size in the table."""
    rows = [timer(random_generator, 2, backend, 4, runs=1) for backend in ("numpy", "torch")]
    assert [r["backend"] for r in rows] == ["numpy", "torch"] and all(r[key] > 0 for r in rows)
    assert getattr(getattr(random_generator.pipeline, model), switch) == "auto"
    results = {
        "model": "m", "untrained": False, "device": "cpu",
        "hardware": {"cpu": "x86_64", "cpu_count": 2, "torch_threads": 1},
        "clip_latency_ms": {"median": 1.0, "p90": 1.0, "runs": 1, "frames": 200},
        "stream": [], "stream_lookahead_frames": 20, "control_delay_frames": 4,
        model: [{**r, "calibration_ms": 32.0, "quiet": {key: 0.5}} for r in rows],
    }  # fmt: skip
    text = bench.format_results(results)
    assert f"{label}, B=2, numpy" in text and f"{label}, B=2, torch" in text
