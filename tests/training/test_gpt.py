"""The GPT trainer on a tiny dataset: tokens of a tiny VQ-VAE, a few steps, resuming, text encoder checks."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.data.dataset import load_stats, read_split
from motion_env.models.checkpoint import load_checkpoint
from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.text.encoders import TextEncoder
from motion_env.training.gpt import GPTTrainConfig, _TokenSet, corrupt_inputs, train_gpt
from motion_env.training.vqvae import VQVAETrainConfig, train_vqvae

TINY_VQ = VQVAEConfig(width=16, code_dim=8, codebook_size=16, depth=1)
TINY_GPT = GPTConfig(block_size=8, n_layer=1, n_head=2, n_embd=16, text_dim=8)


@pytest.fixture
def vqvae(tiny_dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("vqvae") / "vq.pt"
    train_vqvae(
        tiny_dataset, out, VQVAETrainConfig(steps=4, batch_size=4, window=32, progress=False), TINY_VQ
    )
    return out


def test_train_gpt_end_to_end(
    tiny_dataset: Path, vqvae: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    out = tmp_path / "gpt.pt"
    fast = dict(batch_size=4, save_every=2, log_every=2, progress=False, token_keep_random=True)
    m = train_gpt(tiny_dataset, vqvae, out, GPTTrainConfig(steps=4, **fast), TINY_GPT, hash_text())
    assert m["step"] == 4 and 0.0 <= m["val_accuracy"] <= 1.0
    assert 1.0 <= m["val_perplexity"] < 1e4 and 0.0 <= m["train_accuracy"] <= 1.0
    model, ckpt = load_checkpoint(out, "gpt", GPTConfig, TokenGPT)
    assert model.config.vocab_size == TINY_VQ.codebook_size  # taken from the VQ-VAE
    assert ckpt["text_encoder"] == {"name": "hash", "dim": 8}
    assert ckpt["vqvae"] == {"path": str(vqvae), "step": 4}
    # The settings are stored as a plain dict, with the name of the encoder actually used.
    assert ckpt["settings"] == GPTTrainConfig(steps=4, encoder="hash", **fast).to_dict()
    assert (
        train_gpt(tiny_dataset, vqvae, out, GPTTrainConfig(steps=5, **fast), TINY_GPT, hash_text())["step"]
        == 5
    )
    with pytest.raises(ValueError, match="trained with text encoder 'hash'"):
        train_gpt(tiny_dataset, vqvae, out, GPTTrainConfig(steps=6, **fast), TINY_GPT, hash_text("other"))


def test_train_gpt_is_seeded_and_checks_the_text_width(
    tiny_dataset: Path, vqvae: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    config = GPTTrainConfig(steps=3, batch_size=4, progress=False)
    a = train_gpt(tiny_dataset, vqvae, tmp_path / "a.pt", config, TINY_GPT, hash_text())
    b = train_gpt(tiny_dataset, vqvae, tmp_path / "b.pt", config, TINY_GPT, hash_text())
    assert a["loss"] == b["loss"] and a["val_perplexity"] == b["val_perplexity"]
    wide = GPTConfig(block_size=8, n_layer=1, n_head=2, n_embd=16, text_dim=16)
    with pytest.raises(ValueError, match="text_dim=16"):
        train_gpt(tiny_dataset, vqvae, tmp_path / "c.pt", config, wide, hash_text())


def test_fine_tune_starts_from_the_init_weights(
    tiny_dataset: Path, vqvae: Path, tmp_path: Path, hash_text: Callable[..., TextEncoder]
) -> None:
    import torch

    fast = dict(batch_size=4, progress=False)
    base = tmp_path / "base.pt"
    train_gpt(tiny_dataset, vqvae, base, GPTTrainConfig(steps=4, **fast), TINY_GPT, hash_text())
    # A step at a learning rate of ~0 leaves the init's weights; the model config comes from it.
    tuned = tmp_path / "tuned.pt"
    train_gpt(
        tiny_dataset,
        vqvae,
        tuned,
        GPTTrainConfig(steps=1, lr=1e-12, init=str(base), **fast),
        None,
        hash_text(),
    )
    a, _ = load_checkpoint(base, "gpt", GPTConfig, TokenGPT)
    b, ckpt = load_checkpoint(tuned, "gpt", GPTConfig, TokenGPT)
    assert b.config == a.config and ckpt["step"] == 1 and ckpt["settings"]["init"] == str(base)
    for (name, x), y in zip(a.state_dict().items(), b.state_dict().values(), strict=True):
        torch.testing.assert_close(x, y, atol=1e-6, rtol=0, msg=name)
    with pytest.raises(ValueError, match="trained with text encoder 'hash'"):
        train_gpt(tiny_dataset, vqvae, tmp_path / "x.pt", GPTTrainConfig(steps=1, init=str(base), **fast),
                  None, hash_text("other"))  # fmt: skip
    other = GPTConfig(block_size=8, n_layer=2, n_head=2, n_embd=16, text_dim=8)
    with pytest.raises(ValueError, match="holds a GPT with"):
        train_gpt(tiny_dataset, vqvae, tmp_path / "y.pt", GPTTrainConfig(steps=1, init=str(base), **fast),
                  other, hash_text())  # fmt: skip
    with pytest.raises(ValueError, match="GPTTrainConfig.init"):
        GPTTrainConfig(init=" ")


def test_corrupted_inputs_keep_their_share_and_the_start() -> None:
    """T2M-GPT's corruption: about 1 - keep of a row's motion tokens replaced by random ones, START
    never, a row with keep 1 untouched; the batch sampler draws a share per crop when asked."""
    config = GPTConfig(vocab_size=64)
    rng = np.random.default_rng(0)
    prev = torch.from_numpy(rng.integers(0, 64, size=(3, 400)))
    prev[:, 0] = config.start_token
    out = corrupt_inputs(prev, np.array([[1.0], [0.5], [0.1]]), config, rng)
    changed = (out != prev).float().mean(1)
    assert torch.equal(out[0], prev[0]) and bool((out[:, 0] == config.start_token).all())
    assert abs(float(changed[1]) - 0.5 * 63 / 64) < 0.07 and abs(float(changed[2]) - 0.9 * 63 / 64) < 0.07
    assert int(out[:, 1:].max()) < 64  # random tokens are motion tokens
    with pytest.raises(ValueError, match="token_keep"):
        GPTTrainConfig(token_keep=0.0)


def _token_set_inputs(tiny_dataset: Path, vqvae: Path) -> tuple[VQVAE, list, Normalizer]:
    """What a _TokenSet of the tiny dataset is made from: the tiny VQ-VAE, the train clips, the
    feature statistics."""
    vq, _ = load_checkpoint(vqvae, "vqvae", VQVAEConfig, VQVAE)
    return vq, read_split(tiny_dataset, "train"), Normalizer(*load_stats(tiny_dataset))


def test_train_clips_tokenised_at_every_phase(tiny_dataset: Path, vqvae: Path) -> None:
    vq, clips, norm = _token_set_inputs(tiny_dataset, vqvae)
    one, four = _TokenSet(clips, vq, norm, "cpu"), _TokenSet(clips, vq, norm, "cpu", offsets=4)
    assert len(four) == 4 * len(one) and four.names[:4] == [one.names[0]] + [
        f"{one.names[0]}@{o}" for o in (1, 2, 3)
    ]
    # Phase o is the clip from its frame o: its tokens are those of the features cut there.
    feats = clips[0].features[2:]
    n = len(feats) // vq.rate
    x = torch.from_numpy(norm.normalize(np.asarray(feats[: n * vq.rate], np.float32)))[None]
    assert torch.equal(four.codes[2], vq.encode(x)[0]) and four.path[2].shape == (n, one.path[0].shape[1])
    with pytest.raises(ValueError, match="token offsets must be 1 ... 4"):
        _TokenSet(clips, vq, norm, "cpu", offsets=5)


def test_rare_actions_are_drawn_more_often_with_action_balance(tiny_dataset: Path, vqvae: Path) -> None:
    vq, clips, norm = _token_set_inputs(tiny_dataset, vqvae)
    assert set(_TokenSet(clips, vq, norm, "cpu").labels) == {""}  # without an index: no labels
    # One clip (both its phases) is a rare action, the others a common one; the index names
    # whole clips, so the second phase reads its clip's row.
    rare = next(c.name for c in clips if c.captions)
    index = {c.name: {"label": "bye" if c.name == rare else "walk"} for c in clips}
    data = _TokenSet(clips, vq, norm, "cpu", offsets=2, index=index)
    assert len(data) >= 6
    assert data.labels[:2] == ["bye", "bye"] and set(data.labels[2:]) == {"walk"}
    by_length = data.lengths / data.lengths.sum()
    np.testing.assert_allclose(data.draw_weights(0.0), by_length)
    balanced = data.draw_weights(1.0)  # each action drawn as often as the other
    assert balanced.sum() == pytest.approx(1.0)
    ratio = data.lengths[:2].mean() / data.lengths[2:].mean()  # per entry: its length / its action's entries
    assert balanced[:2].sum() / balanced[2:].sum() == pytest.approx(ratio)
    assert balanced[:2].sum() > 2 * by_length[:2].sum()
    with pytest.raises(ValueError, match="action_balance"):
        GPTTrainConfig(action_balance=1.5)


def test_train_clips_played_faster_and_slower_with_time_stretch(tiny_dataset: Path, vqvae: Path) -> None:
    from motion_env.motion.features import joints_to_features
    from motion_env.motion.kinematics import resample
    from motion_env.motion.skeleton import FPS, ROOT_LIN_VEL

    vq, clips, norm = _token_set_inputs(tiny_dataset, vqvae)
    one, three = _TokenSet(clips, vq, norm, "cpu"), _TokenSet(clips, vq, norm, "cpu", stretch=0.25)
    assert len(three) == 3 * len(one)
    name = one.names[0]
    assert three.names[:3] == [name, f"{name}~0.75", f"{name}~1.25"] and torch.equal(
        three.codes[0], one.codes[0]
    )
    assert three.captions[1] == three.captions[0] and three.labels[1] == three.labels[0]
    # Played slower, more tokens; faster, fewer: about the clip's length over its speed.
    np.testing.assert_allclose(three.lengths[1:3] / three.lengths[0], [1 / 0.75, 1 / 1.25], rtol=0.08)
    # The slow entry is the clip's joints resampled, its features made from them, encoded.
    joints = np.asarray(clips[0].joints, np.float32)
    feats = joints_to_features(resample(joints, FPS * 0.75, FPS), floor=False)
    n = len(feats) // vq.rate
    x = torch.from_numpy(norm.normalize(feats[: n * vq.rate].astype(np.float32)))[None]
    assert torch.equal(three.codes[1], vq.encode(x)[0]) and three.path[1].shape[0] == n
    # The walk goes faster and slower with it: its root's forward speed in the features.
    speed = [np.abs(np.asarray(f)[:, ROOT_LIN_VEL]).sum(-1).mean() for f in (clips[0].features, feats)]
    assert speed[1] / speed[0] == pytest.approx(0.75, rel=0.1)
    with pytest.raises(ValueError, match="time_stretch"):
        GPTTrainConfig(time_stretch=0.6)
