"""`load_motion`: one entry point for every motion file the package reads."""

from __future__ import annotations

from pathlib import Path

from motion_env.io.bvh import load_bvh
from motion_env.motion.types import Motion

__all__ = ["load_motion"]


def load_motion(path: str | Path) -> Motion:
    """Load a `.npz` written by :meth:`Motion.save`, or any `.bvh` / `.bvh.gz` file."""
    path = Path(path)
    name = path.name.lower()
    if name.endswith((".bvh", ".bvh.gz")):
        return load_bvh(path)
    if name.endswith(".npz"):
        return Motion.load(path)
    raise ValueError(f"{path}: unknown motion file type (expected .npz, .bvh or .bvh.gz)")
