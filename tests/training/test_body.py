"""Body training loops on a tiny HumanML3D-layout dataset cut from the real sample clip."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.checkpoint import load_checkpoint, read_checkpoint
from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.vqvae import VQVAEConfig
from motion_env.text.encoders import TextEncoder
from motion_env.training.body import train_gpt, train_vqvae

SAMPLE = Path(__file__).resolve().parents[3] / "shared" / "data" / "humanml3d_sample"
TINY_VQ = VQVAEConfig(width=16, code_dim=8, codebook_size=16, depth=1)
TINY_GPT = GPTConfig(block_size=8, n_layer=1, n_head=2, n_embd=16, text_dim=8)


@pytest.fixture(autouse=True)
def one_thread() -> Iterator[None]:
    """Tiny models run fastest single-threaded, and the CPU is shared."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


class HashText(TextEncoder):
    """A deterministic stand-in for MiniLM: a fixed random vector per caption."""

    name, dim = "hash", 8

    def _embed(self, texts: list[str]) -> torch.Tensor:
        return torch.stack(
            [torch.randn(8, generator=torch.Generator().manual_seed(len(t) * 7919)) for t in texts]
        )


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not SAMPLE.is_dir():
        pytest.skip(f"real sample data not found at {SAMPLE}")
    root = tmp_path_factory.mktemp("mocap")
    feats = np.load(SAMPLE / "new_joint_vecs" / "012314.npy")
    joints = np.load(SAMPLE / "new_joints" / "012314.npy")
    for d in ("new_joint_vecs", "new_joints", "texts"):
        (root / d).mkdir()
    names = {"train": [], "val": []}
    for i, (a, b) in enumerate([(0, 80), (40, 130), (90, 170), (10, 100), (60, 170)]):
        name = f"clip{i}"
        np.save(root / "new_joint_vecs" / f"{name}.npy", feats[a:b])
        np.save(root / "new_joints" / f"{name}.npy", joints[a:b])
        captions = ["a person walks", "someone moves forward"] if i % 2 else ["a person turns around"]
        (root / "texts" / f"{name}.txt").write_text("".join(f"{c}#x/NOUN#0.0#0.0\n" for c in captions))
        names["val" if i == 4 else "train"].append(name)
    for split, ns in names.items():
        (root / f"{split}.txt").write_text("\n".join(ns) + "\n")
    shutil.copy(SAMPLE / "Mean.npy", root / "Mean.npy")
    shutil.copy(SAMPLE / "Std.npy", root / "Std.npy")
    return root


def test_train_vqvae_saves_resumes_and_evaluates(data_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "vq.pt"
    m1 = train_vqvae(data_dir, out, TINY_VQ, steps=6, batch_size=4, window=32, save_every=3, log_every=3)
    assert m1["step"] == 6 and np.isfinite(m1["loss"])
    assert m1["val_mpjpe_cm"] > 0 and np.isfinite(m1["val_mpjpe_cm"])
    ckpt = read_checkpoint(out, "vqvae")
    assert ckpt["step"] == 6 and "optimizer" in ckpt and ckpt["mean"].shape == (263,)
    # Resuming continues from the saved step (6) to the new total (8).
    resumed = train_vqvae(data_dir, out, TINY_VQ, steps=8, batch_size=4, window=32)
    assert resumed["step"] == 8
    with pytest.raises(ValueError, match="cannot resume"):
        train_vqvae(data_dir, out, VQVAEConfig(width=8, code_dim=8, codebook_size=16, depth=1), steps=9)


def test_train_vqvae_is_seeded(data_dir: Path, tmp_path: Path) -> None:
    a = train_vqvae(data_dir, tmp_path / "a.pt", TINY_VQ, steps=3, batch_size=4, window=32)
    b = train_vqvae(data_dir, tmp_path / "b.pt", TINY_VQ, steps=3, batch_size=4, window=32)
    assert a["loss"] == b["loss"] and a["val_mpjpe_cm"] == b["val_mpjpe_cm"]


def test_train_gpt_end_to_end(data_dir: Path, tmp_path: Path) -> None:
    vq = tmp_path / "vq.pt"
    train_vqvae(data_dir, vq, TINY_VQ, steps=4, batch_size=4, window=32)
    out = tmp_path / "gpt.pt"
    kw = dict(config=TINY_GPT, batch_size=4, text_encoder=HashText(), save_every=2, log_every=2)
    m = train_gpt(data_dir, vq, out, steps=4, **kw)
    assert m["step"] == 4 and 0.0 <= m["val_accuracy"] <= 1.0
    assert 1.0 <= m["val_perplexity"] < 1e4
    model, ckpt = load_checkpoint(out, "gpt", GPTConfig, TokenGPT)
    assert model.config.vocab_size == TINY_VQ.codebook_size  # taken from the VQ-VAE
    assert ckpt["text_encoder"] == {"name": "hash", "dim": 8}
    assert train_gpt(data_dir, vq, out, steps=5, **kw)["step"] == 5

    class Other(HashText):
        name = "other"

    with pytest.raises(ValueError, match="trained with text encoder 'hash'"):
        train_gpt(data_dir, vq, out, steps=6, **{**kw, "text_encoder": Other()})
