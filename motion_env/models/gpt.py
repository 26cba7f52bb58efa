"""Body GPT: a causal transformer that predicts the next motion token from text, path and past tokens.

The sequence for one clip of N tokens has N positions. The input at position i is

    embedding(previous token)     (tok_{i-1}; the learned START slot at i = 0)
  + path_mlp(path features of token i)   (paths.token_path_features: how the root moves next)
  + text(caption)                 (projected text embedding, the same at every position)
  + position(i)

and the output at position i is the distribution of token i. So position 0 is the
"text-conditioning slot": START carries no token, and text + path decide the first token.

The text is added to every position rather than used only as a prefix: the window slides
(below), so a prefix would fall out of it, and adding it everywhere lets ``set_text`` act from
the very next token while the cached past keeps the pose continuous. A learned "null text"
vector replaces the text for a random 10 % of training clips, which enables classifier-free
guidance (``guidance`` > 1) at sampling time.

Sliding window: positions are learned for ``block_size`` tokens. When the KV cache is full, it is
re-primed from the inputs of the newest ``block_size // 2`` tokens, renumbered from position 0,
and generation continues, so the length is unbounded. Training uses random crops whose first
input is the real previous token when the crop starts mid-clip, which is exactly what a re-primed
window looks like. Sampling is :mod:`motion_env.models.sampling`'s (multinomial).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from motion_env.models.frame_ops import gradients_state, numpy_chosen
from motion_env.models.gpt_numpy import KV, NUMPY_MAX_ROWS, NumpyStep
from motion_env.models.path_features import D_PATH
from motion_env.models.sampling import SamplingConfig, sample_tokens
from motion_env.motion.validation import CheckedConfig, PositiveInt

KV1 = tuple[torch.Tensor, torch.Tensor]  # one layer's keys and values, (R, H, L, C/H) each
Past = tuple[torch.Tensor, torch.Tensor, int]  # one layer's window buffers and the columns cached


@dataclass
class GPTConfig(CheckedConfig):
    """Body GPT hyper-parameters.

    Attributes:
        vocab_size: number of motion tokens (the VQ-VAE codebook size).
        block_size: window length in tokens (positions); 32 tokens = 6.4 s at rate 4, longer
            than most training clips (median 4 s), which keeps CPU training affordable. At
            least 2: the window slides by halves.
        n_layer, n_head, n_embd: transformer depth, heads and width.
        dropout: dropout in training.
        text_dim: width of the text embedding (384 for MiniLM).
        path_dim: width of the per-token path features (paths.D_PATH).
    """

    vocab_size: PositiveInt = 512
    block_size: Annotated[int, ">= 2"] = 32
    n_layer: PositiveInt = 4
    n_head: PositiveInt = 4
    n_embd: PositiveInt = 192
    dropout: Annotated[float, "[0, 1)"] = 0.1
    text_dim: PositiveInt = 384
    path_dim: PositiveInt = D_PATH

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.n_embd % self.n_head:
            raise ValueError(f"GPTConfig.n_embd ({self.n_embd}) must be divisible by n_head ({self.n_head})")

    @property
    def start_token(self) -> int:
        """Input id of the START slot (one past the last motion token)."""
        return self.vocab_size


@dataclass
class GPTCache:
    """State of incremental decoding for a batch of rows (see :meth:`TokenGPT.new_cache`).

    With guidance, the cache holds 2B rows: the B conditional rows, then their B null-text twins.

    Attributes:
        text: (R, C) conditioning vector added at every position of each row.
        kv: per layer (keys, values), each (R, H, L, C/H); empty before the first step.
        valid: (R, L) which cached positions each row may attend to (False after a row reset).
        pos: (R,) the position id of each row's next input.
        tokens: (R, L) the input ids that produced the cache (for re-priming the window).
        path: (R, L, path_dim) the input path features that produced the cache.
        guidance: classifier-free guidance scale (1 = off).
        room: the window-long buffers that kv, valid, tokens and path are the first L columns
            of (None until the first step after the cache was made or re-primed): a step writes
            its column in place instead of concatenating the whole past again.
    """

    text: torch.Tensor
    kv: list[tuple[torch.Tensor, torch.Tensor]] = field(default_factory=list)
    valid: torch.Tensor | None = None
    pos: torch.Tensor | None = None
    tokens: torch.Tensor | None = None
    path: torch.Tensor | None = None
    guidance: float = 1.0
    room: CacheRoom | None = None

    @property
    def length(self) -> int:
        return 0 if self.tokens is None else int(self.tokens.shape[1])

    @property
    def batch_size(self) -> int:
        rows = self.text.shape[0]
        return rows // 2 if self.guidance != 1.0 else rows


@dataclass
class CacheRoom:
    """A GPTCache's buffers for a whole window (block_size columns) of its R rows: per layer
    keys and values (R, H, block, C/H), and valid (R, block), tokens (R, block), path
    (R, block, path_dim). Columns past the cache's length hold nothing yet (or a step undone)."""

    kv: list[tuple[torch.Tensor, torch.Tensor]]
    valid: torch.Tensor
    tokens: torch.Tensor
    path: torch.Tensor


