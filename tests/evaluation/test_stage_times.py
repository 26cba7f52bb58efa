"""scripts/stage_times.py on the untrained test model: a few steps of one env and of the vector
env, every stage's row printed."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "stage_times.py"


@pytest.mark.parametrize("envs", [1, 3])
def test_prints_each_stage_per_token(envs: int) -> None:
    argv = [sys.executable, str(SCRIPT), "--weights", "random", "--agent", "learner_4", "--steps", "6"]
    out = subprocess.run(
        [*argv, "--num-envs", str(envs)], check=True, capture_output=True, text=True, timeout=300
    ).stdout
    head = re.search(rf"learner_4, {envs} env\(s\): 6 steps, (\d+) tokens", out)
    assert head is not None and int(head.group(1)) >= 6, out
    token = re.search(r"token \(all stages\)\s+([\d.]+)", out)
    gpt = re.search(r"GPT step\s+([\d.]+)\s+([\d.]+)", out)
    assert token is not None and gpt is not None, out
    assert 0.0 < float(gpt.group(1)) < float(token.group(1))  # a stage inside the token, counted
    assert float(gpt.group(2)) == 1.0  # one GPT step a token at four frames a step (every env at once)


def test_rejects_bad_counts() -> None:
    argv = [sys.executable, str(SCRIPT), "--weights", "random", "--num-envs", "0"]
    run = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert run.returncode == 2 and "--num-envs must be >= 1, got 0" in run.stderr
