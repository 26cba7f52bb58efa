"""scripts/bench_device.py on the CPU at tiny sizes: every measurement lands in its JSON file, a
broken path is recorded with its traceback instead of ending the run, and the budget skips."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_device.py"
TINY = ["--device", "cpu", "--batch-sizes", "2", "--num-envs", "2", "--env-steps", "3", "--clip-runs", "1"]


def _run(tmp_path: Path, *extra: str) -> dict:
    out = tmp_path / "bench.json"
    subprocess.run([sys.executable, str(SCRIPT), *TINY, "--json", str(out), *extra], check=True, timeout=300)
    return json.loads(out.read_text())


def test_every_measurement_is_written(tmp_path) -> None:
    results = _run(tmp_path)
    for name in ("smoke_clip", "clip", "stream_2", "env_route", "vector_2_learner_4", "profile_2_learner_4"):
        assert name in results and "error" not in results[name], name
    assert results["clip"]["runs"] == 1 and results["vector_2_route"]["num_envs"] == 2
    assert "cpu_clip" not in results  # the same machine's CPU is measured only beside another device
    assert "motion_env" in results["profile_2_learner_4"]["profile"]  # the 30 costliest functions


def test_past_the_budget_only_the_smoke_runs(tmp_path) -> None:
    results = _run(tmp_path, "--budget", "0")
    assert "smoke_clip" in results and "smoke_vector_learner_4" in results
    assert "clip" not in results and "stream_2" not in results
