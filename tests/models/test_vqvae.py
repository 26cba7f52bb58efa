"""Motion VQ-VAE: shapes, causality, exact streaming decode, codebook updates, checkpoints."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.models.checkpoint import export_checkpoint, load_checkpoint, read_checkpoint, save_checkpoint
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import NUMPY_MAX_ROWS, VQVAE, VQVAEConfig


def tiny(rate: int = 4, **kw) -> VQVAE:
    torch.manual_seed(0)
    return VQVAE(VQVAEConfig(width=32, code_dim=16, codebook_size=32, rate=rate, **kw))


@pytest.mark.parametrize(
    "kw",
    [{"rate": 3}, {"codebook_size": 0}, {"width": -1}, {"ema_decay": 1.0}, {"commit_weight": -0.1}],
)
def test_config_rejects_bad_values(kw: dict) -> None:
    with pytest.raises(ValueError, match=next(iter(kw))):
        VQVAEConfig(**kw)


@pytest.mark.parametrize("rate", [2, 4])
def test_forward_shapes_and_losses(rate: int) -> None:
    model = tiny(rate).train()
    x = torch.randn(3, 32, 263)
    recon, codes, losses = model(x)
    assert recon.shape == x.shape
    assert codes.shape == (3, 32 // rate) and codes.dtype == torch.long
    assert set(losses) >= {"loss", "recon", "velocity", "commit", "perplexity"}
    assert all(torch.isfinite(v) for v in losses.values())
    losses["loss"].backward()
    assert model.encoder[0].weight.grad is not None and model.decoder[-1].weight.grad.abs().sum() > 0
    model.eval()
    _, eval_codes, _ = model(x)
    assert torch.equal(model.encode(x), eval_codes)  # the codebook only moves in training
    assert model.decode(codes).shape == (3, 32, 263)


def test_rejects_bad_shapes() -> None:
    model = tiny().eval()
    with pytest.raises(ValueError, match="multiple of rate 4"):
        model.encode(torch.randn(1, 30, 263))
    with pytest.raises(ValueError, match="263"):
        model.encode(torch.randn(1, 32, 100))
    with pytest.raises(ValueError, match=r"\[0, 32\)"):
        model.decode(torch.tensor([[0, 32]]))


@pytest.fixture(params=[2, 4], ids=lambda rate: f"rate{rate}")
def spread(request) -> VQVAE:
    """A tiny model in eval mode at each rate, its codebook spread out so that every code decodes
    to something else."""
    model = tiny(request.param).eval()
    model.quantizer.codebook.normal_()
    return model


def test_encoder_and_decoder_are_causal(spread: VQVAE) -> None:
    model, rate = spread, spread.config.rate
    x = torch.randn(1, 48, 263)
    later = x.clone()
    later[:, 24:] += 5.0  # change only frames from token 24 / rate on
    z1, z2 = model.encode_latent(x), model.encode_latent(later)
    assert torch.allclose(z1[:, : 24 // rate], z2[:, : 24 // rate])
    assert not torch.allclose(z1, z2)
    codes = torch.randint(0, 32, (1, 12))
    other = codes.clone()
    other[:, 8:] = (other[:, 8:] + 1) % 32
    assert torch.allclose(model.decode(codes)[:, : 8 * rate], model.decode(other)[:, : 8 * rate])


def test_stream_decode_equals_full_decode(spread: VQVAE) -> None:
    model, rate = spread, spread.config.rate
    codes = torch.randint(0, 32, (2, 3 * model.decoder_context_tokens))
    full = model.decode(codes)
    for n in range(1, codes.shape[1] + 1):
        # Only the last decoder_context_tokens tokens are handed over (or all, early on).
        recent = codes[:, max(0, n - model.decoder_context_tokens) : n]
        frames = model.decode_stream(recent)
        assert frames.shape == (2, rate, 263)
        torch.testing.assert_close(frames, full[:, (n - 1) * rate : n * rate], atol=1e-5, rtol=1e-5)


def test_decoder_stream_equals_full_decode_per_row(spread: VQVAE) -> None:
    model = spread
    codes = torch.randint(0, 32, (3, 2 * model.decoder_context_tokens))
    full = model.decode(codes)
    stream = model.decoder_stream(3)
    out = torch.cat([stream.step(codes[:, t]) for t in range(codes.shape[1])], dim=1)
    torch.testing.assert_close(out, full, atol=1e-5, rtol=1e-5)
    # Rows step on their own (the others wait), and a reset row starts over as a fresh one.
    stream = model.decoder_stream(3)
    for t in range(5):
        stream.step(codes[[0, 2], t], rows=[0, 2])
    stream.reset([2])
    late = torch.cat([stream.step(codes[[1, 2], t], rows=[1, 2]) for t in range(4)], dim=1)
    torch.testing.assert_close(late, model.decode(codes[[1, 2], :4]), atol=1e-5, rtol=1e-5)


def test_decoder_stream_restores_its_history(spread: VQVAE) -> None:
    """Steps taken ahead of time and undone (the stream's work ahead) leave no trace."""
    codes = torch.randint(0, 32, (2, 6))
    stream = spread.decoder_stream(2)
    for t in range(3):
        stream.step(codes[:, t])
    saved = stream.state()
    want = stream.step(codes[:, 3])
    stream.step(codes[:, 4])  # taken ahead, then undone
    stream.restore(saved)
    torch.testing.assert_close(stream.step(codes[:, 3]), want, atol=0.0, rtol=0.0)
    with pytest.raises(ValueError, match="state"):
        stream.restore(saved[:-1])


def _stream_run(model: VQVAE, backend: str, codes: torch.Tensor) -> torch.Tensor:
    """Frames of 3 rows stepping alone and together, one reset midway, on `backend`."""
    stream = model.decoder_stream(3)
    stream.backend = backend
    out = []
    with torch.no_grad():
        for t in range(codes.shape[1]):
            rows = [0, 2] if t % 3 == 1 else None
            out.append(stream.step(codes[rows or [0, 1, 2], t], rows=rows))
            if t == 4:
                stream.reset([1])
    return torch.cat([o.reshape(-1) for o in out])


def test_decoder_stream_on_numpy_equals_torch(spread: VQVAE) -> None:
    codes = torch.randint(0, 32, (3, 2 * spread.decoder_context_tokens))
    got, want = _stream_run(spread, "numpy", codes), _stream_run(spread, "torch", codes)
    torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)
    assert want.abs().max() > 0.1  # the outputs are not all near zero


