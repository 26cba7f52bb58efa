"""The caption adapter's trainer on a tiny labelled index (text only): examples, targets, resuming."""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.checkpoint import read_checkpoint
from motion_env.text.encoders import TextEncoder
from motion_env.training.caption_adapter import (
    CHECKPOINT_KIND,
    CaptionAdapterTrainConfig,
    adapter_examples,
    canonical_style,
    encode_all,
    label_table,
    labelled_pairs,
    prototype,
    train_caption_adapter,
)

HEADER = "name,split,source,take,label,style,mirrored,frames,file\n"


def _index(root: Path, rows: list[str], cmu_caption: str = "a man plays basketball") -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / "index.csv").write_text(HEADER + "".join(r + "\n" for r in rows))
    (root / "texts").mkdir(exist_ok=True)
    (root / "texts" / "01_01.txt").write_text(f"{cmu_caption}#a/DET#0.0#0.0\n")
    return root


def _labelled(tmp_path: Path) -> Path:
    return _index(tmp_path / "data", [
        "dataset-2_walk_normal_001,train,bandai,t1,walk,normal,0,80,f",
        "dataset-2_run_active_001,train,bandai,t2,run,active,0,80,f",
        "dataset-1_walk_old_001,train,bandai,t3,walk,old,0,80,f",
        "dataset-1_bow_sad_001,val,bandai,t4,bow,sad,0,80,f",
        "01_01,train,cmu,01_01,walk,,0,80,f",
    ])  # fmt: skip


def test_pairs_use_the_canonical_style_names(tmp_path: Path) -> None:
    assert canonical_style("old") == "elderly" and canonical_style("active") == "active"
    assert labelled_pairs(_labelled(tmp_path)) == {
        ("run", "active"): 1,
        ("walk", "elderly"): 1,
        ("walk", "normal"): 1,
    }


def test_an_index_without_bandai_labels_is_refused(tmp_path: Path) -> None:
    root = _index(tmp_path / "cmu", ["01_01,train,cmu,01_01,walk,,0,80,f"])
    with pytest.raises(ValueError, match="no Bandai Namco takes with labels"):
        labelled_pairs(root)
    with pytest.raises(FileNotFoundError, match="no index.csv"):
        labelled_pairs(tmp_path / "nowhere")


def test_prototype_keeps_the_sentence_half_unit_length() -> None:
    emb = torch.tensor([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 1.0, 0.0]])
    p = prototype(emb, sides=True)
    torch.testing.assert_close(p[:2].norm(), torch.tensor(1.0))
    torch.testing.assert_close(p[2:], torch.tensor([1.0, 0.0]))
    torch.testing.assert_close(prototype(emb[:, :2], sides=False).norm(), torch.tensor(1.0))


