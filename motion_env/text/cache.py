"""An on-disk cache of caption embeddings, so that a caption seen before needs no text encoder.

Loading the MiniLM encoder (sentence-transformers) takes seconds; looking a caption up here takes
well under a millisecond. :class:`motion_env.text.encoders.TextEncoder` uses it for every caption
it embeds on its own (one new caption per call: what ``generate``, the stream and the environments
ask for); a call that embeds many new captions at once (training's caption tables) neither reads
nor writes it, so that the cache never changes a result: an embedding read back here is, bit for
bit, the one the encoder gives for that caption alone.

Where: ``$MOTION_ENV_CACHE/text/`` if that variable is set (``MOTION_ENV_CACHE=off`` turns the
cache off), else ``$XDG_CACHE_HOME/motion_env/text/``, else ``~/.cache/motion_env/text/``. One
folder per encoder *namespace* (the encoder's name, the versions of the packages that compute the
embedding, the device type and torch's thread count: anything that may change the last bit), one
small file per caption (named by the SHA-256 of the caption, which it also holds). Delete the
folder at any time to empty the cache.

A cache that cannot be read or written never breaks generation: an unreadable or corrupt entry is
ignored (and rewritten), an unwritable folder is skipped, and either is reported once per process
with a :class:`RuntimeWarning`.
"""

from __future__ import annotations

import hashlib
import os
import re
import struct
import warnings
from pathlib import Path

import numpy as np

__all__ = ["CACHE_ENV", "EmbeddingCache", "cache_root"]

CACHE_ENV = "MOTION_ENV_CACHE"
_OFF = ("off", "none", "0", "false", "no")
_MAGIC = b"motion_env-embedding-v1\n"
_HEADER = struct.Struct("<II")  # caption bytes, embedding width
_warned: set[str] = set()


def cache_root() -> Path | None:
    """The folder of the motion_env cache (None when ``MOTION_ENV_CACHE=off``)."""
    value = os.environ.get(CACHE_ENV)
    if value is not None and value.strip():
        return None if value.strip().lower() in _OFF else Path(value).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "motion_env"


def _warn_once(kind: str, message: str) -> None:
    if kind not in _warned:
        _warned.add(kind)
        warnings.warn(message, RuntimeWarning, stacklevel=4)


class EmbeddingCache:
    """The cached embeddings of one encoder namespace (see the module docstring).

    Args:
        namespace: what must match for an entry to be reused (encoder name, package versions,
            device, threads); any characters, made safe for a folder name.
        dim: the embedding width; an entry of another width is treated as corrupt.
        root: the cache folder (default: :func:`cache_root`, read on each call, so a change of
            ``MOTION_ENV_CACHE`` takes effect at once).
    """

    def __init__(self, namespace: str, dim: int, root: str | Path | None = None) -> None:
        self.namespace = re.sub(r"[^A-Za-z0-9._+-]", "_", namespace)
        self.dim = int(dim)
        self._root = None if root is None else Path(root)

    def folder(self) -> Path | None:
        """This namespace's folder (None when the cache is off)."""
        root = self._root if self._root is not None else cache_root()
        return None if root is None else root / "text" / self.namespace

    def path(self, text: str) -> Path | None:
        """The file that holds `text`'s embedding (None when the cache is off)."""
        folder = self.folder()
        if folder is None:
            return None
        return folder / (hashlib.sha256(text.encode("utf-8")).hexdigest()[:40] + ".emb")

    def get(self, text: str) -> np.ndarray | None:
        """The cached (dim,) float32 embedding of `text`, or None (not cached, unreadable, corrupt)."""
        path = self.path(text)
        if path is None:
            return None
        try:
            data = path.read_bytes()
        except (FileNotFoundError, NotADirectoryError):  # not cached (or no cache folder yet)
            return None
        except OSError as exc:
            _warn_once("read", f"cannot read the text embedding cache ({exc}); encoding instead")
            return None
        row = self._decode(data, text)
        if row is None:
            _warn_once("corrupt", f"ignored a corrupt entry of the text embedding cache: {path}")
        return row

    def put(self, text: str, row: np.ndarray) -> None:
        """Store `text`'s embedding (a (dim,) float32 row); failures only warn, once."""
        path = self.path(text)
        if path is None:
            return
        row = np.ascontiguousarray(row, dtype="<f4")
        if row.shape != (self.dim,):
            raise ValueError(f"embedding of shape {row.shape}, expected ({self.dim},)")
        caption = text.encode("utf-8")
        data = _MAGIC + _HEADER.pack(len(caption), self.dim) + caption + row.tobytes()
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp.write_bytes(data)
            os.replace(tmp, path)  # atomic: a reader sees the old entry or the new one
        except OSError as exc:
            try:
                tmp.unlink(missing_ok=True)
            except OSError:
                pass
            _warn_once(
                "write",
                f"cannot write the text embedding cache in {path.parent} ({exc}); captions are "
                f"encoded each time (set {CACHE_ENV} to a writable folder, or to 'off')",
            )

    def _decode(self, data: bytes, text: str) -> np.ndarray | None:
        head = len(_MAGIC) + _HEADER.size
        if len(data) < head or not data.startswith(_MAGIC):
            return None
        n_text, dim = _HEADER.unpack_from(data, len(_MAGIC))
        if dim != self.dim or len(data) != head + n_text + 4 * dim:
            return None
        if data[head : head + n_text] != text.encode("utf-8"):
            return None
        row = np.frombuffer(data, dtype="<f4", count=dim, offset=head + n_text).astype(np.float32)
        if not np.isfinite(row).all():
            return None
        return row
