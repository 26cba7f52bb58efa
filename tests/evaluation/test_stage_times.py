"""scripts/stage_times.py on the untrained test model: a few steps, every stage's row printed."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "stage_times.py"


def test_prints_each_stage_per_token() -> None:
    argv = [sys.executable, str(SCRIPT), "--weights", "random", "--agent", "learner_4", "--steps", "6"]
    out = subprocess.run(argv, check=True, capture_output=True, text=True, timeout=300).stdout
    head = re.search(r"learner_4: 6 steps, (\d+) tokens", out)
    assert head is not None and int(head.group(1)) >= 6, out
    token = re.search(r"token \(all stages\)\s+([\d.]+)", out)
    gpt = re.search(r"GPT step\s+([\d.]+)\s+([\d.]+)", out)
    assert token is not None and gpt is not None, out
    assert 0.0 < float(gpt.group(1)) < float(token.group(1))  # a stage inside the token, counted
    assert float(gpt.group(2)) == 1.0  # one GPT step a token at four frames a step