def test_examples_map_labelled_captions_to_their_prototype_and_the_rest_to_themselves(
    tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    enc = hash_text()
    table = label_table(_labelled(tmp_path), enc)
    assert table.actions == ["run", "walk"] and table.styles == ["active", "elderly", "normal"]
    assert table.prototypes.shape == (3, 8)
    ex = adapter_examples(_labelled(tmp_path), table, enc, paraphrases=6, seed=0, prior=0.0)
    assert len(set(ex.texts)) == len(ex.texts) and np.isclose(ex.weights.sum(), 1.0)
    i = ex.texts.index("a man plays basketball")
    assert ex.actions[i] == 2 and ex.styles[i] == -1  # the "unlabelled" class, no style
    torch.testing.assert_close(torch.from_numpy(ex.targets[i]), enc.encode([ex.texts[i]])[0])
    runs = ex.actions == 0
    assert runs.sum() > 6 and (ex.targets[runs] == table.prototypes[0].numpy()).all()
    # prior 0: every pair (and the unlabelled captions) drawn equally often
    np.testing.assert_allclose(ex.weights[runs].sum(), 0.25)


def test_embeddings_are_kept_for_the_next_run(tmp_path: Path, hash_text: Callable[..., TextEncoder]) -> None:
    enc, cache = hash_text(), tmp_path / "e.pt"
    first = encode_all(enc, ["a", "bb", "a"], cache)
    assert first.shape == (3, 8) and cache.is_file()
    calls = []
    enc.encode = lambda texts: calls.append(list(texts)) or hash_text().encode(texts)  # type: ignore[method-assign]
    torch.testing.assert_close(
        encode_all(enc, ["bb", "ccc"], cache), torch.cat([first[1:2], hash_text().encode(["ccc"])])
    )
    assert calls == [["ccc"]]


def test_training_writes_a_resumable_checkpoint(
    tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    data, out = _labelled(tmp_path), tmp_path / "adapter.pt"
    cfg = CaptionAdapterTrainConfig(
        steps=6, batch_size=16, paraphrases=6, hidden=16, progress=False, save_every=3
    )
    metrics = train_caption_adapter(data, out, cfg, encoder=hash_text(), target_encoder=hash_text())
    ckpt = read_checkpoint(out, CHECKPOINT_KIND)
    assert ckpt["step"] == 6 and ckpt["text_encoder"] == {"name": "hash", "dim": 8}
    assert ckpt["config"]["encoder"] == "hash" and list(ckpt["config"]["actions"]) == ["run", "walk"]
    assert ckpt["settings"]["target_encoder"] == "hash"
    assert 0.0 <= metrics["val_action_acc"] <= 1.0 and metrics["val_dist"] >= 0.0
    more = CaptionAdapterTrainConfig(
        steps=9, batch_size=16, paraphrases=6, hidden=16, progress=False, target_encoder="hash"
    )
    assert train_caption_adapter(data, out, more, encoder=hash_text())["step"] == 9


# A random CLIP small enough to make here (1.6 M parameters, nearly all its token table).
TINY_CLIP = {
    "embed_dim": 16,
    "vision_cfg": {"image_size": 32, "layers": 1, "width": 32, "patch_size": 16, "head_width": 16},
    "text_cfg": {"context_length": 77, "vocab_size": 49408, "width": 32, "heads": 2, "layers": 1},
}


@pytest.fixture
def tiny_clip(tmp_path: Path) -> Path:
    """An open_clip folder (open_clip_config.json and a checkpoint) of a random tiny CLIP."""
    if importlib.util.find_spec("open_clip") is None:
        pytest.skip("open-clip-torch is not installed (pip install 'motion-env[clip]')")
    from motion_env.text.clip import import_open_clip

    torch.manual_seed(0)
    folder = tmp_path / "tiny_clip"
    folder.mkdir()
    torch.save(import_open_clip().CLIP(**TINY_CLIP).state_dict(), folder / "open_clip_pytorch_model.bin")
    (folder / "open_clip_config.json").write_text(json.dumps({"model_cfg": TINY_CLIP}))
    return folder


def test_train_caption_adapter_encoder_clip(
    tmp_path: Path,
    tiny_clip: Path,
    hash_text: Callable[..., TextEncoder],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`motion-env train caption-adapter --encoder clip`: an adapter from CLIP's embeddings to the
    models' encoder (here the stand-in "hash", known to load_text_encoder for the test)."""
    from motion_env.cli import main
    from motion_env.text import encoders

    monkeypatch.setitem(encoders.TEXT_ENCODERS, "hash", lambda weights, device: hash_text())
    monkeypatch.setenv("MOTION_ENV_CACHE", str(tmp_path / "cache"))
    data, out = _labelled(tmp_path), tmp_path / "caption_adapter.clip.pt"
    args = ["train", "caption-adapter", "--data", str(data), "--out", str(out), "--encoder", "clip"]
    args += ["--encoder-weights", str(tiny_clip), "--target-encoder", "hash", "--steps", "4"]
    args += ["--batch-size", "16", "--paraphrases", "6", "--hidden", "16", "--no-progress", "--threads", "1"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert json.loads(printed[printed.index("{") :])["step"] == 4
    ckpt = read_checkpoint(out, CHECKPOINT_KIND)
    assert ckpt["config"]["encoder"] == "clip" and ckpt["config"]["in_dim"] == 16
    assert ckpt["config"]["out_dim"] == 8 and ckpt["text_encoder"] == {"name": "hash", "dim": 8}


@pytest.mark.parametrize(("field", "value"), [("paraphrases", 0), ("lr", 0.0), ("text_noise", -1.0)])
def test_bad_settings_are_refused(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        CaptionAdapterTrainConfig(**{field: value})
