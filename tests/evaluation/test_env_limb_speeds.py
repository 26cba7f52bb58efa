"""scripts/env_limb_speeds.py on the untrained test model: one short episode, its speeds printed."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "env_limb_speeds.py"


def test_prints_the_speeds_of_an_episode() -> None:
    argv = [sys.executable, str(SCRIPT), "--weights", "random", "--seeds", "1", "--steps", "12"]
    out = subprocess.run(argv, check=True, capture_output=True, text=True, timeout=300).stdout
    line = re.search(r"env, seed 0 \((\d+) frames\): pelvis median ([\d.]+) m/s; .* max ([\d.]+) m/s", out)
    assert line is not None, out
    assert int(line.group(1)) == 13 and float(line.group(3)) >= 0.0
