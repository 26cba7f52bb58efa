"""scripts/measure_standing_sway.py on a synthetic dataset of still takes and the untrained model."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "measure_standing_sway.py"


def _still(frames: int) -> np.ndarray:
    """The rest pose standing still, its feet on the floor: (frames, 22, 3)."""
    from motion_env.motion.kinematics import bone_offsets, forward_kinematics

    pos = np.zeros((frames, 3))
    pos[:, 1] = -float(bone_offsets()[[2, 5, 8], 1].sum())
    rots = np.zeros((frames, 22, 4))
    rots[..., 0] = 1.0
    return forward_kinematics(pos, rots)


def test_prints_the_sway_of_made_and_real_takes(tmp_path: Path, write_labelled_dataset) -> None:
    takes = [
        (f"dataset-1_wave-right-hand_normal_{k:03d}", "test", "wave-right-hand", "normal", _still(25))
        for k in range(3)
    ]
    data = write_labelled_dataset(tmp_path, takes)
    argv = [sys.executable, str(SCRIPT), "--data", str(data), "--weights", "random", "--seeds", "1"]
    out = subprocess.run(argv, check=True, capture_output=True, text=True, timeout=300).stdout
    made = re.search(
        r"made again +3 clips: pelvis horizontal .* median ([\d.]+), 90th percentile ([\d.]+) m/s\^2", out
    )
    real = re.search(
        r"real takes +3 clips: pelvis vertical .* median ([\d.]+), 90th percentile ([\d.]+) m/s\^2", out
    )
    assert made is not None and real is not None, out
    assert float(real.group(1)) == 0.0  # the real takes stand still: no bob
    assert float(made.group(2)) >= float(made.group(1)) >= 0.0