def _compiled_run(
    model: VQVAE, compiled: bool, codes: torch.Tensor
) -> tuple[torch.Tensor, list[torch.Tensor]]:
    """:func:`_stream_run` on numpy, compiled or not; also the histories it leaves."""
    stream = model.decoder_stream(3)
    stream.backend, stream.compiled = "numpy", compiled
    out = []
    with torch.no_grad():
        for t in range(codes.shape[1]):
            rows = [[1], [0, 2], None][t % 3]  # 1 and 2 rows: compiled products; 3 rows of 2-4 frames: BLAS's
            out.append(stream.step(codes[rows or [0, 1, 2], t], rows=rows))
            if t == 4:
                stream.reset([1])
    return torch.cat([o.reshape(-1) for o in out]), stream.state()


def test_the_compiled_decoder_step_decodes_as_numpy_does(spread: VQVAE) -> None:
    """The compiled taps and few-row products (vqvae_jit) against numpy's concatenations and
    BLAS: the same frames and histories to float32 rounding."""
    pytest.importorskip("numba")
    codes = torch.randint(0, 32, (3, 2 * spread.decoder_context_tokens))
    (got, got_state), (want, want_state) = (
        _compiled_run(spread, True, codes),
        _compiled_run(spread, False, codes),
    )
    torch.testing.assert_close(got, want, atol=1e-5, rtol=1e-5)
    assert want.abs().max() > 0.1
    for a, b in zip(got_state, want_state, strict=True):
        torch.testing.assert_close(a, b, atol=1e-5, rtol=1e-5)


def test_the_compiled_decoder_kernels() -> None:
    """causal_taps gathers what the numpy concatenation gathers and moves the history on;
    few_rows_linear multiplies as numpy does, a width not a multiple of four included."""
    pytest.importorskip("numba")
    from motion_env.models.vqvae_jit import causal_taps, few_rows_linear

    rng = np.random.default_rng(0)
    for dilation, t in ((1, 1), (3, 2), (9, 4)):
        cache = rng.normal(size=(4, 2 * dilation, 5)).astype(np.float32)
        x = rng.normal(size=(2, t, 5)).astype(np.float32)
        index = np.array([3, 1])
        full = np.concatenate([cache[index], x], axis=1)
        want = np.concatenate([full[:, j * dilation : j * dilation + t] for j in range(3)], axis=-1)
        untouched = cache[[0, 2]].copy()
        got = causal_taps(cache, x, index, dilation, 3)
        assert np.array_equal(got, want.reshape(2 * t, 15))
        assert np.array_equal(cache[index], full[:, t:]) and np.array_equal(cache[[0, 2]], untouched)
    for k in (8, 13):
        x, w, b = (rng.normal(size=s).astype(np.float32) for s in ((3, k), (k, 6), (6,)))
        np.testing.assert_allclose(few_rows_linear(x, w, b), x @ w + b, rtol=1e-5, atol=1e-5)


