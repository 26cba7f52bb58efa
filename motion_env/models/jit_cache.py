"""The compiled loops' first use: numba compiles them once per machine (about 13 s for the path
controller's and the GPT's together on the 2-core development CPU) and keeps them in its cache;
a process that finds no cached copy says so on stderr before it compiles, instead of pausing
without a word."""

from __future__ import annotations

import os
import sys
from typing import Any

__all__ = ["note_first_compile"]

_checked: set[str] = set()


def note_first_compile(dispatcher: Any, what: str) -> None:
    """Write one line to stderr when numba's cache holds no copy of `dispatcher` (a jitted
    function) yet, so that `what` is compiled now; checked once a process, silent otherwise."""
    name = getattr(dispatcher, "__qualname__", what)
    if name in _checked:
        return
    _checked.add(name)
    try:
        index = dispatcher._cache._cache_file._index_path  # numba's private layout: best effort
    except AttributeError:
        return
    if not os.path.exists(index):
        print(f"motion_env: compiling {what} for this machine (once; numba caches it)", file=sys.stderr)
