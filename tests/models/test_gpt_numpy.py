"""The body GPT's decoding step on numpy against torch's: logits over whole generations (the window
sliding, rows reset and held, guidance), which backend a step takes, and the numpy weights made
again when the parameters change."""

from __future__ import annotations

import pytest
import torch

from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.gpt_numpy import NUMPY_MAX_ROWS
from motion_env.models.path_features import D_PATH
from motion_env.models.sampling import SamplingConfig

V, TEXT = 48, 16


def model(seed: int = 0) -> TokenGPT:
    """A small GPT with weights far from their initial ones (LayerNorms' scales and shifts, biases)
    so that nothing the numpy step folds or rearranges can hide behind a near-uniform output."""
    torch.manual_seed(seed)
    config = GPTConfig(vocab_size=V, block_size=8, n_layer=2, n_head=4, n_embd=32, dropout=0.0, text_dim=TEXT)
    gpt = TokenGPT(config).eval()
    with torch.no_grad():
        for p in gpt.parameters():
            p.add_(torch.randn_like(p) * 0.3)
    return gpt


def _run(gpt: TokenGPT, backend: str, rows: int, guidance: float = 1.0) -> tuple[torch.Tensor, torch.Tensor]:
    """Tokens and logits of 20 steps (the window of 8 slides twice), row 0 restarted with another
    caption at step 6 and held (mid-token) at steps 9-10."""
    gpt.step_backend = "numpy" if backend == "compiled" else backend
    gpt.compiled = backend == "compiled"  # a numpy step as one compiled loop, or numpy's operations
    g = torch.Generator().manual_seed(1)
    text, path = torch.randn(rows, TEXT, generator=g), torch.randn(rows, 20, D_PATH, generator=g)
    cache = gpt.new_cache(text, guidance)
    prev, tokens, logits = None, [], []
    with torch.no_grad():
        for i in range(20):
            if i == 6:
                gpt.reset_cache_rows(cache, 0, torch.randn(1, TEXT, generator=g))
            held = list(range(1, rows)) if i in (9, 10) else None
            out, cache = gpt.step(cache, prev, path[:, i], rows=held)
            prev = out.argmax(-1)
            tokens.append(prev)
            logits.append(out)
    return torch.stack(tokens, 1), torch.stack(logits, 1)


@pytest.mark.parametrize("backend", ["numpy", "compiled"])
@pytest.mark.parametrize(("rows", "guidance"), [(1, 1.0), (3, 1.0), (2, 2.5)])
def test_numpy_steps_equal_torch_ones(rows: int, guidance: float, backend: str) -> None:
    gpt = model()
    tokens, logits = _run(gpt, backend, rows, guidance)
    want_tokens, want_logits = _run(gpt, "torch", rows, guidance)
    assert torch.equal(tokens, want_tokens)
    torch.testing.assert_close(logits, want_logits, rtol=0.0, atol=2e-5)
    assert logits.std() > 1.0  # the outputs are far from uniform: the comparison means something


def test_a_compiled_step_does_not_run_numpy_operations(monkeypatch: pytest.MonkeyPatch) -> None:
    """With ``compiled`` (the default) a new token runs in gpt_jit; numpy's blocks only re-prime
    the window (no logits)."""
    gpt = model()
    blocks = gpt._numpy_step._blocks

    def reprime_only(*args, logits: bool = True):
        assert not logits, "a token step ran on numpy's operations"
        return blocks(*args, logits=logits)

    monkeypatch.setattr(gpt._numpy_step, "_blocks", reprime_only)
    tokens, _ = _run(gpt, "compiled", 2)
    assert tokens.shape == (2, 20)


def test_generation_draws_the_same_tokens() -> None:
    gpt = model(3)
    text, path = torch.randn(2, TEXT), torch.randn(2, 30, D_PATH)
    drawn = {}
    for backend in ("numpy", "torch"):
        gpt.step_backend = backend
        gens = [torch.Generator().manual_seed(7 + b) for b in range(2)]
        drawn[backend] = gpt.generate(text, path, 30, gens, SamplingConfig(temperature=0.8))
    assert torch.equal(drawn["numpy"], drawn["torch"])


def test_which_backend_a_step_takes() -> None:
    gpt = model()
    assert not gpt._on_numpy(1)  # gradients on (outside step's no_grad)
    with torch.no_grad():
        assert gpt._on_numpy(1) and gpt._on_numpy(NUMPY_MAX_ROWS)
        assert not gpt._on_numpy(NUMPY_MAX_ROWS + 1)  # many rows: torch's matrix products win
        gpt.step_backend = "numpy"
        assert gpt._on_numpy(NUMPY_MAX_ROWS + 1)
        gpt.step_backend = "auto"
        gpt.train()
        assert not gpt._on_numpy(1)  # dropout is torch's


def test_a_backend_that_cannot_run_is_named() -> None:
    gpt = model()
    cache = gpt.new_cache(torch.randn(1, TEXT))
    gpt.step_backend = "jax"
    with pytest.raises(ValueError, match="step_backend must be one of"):
        gpt.step(cache, None, torch.zeros(1, D_PATH))
    gpt.step_backend = "numpy"
    gpt.train()
    with pytest.raises(ValueError, match="in eval mode, on the CPU only"):
        gpt.step(cache, None, torch.zeros(1, D_PATH))
    gpt.eval()
    start = torch.tensor([[gpt.config.start_token]])
    with torch.no_grad(), pytest.raises(ValueError, match="path features must be"):
        gpt(start, torch.zeros(1, 1, D_PATH + 1), kv_cache=cache)  # checked on numpy too


def test_numpy_weights_follow_the_parameters() -> None:
    """An optimiser step or a load changes the parameters in place: the numpy copy is made again."""
    gpt = model()
    before = _run(gpt, "numpy", 1)[1]
    cached = gpt._numpy_step.weights(gpt)
    assert gpt._numpy_step.weights(gpt) is cached  # made once while unchanged
    with torch.no_grad():
        gpt.blocks[1].ln_2.weight.mul_(1.5)
    after = _run(gpt, "numpy", 1)[1]
    want = _run(gpt, "torch", 1)[1]
    assert not torch.allclose(before, after, atol=1e-3)
    torch.testing.assert_close(after, want, rtol=0.0, atol=2e-5)
