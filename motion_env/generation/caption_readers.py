"""Caption readers: what reads a caption for the generator's models, picked by ``caption_reader=``.

A *caption reader* is a text encoder plus the *caption adapter* trained for it
(:mod:`motion_env.models.caption_adapter`): the encoder embeds the caption, the adapter moves the
embedding to where the GPT and the controller answer with its meaning. A weights folder holds its
readers as adapter files, named for the reader: ``caption_adapter.pt`` (the ``"default"`` reader)
and ``caption_adapter.<name>.pt`` (the shipped model: ``mpnet``, on the optional all-mpnet-base-v2
encoder). An adapter records the encoder it reads (``config.encoder``), and that encoder is loaded
by name (:func:`motion_env.text.encoders.load_text_encoder`), so a new reader needs no code here:
train an adapter for any known encoder (``motion-env train caption-adapter --encoder clip``) and put
it into the folder as ``caption_adapter.<name>.pt`` (docs/captions.md).
:meth:`MotionGenerator.from_pretrained(caption_reader=...)
<motion_env.generation.generator.MotionGenerator.from_pretrained>` picks one; ``"none"`` picks
none (the models read their own encoder's embedding, as they were trained).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from motion_env.models.caption_adapter import CaptionAdapter, CaptionAdapterConfig
from motion_env.models.checkpoint import load_checkpoint

__all__ = ["ADAPTER_FILE", "caption_readers", "load_caption_reader"]

ADAPTER_FILE = "caption_adapter.pt"  # the adapter of the default reader; optional


def caption_readers(folder: str | Path) -> list[str]:
    """The caption readers `folder` offers: ``"default"`` for ``caption_adapter.pt``, the ``<name>``
    of each ``caption_adapter.<name>.pt``, and ``"none"``."""
    folder = Path(folder)
    names = ["default"] if (folder / ADAPTER_FILE).is_file() else []
    names += sorted(
        f.name[len("caption_adapter.") : -len(".pt")] for f in folder.glob("caption_adapter.*.pt")
    )
    return [*names, "none"]


def _reader_path(folder: Path, reader: str | None) -> Path | None:
    if reader is None:
        return folder / ADAPTER_FILE if (folder / ADAPTER_FILE).is_file() else None
    if reader == "none":
        return None
    path = folder / (ADAPTER_FILE if reader == "default" else f"caption_adapter.{reader}.pt")
    if not path.is_file():
        raise FileNotFoundError(
            f"{folder} has no caption reader {reader!r} ({path.name}); "
            f"it offers: {', '.join(caption_readers(folder))}"
        )
    return path


def load_caption_reader(
    folder: Path,
    reader: str | None,
    models_encoder: str | None = None,
    text_encoder: Any = None,
    device: Any = "cpu",
) -> tuple[CaptionAdapter | None, dict[str, Any] | None]:
    """The caption adapter of the caption reader `reader` in `folder`, and its checkpoint ((None,
    None): no adapter). The reader's text encoder is the one the adapter names (``config.encoder``).

    Args:
        reader: None (the default reader when there is one), ``"none"``, ``"default"`` or a name.
        models_encoder: the text encoder the folder's GPT and controller were trained with; the
            adapter must put out their embeddings (None: not checked).
        text_encoder: an encoder the caller wants to use; it must be the one the adapter reads.
    """
    path = _reader_path(folder, reader)
    if path is None:
        return None, None
    adapter, ckpt = load_checkpoint(path, "caption_adapter", CaptionAdapterConfig, CaptionAdapter, device)
    target = (ckpt.get("text_encoder") or {}).get("name")
    if models_encoder is not None and target != models_encoder:
        raise ValueError(
            f"{path} adapts captions for models trained with {target!r}, "
            f"these were trained with {models_encoder!r}"
        )
    if text_encoder is not None and text_encoder.name != adapter.config.encoder:
        raise ValueError(
            f"{path} reads captions with {adapter.config.encoder!r}, but {text_encoder.name!r} was given"
        )
    return adapter, ckpt
