"""scripts/measure_stop_gap.py on one short clip of the shipped model, and its bad arguments."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "measure_stop_gap.py"


def test_prints_each_clip_and_the_summary() -> None:
    argv = [sys.executable, str(SCRIPT), "--seeds", "1", "--captions", "a person walks", "--turns", "90"]
    out = subprocess.run(argv + ["--frames", "60"], check=True, capture_output=True, text=True, timeout=300)
    clip = re.search(r"turn  90° seed 0: end gap ([\d.]+) m, closest ([\d.]+) m", out.stdout)
    summary = re.search(
        r"generated: end gap median ([\d.]+) m, largest ([\d.]+) m, (\d) of 1 over", out.stdout
    )
    assert clip is not None and summary is not None, out.stdout
    assert float(clip.group(2)) <= float(clip.group(1))
    assert np.isclose(float(summary.group(1)), float(clip.group(1)), atol=1e-3)


def test_bad_arguments_are_named() -> None:
    for bad, word in ((["--seeds", "0"], "--seeds"), (["--frames", "5"], "--frames")):
        run = subprocess.run([sys.executable, str(SCRIPT), *bad], capture_output=True, text=True, timeout=120)
        assert run.returncode == 2 and word in run.stderr, run.stderr
