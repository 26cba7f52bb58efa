"""The shipped weights folder stays within its budget: 30 MB of weights and data (the model card aside)."""

from __future__ import annotations

from motion_env.generation.generator import DEFAULT_WEIGHTS

BUDGET = 30_000_000  # bytes


def test_the_shipped_weights_fit_the_budget() -> None:
    files = [p for p in DEFAULT_WEIGHTS.iterdir() if p.is_file() and p.suffix != ".md"]
    total = sum(p.stat().st_size for p in files)
    largest = sorted(files, key=lambda p: p.stat().st_size)[-3:]
    names = [p.name for p in largest]
    assert total <= BUDGET, f"weights folder holds {total:,} bytes > {BUDGET:,}; largest: {names}"
