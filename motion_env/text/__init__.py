"""Captions in: text encoders (captions -> embeddings), their on-disk cache, and caption mirroring
(left <-> right).

Importing the package does not import torch: :func:`mirror_caption` is here at once, the encoders
(:mod:`.encoders`, torch; the optional CLIP one in :mod:`.clip`) load on first use of their names.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from motion_env.text.mirror import mirror_caption

if TYPE_CHECKING:
    from motion_env.text.clip import ClipTextEncoder
    from motion_env.text.encoders import (
        DEFAULT_TEXT_ENCODER,
        TEXT_ENCODERS,
        MiniLMEncoder,
        SidedEncoder,
        TextEncoder,
        jitter_embeddings,
        load_text_encoder,
        register_text_encoder,
    )

__all__ = [
    "DEFAULT_TEXT_ENCODER",
    "ClipTextEncoder",
    "MiniLMEncoder",
    "SidedEncoder",
    "TEXT_ENCODERS",
    "TextEncoder",
    "jitter_embeddings",
    "load_text_encoder",
    "mirror_caption",
    "register_text_encoder",
]

_LAZY = {name: "motion_env.text.encoders" for name in __all__ if name != "mirror_caption"}
_LAZY["ClipTextEncoder"] = "motion_env.text.clip"


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'motion_env.text' has no attribute {name!r}")
