"""scripts/compare_calibration.py on the untrained test model: both ways' rows printed."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "compare_calibration.py"


def test_prints_both_ways_of_scaling() -> None:
    argv = [sys.executable, str(SCRIPT), "--weights", "random", "--repeats", "2", "--runs", "2"]
    out = subprocess.run(argv, check=True, capture_output=True, text=True, timeout=300).stdout
    for name in ("raw \\(wall time\\)", "one calibration before and after", "a calibration between runs"):
        row = re.search(rf"{name}\s+median\s+([\d.]+)\s+range\s+([\d.]+)-\s*([\d.]+)", out)
        assert row is not None, out
        median, low, high = (float(x) for x in row.groups())
        assert 0.0 < low <= median <= high


def test_rejects_bad_counts() -> None:
    run = subprocess.run(
        [sys.executable, str(SCRIPT), "--weights", "random", "--runs", "0"], capture_output=True, text=True
    )
    assert run.returncode == 2 and "--runs must be >= 1, got 0" in run.stderr
