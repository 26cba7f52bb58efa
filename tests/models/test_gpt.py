"""Body GPT: KV cache == recomputation, batching, sliding window, sampling, checkpoints."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import torch

from motion_env.models.checkpoint import load_checkpoint, save_checkpoint
from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.path_features import D_PATH
from motion_env.models.sampling import SamplingConfig, sample_tokens

V, TEXT = 32, 16


def tiny(block: int = 8) -> TokenGPT:
    torch.manual_seed(0)
    config = GPTConfig(
        vocab_size=V, block_size=block, n_layer=2, n_head=2, n_embd=32, dropout=0.0, text_dim=TEXT
    )
    return TokenGPT(config).eval()


def inputs(B: int, N: int, seed: int = 1) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    tokens = torch.randint(0, V, (B, N), generator=g)
    return tokens, torch.randn(B, N, D_PATH, generator=g), torch.randn(B, TEXT, generator=g)


def shifted(tokens: torch.Tensor, start: int) -> torch.Tensor:
    return torch.cat([torch.full_like(tokens[:, :1], start), tokens[:, :-1]], dim=1)


@pytest.mark.parametrize(
    "kw", [{"n_embd": 30, "n_head": 4}, {"block_size": 1}, {"vocab_size": 0}, {"dropout": 1.0}]
)
def test_config_rejects_bad_values(kw: dict) -> None:
    with pytest.raises(ValueError, match="GPTConfig"):
        GPTConfig(**kw)


def test_forward_shapes_and_loss() -> None:
    model = tiny()
    tokens, path, text = inputs(3, 8)
    targets = tokens.clone()
    targets[0, 5:] = -1  # padding is ignored
    logits, loss = model(shifted(tokens, model.config.start_token), path, text, targets)
    assert logits.shape == (3, 8, V)
    assert loss is not None and torch.isfinite(loss)
    with pytest.raises(ValueError, match="block_size"):
        model(torch.zeros(1, 9, dtype=torch.long), torch.zeros(1, 9, D_PATH), text[:1])
    with pytest.raises(ValueError, match="path features"):
        model(tokens, path[..., :3], text)


def test_output_at_i_depends_only_on_inputs_up_to_i() -> None:
    model = tiny()
    tokens, path, text = inputs(1, 8)
    prev = shifted(tokens, model.config.start_token)
    logits, _ = model(prev, path, text)
    path2 = path.clone()
    path2[:, 5] += 3.0
    logits2, _ = model(prev, path2, text)
    torch.testing.assert_close(logits[:, :5], logits2[:, :5])
    assert not torch.allclose(logits[:, 5], logits2[:, 5])  # path features of token i steer token i


def test_kv_cache_matches_full_recomputation() -> None:
    model = tiny()
    tokens, path, text = inputs(3, 8)
    full, _ = model(shifted(tokens, model.config.start_token), path, text)
    cache = model.new_cache(text)
    stepped, prev = [], None
    for i in range(8):
        logits, cache = model.step(cache, prev, path[:, i])
        stepped.append(logits)
        prev = tokens[:, i]
    torch.testing.assert_close(torch.stack(stepped, 1), full, atol=1e-5, rtol=1e-5)
    # forward(kv_cache=...) with several inputs at once continues the same way.
    cache = model.new_cache(text)
    a, _ = model(shifted(tokens, model.config.start_token)[:, :3], path[:, :3], kv_cache=cache)
    b, _ = model(tokens[:, 2:7], path[:, 3:8], kv_cache=cache)
    torch.testing.assert_close(torch.cat([a, b], 1), full, atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_a_step_writes_in_place_and_a_shallow_copy_undoes_it(backend: str) -> None:
    """The cache's fields are views of window buffers a step writes its column into; a shallow
    copy taken before a step (how the stream undoes a token worked out ahead) still continues as
    if that step never happened, across the window's slide too."""
    model = tiny(block=8)
    model.step_backend = backend
    tokens, path, text = inputs(2, 12)
    cache, prev = model.new_cache(text), None
    for i in range(7):
        _, cache = model.step(cache, prev, path[:, i])
        prev = tokens[:, i]
        room = cache.room
        assert room is not None and cache.kv[0][0].data_ptr() == room.kv[0][0].data_ptr()
        assert cache.valid.data_ptr() == room.valid.data_ptr() and cache.length == i + 1
    for ahead in (7, 8):  # the 8th input fills the window, the 9th re-primes it
        saved = replace(cache)
        model.step(cache, prev, path[:, ahead] + 5.0)  # a step taken ahead, then undone
        cache = saved
        redo, cache = model.step(cache, prev, path[:, ahead])
        prev = tokens[:, ahead]
        replay, prev_r = model.new_cache(text), None
        for i in range(ahead + 1):
            expected, replay = model.step(replay, prev_r, path[:, i])
            prev_r = tokens[:, i]
        torch.testing.assert_close(redo, expected, atol=0, rtol=0)


