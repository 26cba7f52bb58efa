"""The compiled loops' switch and first use. numba compiles them once per machine (about a minute
for the twenty a clip and an environment use on the 2-core development CPU at half its quiet
speed, 75 s at 0.52x: the path controller's roll-out 10-13 s and its step inputs 1 more, the
GPT's step 3, the placement and the IK 4 each, the body's local pose 3) and keeps them in its
cache; a process that finds no cached copy says so on stderr before it compiles, instead of
pausing without a word.
Without numba (or with ``NUMBA_DISABLE_JIT=1``, which would run the loops as Python, element by
element) the models run numpy's operations instead, the same numbers to float32 rounding."""

from __future__ import annotations

import os
import sys
from typing import Any

__all__ = ["jit_enabled", "note_first_compile"]

_checked: set[str] = set()
_enabled: bool | None = None


def jit_enabled() -> bool:
    """Whether the compiled loops run: numba imports and its JIT is on (checked once a process)."""
    global _enabled
    if _enabled is None:
        if os.environ.get("NUMBA_DISABLE_JIT", "0") not in ("", "0"):
            _enabled = False
        else:
            try:
                import numba  # noqa: F401
            except ImportError:
                _enabled = False
            else:
                _enabled = True
    return _enabled


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
