"""Generation: one pipeline (caption + route -> motion) and its two drivers, whole clips and the stream.

- :mod:`.request`: a request checked once at the boundary (numpy only);
- :mod:`.pipeline`: the models and the stages; :mod:`.recompose`, :mod:`.feet`: the closed-form ones;
- :mod:`.generator`: :class:`MotionGenerator`, whole clips (and loading/saving the weights);
- :mod:`.streaming`: :class:`MotionStream`, the same stages one token at a time.

The torch-heavy names are imported on first use, so ``import motion_env`` (which registers the
environments, whose input checks live in :mod:`.request`) does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["MotionGenerator", "MotionStream", "SamplingConfig"]

_LAZY = {
    "MotionGenerator": "motion_env.generation.generator",
    "MotionStream": "motion_env.generation.streaming",
    "SamplingConfig": "motion_env.models.sampling",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'motion_env.generation' has no attribute {name!r}")
