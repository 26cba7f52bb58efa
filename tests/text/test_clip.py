"""The optional CLIP encoder on a tiny random open_clip model made here: where its weights are
found (a path, $MOTION_ENV_CLIP_WEIGHTS, open_clip's cache), the error without them, and a
caption reader that reads with it."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path
from typing import Any

import pytest
import torch

from motion_env.text import clip as clip_module
from motion_env.text.clip import CLIP_HUB_REPO, CLIP_WEIGHTS_ENV, ClipTextEncoder, find_clip_weights
from motion_env.text.encoders import load_text_encoder

# A CLIP small enough to make in a test (1.6 M parameters, nearly all the token table); the text
# tower takes open_clip's own tokenizer, so the vocabulary and context stay CLIP's.
TINY = {
    "embed_dim": 16,
    "vision_cfg": {"image_size": 32, "layers": 1, "width": 32, "patch_size": 16, "head_width": 16},
    "text_cfg": {"context_length": 77, "vocab_size": 49408, "width": 32, "heads": 2, "layers": 1},
}
CAPTIONS = ["a person walks forward", "a person waves with the left hand"]


@pytest.fixture(autouse=True)
def _no_user_weights(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Neither the user's $MOTION_ENV_CLIP_WEIGHTS nor their caches take part."""
    monkeypatch.delenv(CLIP_WEIGHTS_ENV, raising=False)
    monkeypatch.setenv("MOTION_ENV_CACHE", str(tmp_path / "motion_env_cache"))
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")


@pytest.fixture(scope="module")
def open_clip() -> Any:
    if importlib.util.find_spec("open_clip") is None:
        pytest.skip("open-clip-torch is not installed (pip install 'motion-env[clip]')")
    return clip_module.import_open_clip()


def _save(model: torch.nn.Module, folder: Path, filename: str, config: dict | None = TINY) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    if filename.endswith(".safetensors"):
        from safetensors.torch import save_file

        save_file({k: v.contiguous() for k, v in model.state_dict().items()}, str(folder / filename))
    else:
        torch.save(model.state_dict(), folder / filename)
    if config is not None:
        (folder / "open_clip_config.json").write_text(json.dumps({"model_cfg": config}))
    return folder / filename


@pytest.fixture(scope="module")
def tiny(open_clip: Any, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, torch.nn.Module]:
    """An open_clip folder (config + .bin) of a random tiny CLIP, and the model."""
    torch.manual_seed(0)
    model = open_clip.CLIP(**TINY).eval()
    folder = tmp_path_factory.mktemp("tiny_clip")
    _save(model, folder, "open_clip_pytorch_model.bin")
    return folder, model


def _expected(open_clip: Any, model: torch.nn.Module, texts: list[str]) -> torch.Tensor:
    with torch.no_grad():
        return torch.nn.functional.normalize(model.encode_text(open_clip.tokenize(texts)), dim=-1)


def test_a_folder_gives_open_clips_text_embedding(open_clip: Any, tiny: tuple[Path, Any]) -> None:
    folder, model = tiny
    encoder = load_text_encoder("clip", weights=folder)
    assert isinstance(encoder, ClipTextEncoder) and encoder.dim == 16
    torch.testing.assert_close(encoder.encode(CAPTIONS), _expected(open_clip, model, CAPTIONS))
    sided = load_text_encoder("clip+sides", weights=folder)
    assert sided.name == "clip+sides" and sided.encode(CAPTIONS).shape == (2, 32)


def test_a_custom_text_clip_in_safetensors(open_clip: Any, tmp_path: Path) -> None:
    torch.manual_seed(1)
    model = open_clip.CustomTextCLIP(**TINY).eval()  # its text tower is stored under "text."
    _save(model, tmp_path / "custom", "open_clip_model.safetensors")
    encoder = ClipTextEncoder(tmp_path / "custom")
    assert encoder.checkpoint.name == "open_clip_model.safetensors"
    torch.testing.assert_close(encoder.encode(CAPTIONS), _expected(open_clip, model, CAPTIONS))


