"""The base of the text encoders: captions checked, embedded in batches, cached per caption.

Every encoder (:mod:`motion_env.text.encoders`, the optional CLIP one in :mod:`motion_env.text.clip`)
subclasses :class:`TextEncoder` and implements ``_embed``; this module is what they share, so an
encoder module never needs the registry that loads encoders by name.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from motion_env.text.cache import EmbeddingCache

__all__ = ["TextEncoder", "check_captions"]


def check_captions(texts: Sequence[str]) -> list[str]:
    """N captions -> the N stripped captions; TypeError / ValueError naming the bad one."""
    if isinstance(texts, str):
        raise TypeError("encode() takes a list of captions, not a single string")
    out = []
    for i, text in enumerate(texts):
        if not isinstance(text, str):
            raise TypeError(f"caption {i} is {type(text).__name__}, expected str")
        if not text.strip():
            raise ValueError(f"caption {i} is empty; every caption needs some text")
        out.append(text.strip())
    return out


class TextEncoder:
    """Base of the text encoders: a per-caption cache around a batched `_embed`.

    Attributes:
        name: short identifier stored in checkpoints ("minilm", "clip").
        dim: embedding width.
    """

    name: str = ""
    dim: int = 0

    def __init__(self, device: str | torch.device = "cpu") -> None:
        self.device = torch.device(device)
        self._cache: dict[str, torch.Tensor] = {}
        self._disk: EmbeddingCache | None = None
        self._disk_threads = -1

    def _embed(self, texts: list[str]) -> torch.Tensor:
        raise NotImplementedError

    def cache_namespace(self) -> str | None:
        """What an embedding on disk must have been computed with to be reused here (see
        :mod:`motion_env.text.cache`); None: this encoder's embeddings are not kept on disk."""
        return None

    def disk_cache(self) -> EmbeddingCache | None:
        """The on-disk cache of this encoder's single-caption embeddings (None: not cached)."""
        threads = torch.get_num_threads()
        if self._disk is None or threads != self._disk_threads:
            namespace = self.cache_namespace()
            self._disk_threads = threads
            self._disk = None if namespace is None else EmbeddingCache(f"{namespace}-t{threads}", self.dim)
        return self._disk

    def _normalized(self, texts: list[str]) -> torch.Tensor:
        emb = self._embed(texts).detach().float().cpu()
        emb = torch.nn.functional.normalize(emb, dim=-1)
        if emb.shape != (len(texts), self.dim):
            raise RuntimeError(
                f"{self.name} returned embeddings of shape {tuple(emb.shape)}, "
                f"expected ({len(texts)}, {self.dim})"
            )
        return emb

    def _embed_one(self, text: str) -> torch.Tensor:
        """One caption's embedding: from the disk cache, or encoded alone (and then stored)."""
        disk = self.disk_cache()
        row = None if disk is None else disk.get(text)
        if row is not None:
            return torch.from_numpy(row)
        emb = self._normalized([text])[0]
        if disk is not None:
            disk.put(text, emb.numpy())
        return emb

    @torch.no_grad()
    def encode(self, texts: Sequence[str]) -> torch.Tensor:
        """Embed captions.

        Args:
            texts: N non-empty captions (leading/trailing whitespace is ignored).

        Returns:
            (N, dim) float32 CPU tensor, each row L2-normalised. Repeated captions are served
            from a cache, so a caption is embedded once per encoder. A call with one new caption
            also looks it up on disk (and stores it there), see :mod:`motion_env.text.cache`.
        """
        texts = check_captions(texts)
        missing = list(dict.fromkeys(t for t in texts if t not in self._cache))
        if len(missing) == 1:
            self._cache[missing[0]] = self._embed_one(missing[0])
        elif missing:
            for text, row in zip(missing, self._normalized(missing), strict=True):
                self._cache[text] = row
        if not texts:
            return torch.zeros(0, self.dim)
        return torch.stack([self._cache[t] for t in texts])
