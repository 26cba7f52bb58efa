"""Captions in: text encoders (captions -> embeddings) and caption mirroring (left <-> right)."""

from motion_env.text.encoders import (
    DEFAULT_TEXT_ENCODER,
    ClipTextEncoder,
    MiniLMEncoder,
    SidedEncoder,
    TextEncoder,
    jitter_embeddings,
    load_text_encoder,
)
from motion_env.text.mirror import mirror_caption

__all__ = [
    "DEFAULT_TEXT_ENCODER",
    "ClipTextEncoder",
    "MiniLMEncoder",
    "SidedEncoder",
    "TextEncoder",
    "jitter_embeddings",
    "load_text_encoder",
    "mirror_caption",
]
