"""The compiled loops' first-use note: one line on stderr when numba's cache has no copy yet."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from motion_env.models import jit_cache


def _dispatcher(name: str, index: Path) -> SimpleNamespace:
    cache = SimpleNamespace(_cache_file=SimpleNamespace(_index_path=str(index)))
    return SimpleNamespace(__qualname__=name, _cache=cache)


def test_a_cold_cache_is_announced_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cold = _dispatcher("test.cold", tmp_path / "missing.nbi")
    jit_cache.note_first_compile(cold, "the cold loop")
    jit_cache.note_first_compile(cold, "the cold loop")
    assert capsys.readouterr().err.count("compiling the cold loop") == 1


def test_a_cached_loop_is_silent(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    index = tmp_path / "there.nbi"
    index.write_text("")
    jit_cache.note_first_compile(_dispatcher("test.warm", index), "the warm loop")
    jit_cache.note_first_compile(SimpleNamespace(__qualname__="test.odd"), "a loop numba lays out otherwise")
    assert capsys.readouterr().err == ""