def test_decoder_stream_backend_choice_and_errors(spread: VQVAE) -> None:
    stream = spread.decoder_stream(1)
    with torch.no_grad():
        assert stream._on_numpy(1) and stream._on_numpy(NUMPY_MAX_ROWS)
        assert not stream._on_numpy(NUMPY_MAX_ROWS + 1)  # many rows: torch's products win
    assert not stream._on_numpy(1)  # gradients on
    stream.backend = "numpy"
    with pytest.raises(ValueError, match="without gradients on the CPU only"):
        stream._on_numpy(1)  # (step() itself runs without gradients)
    stream.backend = "jax"
    with torch.no_grad(), pytest.raises(ValueError, match="backend must be one of"):
        stream.step(torch.tensor([0]))


def test_decoder_context_is_tight() -> None:
    model = tiny(4).eval()
    model.quantizer.codebook.normal_()
    ctx = model.decoder_context_tokens
    codes = torch.randint(0, 32, (1, ctx + 4))
    base = model.decode(codes)[:, -4:]

    @torch.no_grad()
    def change(k: int) -> float:
        other = codes.clone()
        other[0, -k] = (other[0, -k] + 1) % 32
        return float((model.decode(other)[:, -4:] - base).abs().max())

    assert change(ctx + 1) == 0.0  # outside the receptive field
    assert change(ctx) > 0.0  # the oldest token of the context still matters


def test_codebook_ema_moves_and_resets_dead_codes() -> None:
    model = tiny().train()
    x = torch.randn(8, 32, 263)
    model(x)  # initialises the codebook from encoder outputs
    before = model.quantizer.codebook.clone()
    model.quantizer.code_count[:5] = 0.0  # pretend 5 codes went unused
    dead = before[:5].clone()
    model(x)
    after = model.quantizer.codebook
    assert not torch.allclose(before, after)
    assert (model.quantizer.code_count[:5] > 0.0).all()
    assert not torch.allclose(after[:5], dead)
    q = model.quantizer  # a reset code's statistics agree with its new position
    torch.testing.assert_close(q.code_sum[:5] / q.code_count[:5, None], after[:5])


def test_overfits_real_clip(humanml3d_sample, require_data) -> None:
    """A few steps on a real clip lower the loss (the model can learn at all)."""
    _, feats = humanml3d_sample
    stats = require_data("humanml3d_sample")
    normalizer = Normalizer(np.load(stats / "Mean.npy"), np.load(stats / "Std.npy"))
    x = torch.from_numpy(normalizer.normalize(feats[:64])).float()[None]
    model = tiny().train()
    opt = torch.optim.Adam(model.parameters(), lr=2e-3)
    losses = []
    for _ in range(30):
        _, _, loss = model(x)
        opt.zero_grad()
        loss["loss"].backward()
        opt.step()
        losses.append(float(loss["recon"].detach()))
    assert losses[-1] < 0.7 * losses[0]


def test_checkpoint_round_trip(tmp_path: Path) -> None:
    model = tiny().train()
    model(torch.randn(2, 32, 263))
    model.eval()
    codes = torch.randint(0, 32, (1, 6))
    path = save_checkpoint(tmp_path / "vq.pt", kind="vqvae", config=model.config, model=model, step=7)
    loaded, ckpt = load_checkpoint(path, "vqvae", VQVAEConfig, VQVAE)
    assert ckpt["step"] == 7 and ckpt["config"]["codebook_size"] == 32
    assert torch.equal(loaded.decode(codes), model.decode(codes))
    half = save_checkpoint(tmp_path / "vq16.pt", kind="vqvae", config=model.config, model=model, half=True)
    assert half.stat().st_size < 0.6 * path.stat().st_size
    loaded16, _ = load_checkpoint(half, "vqvae", VQVAEConfig, VQVAE)
    opt = torch.optim.Adam(model.parameters())
    full = save_checkpoint(
        tmp_path / "t.pt", kind="vqvae", config=model.config, model=model, optimizer=opt.state_dict()
    )
    shipped = read_checkpoint(export_checkpoint(full, tmp_path / "ship.pt"), "vqvae")
    assert "optimizer" not in shipped and shipped["model"]["quantizer.codebook"].dtype == torch.float16
    assert loaded16.quantizer.codebook.dtype == torch.float32
    torch.testing.assert_close(loaded16.decode(codes), model.decode(codes), atol=5e-3, rtol=5e-2)


def test_checkpoint_errors(tmp_path: Path) -> None:
    model = tiny()
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        load_checkpoint(tmp_path / "missing.pt", "vqvae", VQVAEConfig, VQVAE)
    path = save_checkpoint(tmp_path / "vq.pt", kind="vqvae", config=model.config, model=model)
    with pytest.raises(ValueError, match="expected 'gpt'"):
        read_checkpoint(path, "gpt")
    ckpt = torch.load(path, weights_only=True)
    ckpt["format_version"] = 99
    torch.save(ckpt, tmp_path / "new.pt")
    with pytest.raises(ValueError, match="newer"):
        read_checkpoint(tmp_path / "new.pt")
    with pytest.raises(ValueError, match="reserved"):
        save_checkpoint(tmp_path / "x.pt", kind="vqvae", config=model.config, model=model, format_version=2)
