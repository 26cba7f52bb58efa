"""Fixtures of the studio tests: the shipped generator, loaded once for the folder."""

from __future__ import annotations

from pathlib import Path

import pytest

WEIGHTS = Path(__file__).resolve().parents[2] / "motion_env" / "weights" / "gpt.pt"


@pytest.fixture(scope="session")
def generator():
    """The shipped generator (skips where the weights are not packaged)."""
    if not WEIGHTS.is_file():
        pytest.skip("the shipped weights are not in motion_env/weights")
    from motion_env.generation.generator import MotionGenerator

    return MotionGenerator.from_pretrained()