def test_the_environment_variable_names_the_weights(
    tiny: tuple[Path, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    folder, _ = tiny
    monkeypatch.setenv(CLIP_WEIGHTS_ENV, str(folder / "open_clip_pytorch_model.bin"))
    encoder = load_text_encoder("clip")
    assert encoder.checkpoint == folder / "open_clip_pytorch_model.bin" and encoder.dim == 16
    monkeypatch.setenv(CLIP_WEIGHTS_ENV, str(folder / "nothing.bin"))
    with pytest.raises(FileNotFoundError, match=f"\\${CLIP_WEIGHTS_ENV} .*nothing.bin: no such file"):
        load_text_encoder("clip")


def _hub_cache(root: Path, model: torch.nn.Module) -> Path:
    """The Hugging Face cache layout open_clip downloads CLIP_HUB_REPO into."""
    repo = root / ("models--" + CLIP_HUB_REPO.replace("/", "--"))
    (repo / "refs").mkdir(parents=True)
    (repo / "refs" / "main").write_text("0123abcd")
    return _save(model, repo / "snapshots" / "0123abcd", "open_clip_pytorch_model.bin")


def test_open_clips_cache_is_searched(
    open_clip: Any, tiny: tuple[Path, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, model = tiny
    cached = _hub_cache(tmp_path / "hub", model)
    assert ClipTextEncoder(cache_dir=tmp_path / "hub").checkpoint == cached
    import huggingface_hub.constants

    monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_CACHE", str(tmp_path / "hub"))
    encoder = load_text_encoder("clip")  # the user's default cache
    torch.testing.assert_close(encoder.encode(CAPTIONS), _expected(open_clip, model, CAPTIONS))


def test_a_bare_checkpoint_is_the_default_architecture(
    open_clip: Any, tiny: tuple[Path, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No open_clip_config.json: the architecture is CLIP_MODEL (ViT-B-32; a tiny one here)."""
    _, model = tiny
    for name, width in (("motion-env-test-tiny", 32), ("motion-env-test-wider", 48)):
        config = {**TINY, "text_cfg": {**TINY["text_cfg"], "width": width}}
        (tmp_path / f"{name}.json").write_text(json.dumps(config))
        open_clip.add_model_config(tmp_path / f"{name}.json")
    bare = _save(model, tmp_path / "bare", "open_clip_pytorch_model.bin", config=None)
    monkeypatch.setattr(clip_module, "CLIP_MODEL", "motion-env-test-tiny")
    torch.testing.assert_close(ClipTextEncoder(bare).encode(CAPTIONS), _expected(open_clip, model, CAPTIONS))
    monkeypatch.setattr(clip_module, "CLIP_MODEL", "motion-env-test-wider")
    with pytest.raises(ValueError, match="does not fit the text tower .*open_clip_config.json beside it"):
        ClipTextEncoder(bare).encode(CAPTIONS)


def test_without_weights_the_error_says_where_to_put_them(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    empty = tmp_path / "empty_hub"
    empty.mkdir()
    with pytest.raises(FileNotFoundError) as err:
        find_clip_weights(cache_dir=empty)
    message = str(err.value)
    for part in ("never downloads", CLIP_WEIGHTS_ENV, "--encoder-weights", CLIP_HUB_REPO, str(empty)):
        assert part in message
    if importlib.util.find_spec("open_clip") is not None:
        import huggingface_hub.constants

        monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_CACHE", str(empty))
        with pytest.raises(FileNotFoundError, match="never downloads"):
            load_text_encoder("clip")
    with pytest.raises(FileNotFoundError, match="no such file or folder"):
        find_clip_weights(tmp_path / "missing.bin")


def test_without_open_clip_the_error_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a: None if n == "open_clip" else real(n, *a))
    with pytest.raises(ImportError, match="motion-env\\[clip\\]"):
        ClipTextEncoder()


def test_open_clip_imports_without_torchvision(open_clip: Any) -> None:
    if importlib.util.find_spec("torchvision") is not None:
        pytest.skip("torchvision is installed: open_clip imports it as usual")
    assert "torchvision" not in sys.modules  # the stand-ins are gone again
    with pytest.raises(ImportError, match="torchvision is not installed"):
        open_clip.transform.ToTensor()


def test_a_caption_reader_on_clip(
    tiny: tuple[Path, Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An adapter trained for clip, saved as caption_adapter.clip.pt, is the caption reader "clip"."""
    from motion_env.generation.caption_readers import ADAPTER_FILE, caption_readers
    from motion_env.generation.generator import MotionGenerator
    from motion_env.models.caption_adapter import CaptionAdapter, CaptionAdapterConfig

    folder, _ = tiny
    monkeypatch.setenv(CLIP_WEIGHTS_ENV, str(folder))
    gen = MotionGenerator.random()
    gen.caption_adapter = CaptionAdapter(
        CaptionAdapterConfig(in_dim=16, out_dim=384, hidden=8, encoder="clip")
    )
    weights = gen.save(tmp_path / "weights")
    (weights / ADAPTER_FILE).rename(weights / "caption_adapter.clip.pt")
    assert caption_readers(weights) == ["clip", "none"]
    back = MotionGenerator.from_pretrained(weights, caption_reader="clip")
    assert back.pipeline.reader_name == "clip"
    assert back.encode_text(CAPTIONS).shape == (2, 384)
    assert back.pipeline.text_encoder.name == "clip"