def _linear(layer: nn.Linear, x: torch.Tensor) -> torch.Tensor:
    """``layer(x)`` as a function call: the module's own kernel, without the cost of calling a
    module (which adds up at one token per step)."""
    return F.linear(x, layer.weight, layer.bias)


def _layer_norm(layer: nn.LayerNorm, x: torch.Tensor) -> torch.Tensor:
    """``layer(x)`` as a function call (see :func:`_linear`)."""
    return F.layer_norm(x, layer.normalized_shape, layer.weight, layer.bias, layer.eps)


class CausalSelfAttention(nn.Module):
    def __init__(self, config: GPTConfig) -> None:
        super().__init__()
        self.n_head = config.n_head
        self.qkv = nn.Linear(config.n_embd, 3 * config.n_embd)
        self.proj = nn.Linear(config.n_embd, config.n_embd)
        self.dropout = config.dropout

    def project(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """x (B, T, C) -> q, k, v, each (B, H, T, hd): views of the projection, as split + transpose give."""
        B, T, C = x.shape
        return _linear(self.qkv, x).view(B, T, 3, self.n_head, C // self.n_head).permute(2, 0, 3, 1, 4)

    def forward(self, x: torch.Tensor, mask: torch.Tensor, past: Past | None) -> tuple[torch.Tensor, KV1]:
        """x (B, T, C) after an optional past: its layer's window buffers (B, H, block, hd), into
        which the new keys and values are written after its first L columns, and L."""
        B, T, C = x.shape
        q, k, v = self.project(x)
        if past is not None:
            keys, values, start = past
            keys[:, :, start : start + T], values[:, :, start : start + T] = k, v
            k, v = keys[:, :, : start + T], values[:, :, : start + T]  # (B, H, L+T, hd)
        y = F.scaled_dot_product_attention(
            q, k, v, attn_mask=mask, dropout_p=self.dropout if self.training else 0.0
        )  # (B, H, T, hd)
        return _linear(self.proj, y.transpose(1, 2).reshape(B, T, C)), (k, v)


class Block(nn.Module):
    def __init__(self, config: GPTConfig) -> None:
        super().__init__()
        self.ln_1 = nn.LayerNorm(config.n_embd)
        self.attn = CausalSelfAttention(config)
        self.ln_2 = nn.LayerNorm(config.n_embd)
        self.mlp = nn.Sequential(
            nn.Linear(config.n_embd, 4 * config.n_embd),
            nn.GELU(),
            nn.Linear(4 * config.n_embd, config.n_embd),
            nn.Dropout(config.dropout),
        )

    def forward(self, x: torch.Tensor, mask: torch.Tensor, past: Past | None) -> tuple[torch.Tensor, KV1]:
        a, kv = self.attn(_layer_norm(self.ln_1, x), mask, past)
        x = x + a
        fc, _, out, drop = self.mlp  # self.mlp(...), layer by layer (see _linear)
        h = _linear(out, F.gelu(_linear(fc, _layer_norm(self.ln_2, x))))
        return x + (drop(h) if self.training else h), kv


class TokenGPT(nn.Module):
    """Causal transformer over motion tokens, conditioned on text and per-token path features."""

    def __init__(self, config: GPTConfig) -> None:
        super().__init__()
        self.config = c = config
        self.tok_emb = nn.Embedding(c.vocab_size + 1, c.n_embd)  # + the START slot
        self.pos_emb = nn.Embedding(c.block_size, c.n_embd)
        self.path_mlp = nn.Sequential(
            nn.Linear(c.path_dim, c.n_embd), nn.GELU(), nn.Linear(c.n_embd, c.n_embd)
        )
        self.text_proj = nn.Linear(c.text_dim, c.n_embd)
        self.null_text = nn.Parameter(torch.zeros(c.n_embd))
        self.drop = nn.Dropout(c.dropout)
        self.blocks = nn.ModuleList([Block(c) for _ in range(c.n_layer)])
        self.ln_f = nn.LayerNorm(c.n_embd)
        self.head = nn.Linear(c.n_embd, c.vocab_size, bias=False)
        self.apply(self._init_weights)
        for name, p in self.named_parameters():
            if name.endswith("proj.weight") and "text" not in name or name.endswith("mlp.2.weight"):
                nn.init.normal_(p, std=0.02 / math.sqrt(2 * c.n_layer))  # GPT-2's residual scaling
        self._numpy_step = NumpyStep()
        # Where a decoding step (a new token, the window re-primed) runs (frame_ops.BACKENDS): "auto"
        # (numpy for a few rows on the CPU without gradients, in eval mode, else torch), "torch"
        # (any device, the module's own forward pass), or "numpy"; the two agree to float32 rounding.
        self.step_backend = "auto"
        # Whether a token step on numpy runs as one compiled loop (gpt_jit, numba) or on numpy's
        # operations (the reference it is tested against); the same logits to float32 rounding.
        self.compiled = True

    @staticmethod
    def _init_weights(module: nn.Module) -> None:
        if isinstance(module, nn.Linear):
            nn.init.normal_(module.weight, std=0.02)
            if module.bias is not None:
                nn.init.zeros_(module.bias)
        elif isinstance(module, nn.Embedding):
            nn.init.normal_(module.weight, std=0.02)

    # --- conditioning -------------------------------------------------------------------------

    def text_condition(self, text_emb: torch.Tensor | None, drop: torch.Tensor | None = None) -> torch.Tensor:
        """(B, text_dim) text embeddings -> (B, n_embd) conditioning vectors.

        Rows where the optional (B,) bool `drop` is True get the learned null text instead.
        """
        if text_emb is None:
            raise ValueError("text_emb is required (rows can be made unconditional with `drop`)")
        if text_emb.ndim != 2 or text_emb.shape[1] != self.config.text_dim:
            raise ValueError(f"text_emb must be (B, {self.config.text_dim}), got {tuple(text_emb.shape)}")
        cond = self.text_proj(text_emb)
        if drop is not None:
            cond = torch.where(drop[:, None], self.null_text.expand_as(cond), cond)
        return cond

    def _check_path(self, tokens: torch.Tensor, path: torch.Tensor) -> None:
        if path.shape[:2] != tokens.shape or path.shape[-1] != self.config.path_dim:
            raise ValueError(
                f"path features must be (B, N, {self.config.path_dim}) like tokens {tuple(tokens.shape)}, "
                f"got {tuple(path.shape)}"
            )

    def _embed(
        self, tokens: torch.Tensor, path: torch.Tensor, text: torch.Tensor, pos: torch.Tensor
    ) -> torch.Tensor:
        self._check_path(tokens, path)
        fc, _, out = self.path_mlp  # self.path_mlp(path), layer by layer (see _linear)
        path_x = _linear(out, F.gelu(_linear(fc, path)))
        x = (
            F.embedding(tokens, self.tok_emb.weight)
            + path_x
            + text[:, None]
            + F.embedding(pos, self.pos_emb.weight)
        )
        return self.drop(x) if self.training else x  # (B, N, C)

    def _run(
        self,
        x: torch.Tensor,
        new_valid: torch.Tensor,
        past: tuple[KV, int] | None,
        past_valid: torch.Tensor | None,
        decoding: bool = False,
    ) -> tuple[torch.Tensor | None, KV]:
        """Transformer over new inputs x (B, N, C) after an optional cached past (a cache's room:
        each layer's window buffers, and the L columns cached, whose (B, L) `past_valid` the
        queries may see); -> logits (B, N, V) and each layer's keys and values (views of the
        buffers with a past). With `decoding` (the window re-primed during decoding: only the
        keys and values, logits None) a past-less run may take the numpy step's backend
        (:meth:`_on_numpy`); training and full forward passes stay on torch."""
        B, N, _ = x.shape
        if past and N == 1:
            # One new input (a decoding step): it sees the valid cached positions and itself.
            itself = torch.ones(B, 1, dtype=torch.bool, device=x.device)
            mask = torch.cat([past_valid, itself], dim=1)[:, None, None]  # (B, 1, 1, L+1)
        else:
            causal = torch.ones(N, N, dtype=torch.bool, device=x.device).tril()
            mask = causal[None] & new_valid[:, None, :]  # (B, N, N)
            if past:
                mask = torch.cat([past_valid[:, None, :].expand(B, N, -1), mask], dim=2)  # (B, N, L+N)
            # Every query sees at least itself, so padded queries never produce NaN.
            eye = torch.zeros_like(mask)
            eye[:, :, -N:] = torch.eye(N, dtype=torch.bool, device=x.device)
            mask = (mask | eye)[:, None]  # (B, 1, N, L+N)
        # The additive form scaled_dot_product_attention makes of a bool mask, made once for
        # all the layers instead of once per layer (the same numbers).
        mask = torch.where(mask, 0.0, -math.inf).to(x.dtype)
        if decoding and not past and self._on_numpy(B):
            return self._numpy_step.run(self, x, mask)
        kvs = []
        # Re-priming wants only the keys and values: the last block's attention and MLP and the
        # head would make what is thrown away.
        last = len(self.blocks) - 1 if decoding else len(self.blocks)
        for i, block in enumerate(self.blocks[:last]):
            x, kv = block(x, mask, (*past[0][i], past[1]) if past else None)
            kvs.append(kv)
        if decoding:
            block = self.blocks[last]
            _, k, v = block.attn.project(_layer_norm(block.ln_1, x))
            return None, [*kvs, (k, v)]
        return F.linear(_layer_norm(self.ln_f, x), self.head.weight), kvs

    # --- training / full recomputation -------------------------------------------------------

    def forward(
        self,
        prev_tokens: torch.Tensor,
        path_feats: torch.Tensor,
        text_emb: torch.Tensor | None = None,
        targets: torch.Tensor | None = None,
        text_drop: torch.Tensor | None = None,
        kv_cache: GPTCache | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Logits for every position.

        Args:
            prev_tokens: (B, N) long inputs: START (config.start_token) or the previous token.
            path_feats: (B, N, path_dim) path features of the token predicted at each position.
            text_emb: (B, text_dim) caption embeddings (not used with kv_cache, which holds the text).
            targets: optional (B, N) long token ids; -1 = ignored (padding).
            text_drop: optional (B,) bool, rows that get the null text (training dropout).
            kv_cache: continue decoding: the N inputs are appended to the cache (in place; the
                window slides when full) and positions continue from it. Must hold B rows
                (no guidance).

        Returns:
            logits (B, N, vocab_size), and the mean cross-entropy over non-ignored targets (or None).
        """
        if prev_tokens.ndim != 2:
            raise ValueError(f"prev_tokens must be (B, N), got {tuple(prev_tokens.shape)}")
        if kv_cache is not None:
            if kv_cache.guidance != 1.0:
                raise ValueError("forward(kv_cache=...) needs a cache without guidance; use step()")
            logits = self._append(kv_cache, prev_tokens, path_feats)
        else:
            B, N = prev_tokens.shape
            if N > self.config.block_size:
                raise ValueError(f"sequence of {N} tokens exceeds block_size {self.config.block_size}")
            pos = torch.arange(N, device=prev_tokens.device).expand(B, N)
            x = self._embed(prev_tokens, path_feats, self.text_condition(text_emb, text_drop), pos)
            valid = torch.ones(B, N, dtype=torch.bool, device=x.device)
            logits, _ = self._run(x, valid, None, None)
        loss = None
        if targets is not None:
            loss = F.cross_entropy(logits.reshape(-1, logits.shape[-1]), targets.reshape(-1), ignore_index=-1)
        return logits, loss

    # --- incremental decoding -----------------------------------------------------------------

    def new_cache(self, text_emb: torch.Tensor, guidance: float = 1.0) -> GPTCache:
        """An empty decoding state for B rows: (B, text_dim) text embeddings; guidance 1 = off."""
        cond = self.text_condition(text_emb)
        if guidance != 1.0:
            cond = torch.cat([cond, self.null_text.expand_as(cond)], dim=0)
        device = cond.device
        rows = cond.shape[0]
        return GPTCache(
            text=cond,
            valid=torch.zeros(rows, 0, dtype=torch.bool, device=device),
            pos=torch.zeros(rows, dtype=torch.long, device=device),
            tokens=torch.zeros(rows, 0, dtype=torch.long, device=device),
            path=torch.zeros(rows, 0, self.config.path_dim, device=device),
            guidance=float(guidance),
        )

    def _rows(self, cache: GPTCache, index: int | list[int] | None) -> torch.Tensor:
        B = cache.batch_size
        idx = torch.arange(B) if index is None else torch.as_tensor(index, dtype=torch.long).reshape(-1)
        if idx.numel() and (idx.min() < 0 or idx.max() >= B):
            raise IndexError(f"row index {index} out of range for a batch of {B}")
        return idx.to(cache.text.device)

    def set_cache_text(
        self, cache: GPTCache, text_emb: torch.Tensor, index: int | list[int] | None = None
    ) -> None:
        """Change the caption of some rows from their next token on (the cached past is kept)."""
        rows = self._rows(cache, index)
        cache.text[rows] = self.text_condition(text_emb.reshape(len(rows), -1)).to(cache.text.dtype)

    def reset_cache_rows(self, cache: GPTCache, index: int | list[int], text_emb: torch.Tensor) -> None:
        """Restart some rows from START with a new caption (their past is forgotten)."""
        rows = self._rows(cache, index)
        self.set_cache_text(cache, text_emb, rows.tolist())
        if cache.guidance != 1.0:
            rows = torch.cat([rows, rows + cache.batch_size])
        cache.valid[rows] = False
        cache.pos[rows] = 0

    def _reprime(self, cache: GPTCache, keep: int) -> None:
        """Rebuild the cache from each row's newest `keep` valid inputs, renumbered from position 0."""
        R, L = cache.tokens.shape
        device = cache.text.device
        # Right-align each row's newest valid inputs; rank = how many valid inputs follow.
        after = cache.valid.flip(1).cumsum(1).flip(1) - cache.valid.long()  # (R, L)
        sel = cache.valid & (after < keep)
        count = sel.sum(1)  # (R,)
        slot = keep - 1 - after  # target column of each selected input
        tokens = torch.full((R, keep), self.config.start_token, dtype=torch.long, device=device)
        path = torch.zeros(R, keep, self.config.path_dim, device=device)
        r, c = sel.nonzero(as_tuple=True)
        tokens[r, slot[r, c]] = cache.tokens[r, c]
        path[r, slot[r, c]] = cache.path[r, c]
        cols = torch.arange(keep, device=device)[None]
        valid = cols >= (keep - count)[:, None]  # (R, keep)
        pos = (cols - (keep - count)[:, None]).clamp_min(0)
        x = self._embed(tokens, path, cache.text, pos)
        _, kv = self._run(x, valid, None, None, decoding=True)
        cache.kv, cache.valid, cache.pos, cache.tokens, cache.path = kv, valid, count.clone(), tokens, path
        cache.room = None  # the next step makes a new one (an undone step's copy keeps the old)

    def _room(self, cache: GPTCache) -> CacheRoom:
        """The cache's window buffers, made with its L cached columns copied in if it has none."""
        if cache.room is not None:
            return cache.room
        (rows, length), c = cache.valid.shape, self.config
        device, kv_shape = cache.text.device, (rows, c.n_head, c.block_size, c.n_embd // c.n_head)

        def window(part: torch.Tensor | None, shape: tuple[int, ...], dim: int) -> torch.Tensor:
            buffer = torch.zeros(shape, dtype=cache.text.dtype if part is None else part.dtype, device=device)
            if part is not None:
                buffer.narrow(dim, 0, length).copy_(part)
            return buffer

        past = cache.kv or [(None, None)] * c.n_layer  # nothing cached yet: empty buffers
        kv = [(window(k, kv_shape, 2), window(v, kv_shape, 2)) for k, v in past]
        cache.room = CacheRoom(
            kv=kv,
            valid=window(cache.valid, (rows, c.block_size), 1),
            tokens=window(cache.tokens, (rows, c.block_size), 1),
            path=window(cache.path, (rows, c.block_size, c.path_dim), 1),
        )
        return cache.room

    def _append(self, cache: GPTCache, tokens: torch.Tensor, path: torch.Tensor) -> torch.Tensor:
        """Append (R, N) inputs to the cache, sliding the window if needed; -> logits (R, N, V)."""
        N = tokens.shape[1]
        block = self.config.block_size
        if N > block:
            raise ValueError(f"cannot append {N} tokens at once to a window of {block}")
        if cache.length + N > block:
            self._reprime(cache, min(block // 2, block - N))
        length, room = cache.length, self._room(cache)
        end = length + N
        # The new columns written after the cached ones; the cache's fields are views of them.
        if N == 1 and self._on_numpy(tokens.shape[0]):
            self._check_path(tokens, path)
            past = (room.kv, length)
            logits, kv = self._numpy_step(self, tokens, path, cache.text, cache.pos, cache.valid, past)
            # One column, through numpy views of the buffers: 15 us where a mask tensor and three
            # torch slice assignments took 32 (of a one-row token's 1-2 ms).
            room.valid.numpy()[:, length] = True
            room.tokens.numpy()[:, length] = tokens.numpy()[:, 0]
            room.path.numpy()[:, length] = path.detach().numpy()[:, 0]
        else:
            valid = torch.ones(tokens.shape, dtype=torch.bool, device=tokens.device)
            pos = cache.pos[:, None] + torch.arange(N, device=tokens.device)[None]
            x = self._embed(tokens, path.to(cache.text.dtype), cache.text, pos)
            logits, kv = self._run(x, valid, (room.kv, length), cache.valid)
            room.valid[:, length:end], room.tokens[:, length:end] = valid, tokens
            room.path[:, length:end] = path
        cache.kv = kv
        cache.valid, cache.tokens, cache.path = room.valid[:, :end], room.tokens[:, :end], room.path[:, :end]
        cache.pos = cache.pos + N
        return logits

    def _on_numpy(self, rows: int) -> bool:
        """Whether a decoding step for `rows` rows (a new token, or the window re-primed) runs on
        numpy (:attr:`step_backend`)."""
        weight = self.head.weight
        numpy_ok = (
            not torch.is_grad_enabled()
            and not self.training
            and weight.device.type == "cpu"
            and weight.dtype == torch.float32
        )
        return numpy_chosen(
            "TokenGPT.step_backend", self.step_backend, rows, NUMPY_MAX_ROWS, numpy_ok,
            "float32 steps without gradients, in eval mode, on the CPU",
            lambda: f"{gradients_state()}, training {self.training}, {weight.dtype} on {weight.device}",
        )  # fmt: skip

    @torch.no_grad()
    def step(
        self,
        cache: GPTCache,
        prev_token: torch.Tensor | None,
        path_feat: torch.Tensor,
        rows: np.ndarray | Sequence[int] | None = None,
    ) -> tuple[torch.Tensor, GPTCache]:
        """One decoding step for every row, or for some rows only.

        Args:
            cache: from :meth:`new_cache` (updated in place and returned).
            prev_token: (B,) long, the token sampled at the previous step; rows at position 0
                (fresh or reset) take START whatever is passed. None = every row starts.
            path_feat: (B, path_dim) path features of the token about to be predicted.
            rows: the rows that advance (None: all). The batch runs as one call either way; the
                other rows' new cache entry is masked out and their position rewound, so their
                next step is as if this one never happened (the stream's characters that are
                still mid-token).

        Returns:
            logits (B, vocab_size) of the next token (guidance applied), and the cache.
        """
        B = cache.batch_size
        if path_feat.shape != (B, self.config.path_dim):
            raise ValueError(f"path_feat must be ({B}, {self.config.path_dim}), got {tuple(path_feat.shape)}")
        device = cache.text.device
        start = torch.full((B,), self.config.start_token, dtype=torch.long, device=device)
        prev = start if prev_token is None else prev_token.to(device).long().reshape(B)
        path = path_feat.to(device)
        if cache.guidance != 1.0:
            prev, path = torch.cat([prev, prev]), torch.cat([path, path])
            start = torch.cat([start, start])
        prev = torch.where(cache.pos == 0, start, prev)
        logits = self._append(cache, prev[:, None], path[:, None])[:, 0]  # (R, V)
        if rows is not None and len(rows) < B:
            self._hold(cache, rows)
        if cache.guidance != 1.0:
            cond, uncond = logits[:B], logits[B:]
            logits = uncond + cache.guidance * (cond - uncond)
        return logits, cache

    @staticmethod
    def _hold(cache: GPTCache, rows: np.ndarray | Sequence[int]) -> None:
        """Undo the last step for every row not in `rows` (and for their null-text twins)."""
        idle = np.setdiff1d(np.arange(cache.batch_size), np.asarray(rows))
        if cache.guidance != 1.0:
            idle = np.concatenate([idle, idle + cache.batch_size])
        idle_t = torch.as_tensor(idle, device=cache.valid.device)
        cache.valid[idle_t, -1] = False
        cache.pos[idle_t] -= 1

    @torch.no_grad()
    def generate(
        self,
        text_emb: torch.Tensor,
        path_feats: torch.Tensor,
        num_tokens: int,
        generators: Sequence[torch.Generator],
        sampling: SamplingConfig | None = None,
        logits_out: list[torch.Tensor] | None = None,
    ) -> torch.Tensor:
        """Sample token sequences of any length (the window slides past block_size).

        This is what whole-clip generation runs (:mod:`motion_env.generation.pipeline`); the stream
        runs the same :meth:`step` and :func:`~motion_env.models.sampling.sample_tokens` one token
        at a time.

        Args:
            text_emb: (B, text_dim) caption embeddings.
            path_feats: (B, >= num_tokens, path_dim) path features of each token to generate.
            num_tokens: tokens to sample.
            generators: one torch.Generator per row (each row's samples then equal those of
                generating it alone with that generator).
            sampling: temperature, nucleus and guidance (default: the model's distribution).
            logits_out: a list that receives the (B, vocab_size) logits each token was drawn
                from, in order (the joint refinement's prior); None keeps nothing.

        Returns:
            (B, num_tokens) long token ids, on the CPU.
        """
        sampling = sampling or SamplingConfig()
        B = text_emb.shape[0]
        if path_feats.ndim != 3 or path_feats.shape[0] != B or path_feats.shape[1] < num_tokens:
            raise ValueError(f"path_feats must be ({B}, >= {num_tokens}, D), got {tuple(path_feats.shape)}")
        cache = self.new_cache(text_emb, sampling.guidance)
        out = torch.zeros(B, num_tokens, dtype=torch.long)
        prev = None
        for i in range(num_tokens):
            logits, cache = self.step(cache, prev, path_feats[:, i])
            if logits_out is not None:
                logits_out.append(logits.detach().cpu())
            out[:, i] = sample_tokens(logits, generators, sampling)
            prev = out[:, i].to(text_emb.device)
        return out
