"""Checkpoints: one self-describing file per model, rebuilt from the file alone.

A checkpoint is a plain dict ``{"format_version", "kind", "config": asdict(config), "model":
state_dict, ...extra}`` saved with :func:`torch.save` and read back with
``torch.load(..., weights_only=True)``, so only tensors and plain Python containers are ever
unpickled. ``extra`` carries what resuming needs (optimizer state, step) or what a consumer must
check (the text encoder record, see :func:`text_encoder_record`).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import asdict, fields, is_dataclass
from pathlib import Path
from typing import Any, TypeVar

import torch
from torch import nn

FORMAT_VERSION = 1

ModelT = TypeVar("ModelT", bound=nn.Module)


def atomic_torch_save(obj: Any, path: str | Path) -> Path:
    """`torch.save` to a temporary file next to `path`, then rename it over `path`.

    A reader (or a crash mid-write) never sees a half-written checkpoint.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        torch.save(obj, tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def save_checkpoint(
    path: str | Path,
    *,
    kind: str,
    config: Any,
    model: nn.Module,
    half: bool = False,
    **extra: Any,
) -> Path:
    """Write `model` and its config dataclass to `path` (atomically).

    Args:
        path: destination file (parent folders are created).
        kind: what the file holds ("vqvae", "gpt", ...); checked again by :func:`load_checkpoint`.
        config: the model's config dataclass; stored as a plain dict.
        model: the module whose ``state_dict`` is stored (moved to CPU).
        half: store floating-point weights as float16 (for shipping: half the size; they are
            cast back to float32 on load). Leave False for training checkpoints.
        extra: anything else torch can save with ``weights_only`` loading: plain containers,
            numbers, strings, tensors (optimizer state, step, metrics, text encoder record).
    """
    if not is_dataclass(config) or isinstance(config, type):
        raise TypeError(f"config must be a dataclass instance, got {type(config).__name__}")
    reserved = {"format_version", "kind", "config", "model"} & set(extra)
    if reserved:
        raise ValueError(f"extra keys {sorted(reserved)} are reserved by the checkpoint format")
    state = {}
    for name, tensor in model.state_dict().items():
        tensor = tensor.detach().cpu()
        if half and tensor.is_floating_point():
            tensor = tensor.half()
        state[name] = tensor
    ckpt = {"format_version": FORMAT_VERSION, "kind": kind, "config": asdict(config), "model": state}
    ckpt.update(extra)
    return atomic_torch_save(ckpt, path)


def read_checkpoint(path: str | Path, kind: str | None = None) -> dict[str, Any]:
    """Read a checkpoint dict (weights-only unpickling) and check its format and kind."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint at {path}")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises several types for corrupt or foreign files
        raise ValueError(f"{path}: not a readable checkpoint ({exc})") from exc
    if not isinstance(ckpt, dict) or "format_version" not in ckpt or "config" not in ckpt:
        raise ValueError(f"{path}: not a motion_env checkpoint (no 'format_version'/'config' keys)")
    version = ckpt["format_version"]
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ValueError(
            f"{path}: checkpoint format_version {version!r} is newer than this motion_env "
            f"supports ({FORMAT_VERSION}); upgrade motion_env"
        )
    if kind is not None and ckpt.get("kind") != kind:
        raise ValueError(f"{path}: holds a {ckpt.get('kind')!r} checkpoint, expected {kind!r}")
    return ckpt


def config_from_dict(config_cls: type, data: dict[str, Any]) -> Any:
    """Rebuild a config dataclass from its stored dict; unknown keys are an error."""
    names = {f.name for f in fields(config_cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        raise ValueError(f"{config_cls.__name__} has no fields {unknown} (checkpoint from another version?)")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    return config_cls(**values)


def load_checkpoint(
    path: str | Path,
    kind: str,
    config_cls: type,
    model_cls: type[ModelT],
    device: str | torch.device = "cpu",
) -> tuple[ModelT, dict[str, Any]]:
    """Rebuild a model from a checkpoint written by :func:`save_checkpoint`.

    Returns:
        (model, ckpt): the model in eval mode, float32, on `device`; ckpt is the whole stored dict
        (``ckpt["config"]`` is the plain dict, extra keys as saved).
    """
    ckpt = read_checkpoint(path, kind)
    config = config_from_dict(config_cls, ckpt["config"])
    model = model_cls(config)
    state = {k: v.float() if v.is_floating_point() else v for k, v in ckpt["model"].items()}
    try:
        model.load_state_dict(state)
    except RuntimeError as exc:
        raise ValueError(f"{path}: weights do not match {model_cls.__name__}({config}): {exc}") from exc
    return model.to(device).eval(), ckpt


def text_encoder_record(encoder: Any) -> dict[str, Any]:
    """What a checkpoint stores about the text encoder it was trained with: its name and width."""
    return {"name": str(encoder.name), "dim": int(encoder.dim)}


def check_text_encoder(ckpt: dict[str, Any], encoder: Any, path: str | Path = "checkpoint") -> None:
    """Raise a clear ValueError when `encoder` is not the one the checkpoint was trained with."""
    record = ckpt.get("text_encoder")
    if record is None:
        raise ValueError(f"{path}: no 'text_encoder' record; cannot tell which text encoder it needs")
    if record.get("name") != encoder.name or int(record.get("dim", -1)) != int(encoder.dim):
        raise ValueError(
            f"{path} was trained with text encoder {record.get('name')!r} ({record.get('dim')}-d), "
            f"but {encoder.name!r} ({encoder.dim}-d) was given; load it with "
            f"load_text_encoder({record.get('name')!r})"
        )


def training_record(ckpt: dict[str, Any]) -> dict[str, Any]:
    """What a checkpoint says about its training (a training checkpoint's own keys, or the record
    a packaged one carries), as plain numbers and strings."""
    if isinstance(ckpt.get("training"), dict):
        return ckpt["training"]
    record: dict[str, Any] = {}
    for key in ("step", "metrics", "settings", "vqvae"):
        value = ckpt.get(key)
        if isinstance(value, int | float | str):
            record[key] = value
        elif isinstance(value, dict):
            record[key] = {str(k): v for k, v in value.items() if isinstance(v, int | float | str)}
    return record


def export_checkpoint(src: str | Path, dst: str | Path, half: bool = True) -> Path:
    """Copy a training checkpoint for shipping: without the optimizer state, weights as float16.

    Everything else (config, step, metrics, text encoder record, normalisation stats) is kept.
    """
    ckpt = read_checkpoint(src)
    out = {k: v for k, v in ckpt.items() if k != "optimizer"}
    if half:
        out["model"] = {k: v.half() if v.is_floating_point() else v for k, v in ckpt["model"].items()}
    return atomic_torch_save(out, dst)