def test_sliding_window_reprimes_from_last_half() -> None:
    model = tiny(block=8)
    tokens, path, text = inputs(2, 12)
    cache = model.new_cache(text)
    prev = None
    for i in range(9):  # the 9th step overflows the window of 8
        logits, cache = model.step(cache, prev, path[:, i])
        prev = tokens[:, i]
    # After re-priming: the newest 4 inputs at positions 0..3, then the new one at 4.
    assert cache.length == 5 and cache.pos.tolist() == [5, 5]
    window_prev = tokens[:, 3:8]  # inputs of steps 4..8 are the tokens of steps 3..7
    expected, _ = model(window_prev, path[:, 4:9], text)
    torch.testing.assert_close(logits, expected[:, -1], atol=1e-5, rtol=1e-5)
    out = model.generate(text, torch.randn(2, 40, D_PATH), 40, [torch.Generator().manual_seed(0)] * 2)
    assert out.shape == (2, 40) and out.min() >= 0 and out.max() < V


def test_batched_equals_per_sample() -> None:
    model = tiny()
    tokens, path, text = inputs(3, 8)
    prev = shifted(tokens, model.config.start_token)
    batched, _ = model(prev, path, text)
    for b in range(3):
        alone, _ = model(prev[b : b + 1], path[b : b + 1], text[b : b + 1])
        torch.testing.assert_close(alone, batched[b : b + 1], atol=1e-5, rtol=1e-5)
    path = torch.randn(3, 20, D_PATH)
    gens = [torch.Generator().manual_seed(10 + b) for b in range(3)]
    together = model.generate(text, path, 20, gens)
    for b in range(3):
        alone = model.generate(text[b : b + 1], path[b : b + 1], 20, [torch.Generator().manual_seed(10 + b)])
        assert torch.equal(alone[0], together[b])


def test_seeded_generation_is_deterministic() -> None:
    model = tiny()
    _, _, text = inputs(2, 1)
    path = torch.randn(2, 12, D_PATH)
    nucleus = SamplingConfig(top_p=0.9)

    def gens(seed: int) -> list[torch.Generator]:
        return [torch.Generator().manual_seed(seed + b) for b in range(2)]

    a = model.generate(text, path, 12, gens(3), nucleus)
    b = model.generate(text, path, 12, gens(3), nucleus)
    c = model.generate(text, path, 12, gens(4), nucleus)
    assert torch.equal(a, b) and not torch.equal(a, c)
    g = model.generate(text, path, 12, gens(3), SamplingConfig(guidance=2.5))
    assert g.shape == (2, 12)
    with pytest.raises(ValueError, match="generators"):
        model.generate(text, path, 12, gens(3)[:1])


def test_row_reset_and_text_change() -> None:
    model = tiny()
    tokens, path, text = inputs(2, 6)
    other = torch.randn(1, TEXT)
    cache = model.new_cache(text)
    prev = None
    for i in range(3):
        _, cache = model.step(cache, prev, path[:, i])
        prev = tokens[:, i]
    model.reset_cache_rows(cache, 1, other)
    logits, cache = model.step(cache, prev, path[:, 3])
    # Row 1 restarted: same as a fresh sequence with the new text; row 0 unaffected.
    fresh, _ = model(torch.tensor([[model.config.start_token]]), path[1:2, 3:4], other)
    torch.testing.assert_close(logits[1], fresh[0, 0], atol=1e-5, rtol=1e-5)
    full, _ = model(shifted(tokens[:1, :4], model.config.start_token), path[:1, :4], text[:1])
    torch.testing.assert_close(logits[0], full[0, 3], atol=1e-5, rtol=1e-5)
    before = cache.text[0].clone()
    model.set_cache_text(cache, other, index=0)
    assert not torch.allclose(cache.text[0], before)


def test_top_p_keeps_only_the_nucleus() -> None:
    logits = torch.log(torch.tensor([[0.6, 0.3, 0.05, 0.05]]))
    g = torch.Generator().manual_seed(0)
    draws = {int(sample_tokens(logits, [g], SamplingConfig(top_p=0.8))[0]) for _ in range(200)}
    assert draws == {0, 1}


def test_checkpoint_round_trip(tmp_path: Path) -> None:
    model = tiny()
    tokens, path, text = inputs(1, 8)
    path_file = save_checkpoint(tmp_path / "gpt.pt", kind="gpt", config=model.config, model=model)
    loaded, _ = load_checkpoint(path_file, "gpt", GPTConfig, TokenGPT)
    prev = shifted(tokens, model.config.start_token)
    torch.testing.assert_close(loaded(prev, path, text)[0], model(prev, path, text)[0])
