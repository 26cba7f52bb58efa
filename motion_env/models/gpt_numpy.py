"""The body GPT's decoding on numpy: one new token for a few rows, or the window re-primed, on the
CPU without gradients (:meth:`TokenGPT._append <motion_env.models.gpt.TokenGPT._append>` and
:meth:`TokenGPT._run <motion_env.models.gpt.TokenGPT._run>` choose it).

A token step at one row is some seventy operations on vectors of 192 to 1,024 numbers, where
torch's cost per operation (a few microseconds each, the exact GELU and the masks' bookkeeping
more) is a large share: a 50-token generation at one row takes 1.1 ms a token on torch and 0.9
here (``motion-env bench``'s GPT rows), of which the step itself about 0.6, mostly reading the 8 MB
of weights (more than the L2 cache holds). The step is the module's forward pass written
out for one query: the same embeddings, LayerNorms, attention over the cached keys and values, and
MLPs, with two exact rearrangements that save operations, each LayerNorm's scale and shift folded
into the product after it, and the attention's 1 / sqrt(head size) into the query's rows. The
logits agree with torch's to float32 rounding (``tests/models/test_gpt_numpy.py``), so a token
drawn from them is the same unless a uniform draw falls within that rounding of a token's boundary.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from motion_env.models.frame_ops import NumpyOps
from motion_env.models.jit_cache import jit_enabled, note_first_compile

# (The GPT is typed as a module here: models.gpt imports this one, not the other way round.)
KV = list[tuple[torch.Tensor, torch.Tensor]]

# The most rows (characters, or twice that with guidance) a step runs on numpy; above it torch's
# matrix products win (`motion-env bench`'s GPT rows).
NUMPY_MAX_ROWS = 8


class _Layer(NamedTuple):
    """One block's weights, transposed to (in, out), LayerNorms folded in."""

    qkv: np.ndarray
    qkv_b: np.ndarray
    proj: np.ndarray
    proj_b: np.ndarray
    fc: np.ndarray
    fc_b: np.ndarray
    out: np.ndarray
    out_b: np.ndarray


class _Weights(NamedTuple):
    tok_emb: np.ndarray
    pos_emb: np.ndarray
    path_fc: np.ndarray
    path_fc_b: np.ndarray
    path_out: np.ndarray
    path_out_b: np.ndarray
    layers: tuple[_Layer, ...]
    stacked: _Layer  # every layer's weights of a kind in one (n_layer, ...) array (layers: views)
    head: np.ndarray
    head_b: np.ndarray
    eps: np.float32
    mean: np.ndarray  # (C,) 1 / C each: a LayerNorm's means as one product


def _tensor(a: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(a))


def _np(t: torch.Tensor) -> np.ndarray:
    return t.detach().cpu().double().numpy()


def _folded(
    norm: torch.nn.LayerNorm, linear: torch.nn.Linear, scale: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(W^T, b) of ``linear(norm(x))`` taking the normalised x (zero mean, unit variance), folded
    in float64: W diag(gamma) and W beta + b, the output columns times `scale` if given."""
    weight, gamma, beta = _np(linear.weight), _np(norm.weight), _np(norm.bias)
    bias = _np(linear.bias) if linear.bias is not None else np.zeros(weight.shape[0])
    w_t = (weight * gamma[None]).T
    b = weight @ beta + bias
    if scale is not None:
        w_t, b = w_t * scale[None], b * scale
    return np.ascontiguousarray(w_t, np.float32), b.astype(np.float32)


def _plain(linear: torch.nn.Linear) -> tuple[np.ndarray, np.ndarray]:
    return np.ascontiguousarray(_np(linear.weight).T, np.float32), _np(linear.bias).astype(np.float32)


def _prepare(gpt: nn.Module) -> _Weights:
    c = gpt.config
    head_dim = c.n_embd // c.n_head
    # The query's third of the qkv product scaled by 1 / sqrt(head size), as attention would.
    q_scale = np.ones(3 * c.n_embd)
    q_scale[: c.n_embd] = 1.0 / math.sqrt(head_dim)
    layers = []
    for block in gpt.blocks:
        fc, _, out, _ = block.mlp
        layers.append(
            _Layer(
                *_folded(block.ln_1, block.attn.qkv, q_scale),
                *_plain(block.attn.proj),
                *_folded(block.ln_2, fc),
                *_plain(out),
            )
        )
    # Each kind of weight of every layer in one (n_layer, ...) array (the compiled step's
    # arguments, gpt_jit), the layers' arrays views of them.
    stacked = _Layer(*(np.stack(arrays) for arrays in zip(*layers, strict=True)))
    layers = [_Layer(*(a[i] for a in stacked)) for i in range(len(layers))]
    path_fc, _, path_out = gpt.path_mlp
    (path_fc_w, path_fc_b), (path_out_w, path_out_b) = _plain(path_fc), _plain(path_out)
    head, head_b = _folded(gpt.ln_f, gpt.head)
    epsilons = {m.eps for m in gpt.modules() if isinstance(m, torch.nn.LayerNorm)}
    if len(epsilons) != 1:
        raise ValueError(f"the numpy GPT step needs one LayerNorm eps, the model has {sorted(epsilons)}")
    return _Weights(
        tok_emb=gpt.tok_emb.weight.detach().cpu().numpy().astype(np.float32),
        pos_emb=gpt.pos_emb.weight.detach().cpu().numpy().astype(np.float32),
        path_fc=path_fc_w,
        path_fc_b=path_fc_b,
        path_out=path_out_w,
        path_out_b=path_out_b,
        layers=tuple(layers),
        stacked=stacked,
        head=head,
        head_b=head_b,
        eps=np.float32(epsilons.pop()),
        mean=np.full(c.n_embd, 1.0 / c.n_embd, np.float32),
    )


class NumpyStep:
    """A TokenGPT's decoding on numpy (a new token, the window re-primed); holds the weights
    prepared for it, made again when a parameter changes in place (the version counters move with
    every optimiser step or load; a parameter replaced by another object is not seen)."""

    def __init__(self) -> None:
        self._params: tuple[torch.Tensor, ...] = ()
        self._weights: tuple[tuple[int, ...], _Weights] | None = None

    def weights(self, gpt: nn.Module) -> _Weights:
        # Listing a module's parameters costs a third of a step: the list is kept, and only the
        # version counters are read each step.
        if not self._params:
            self._params = tuple(gpt.parameters())
        key = tuple(p._version for p in self._params)
        if self._weights is None or self._weights[0] != key:
            self._weights = (key, _prepare(gpt))
        return self._weights[1]

    @staticmethod
    def _normed(x: np.ndarray, w: _Weights) -> np.ndarray:
        """(..., C) -> zero mean, unit variance over C (a LayerNorm without its affine part)."""
        d = x - (x @ w.mean)[..., None]
        return d / np.sqrt(((d * d) @ w.mean)[..., None] + w.eps)

    def _blocks(
        self,
        gpt: nn.Module,
        x: np.ndarray,
        mask: np.ndarray,
        past: tuple[KV, int] | None,
        logits: bool = True,
    ) -> tuple[torch.Tensor | None, KV]:
        """The transformer over new inputs x (R, N, C) after an optional cached past (each layer's
        window buffers (R, H, block, hd), float32 on the CPU, and the L columns cached: the new
        keys and values are written after them), each query seeing the keys where the additive
        `mask` (R, 1, N, L+N) is 0: logits (R, N, V) (None without `logits`: the keys and values
        only, the last layer's attention and MLP not made) and every layer's keys and values
        (R, H, L+N, hd), as torch tensors (views of the buffers with a past)."""
        w = self.weights(gpt)
        rows, n, heads = x.shape[0], x.shape[1], gpt.config.n_head
        head_dim = gpt.config.n_embd // heads
        kvs = []
        for i, layer in enumerate(w.layers):
            qkv = self._normed(x, w) @ layer.qkv + layer.qkv_b  # (R, N, 3C)
            q, k, v = qkv.reshape(rows, n, 3, heads, head_dim).transpose(2, 0, 3, 1, 4)  # (R, H, N, hd)
            if not logits and i == len(w.layers) - 1:  # re-priming: the last keys and values are all
                kvs.append((_tensor(k), _tensor(v)))
                return None, kvs
            if past is not None:
                (keys, values), start = past[0][i], past[1]
                end = start + n
                keys.numpy()[:, :, start:end], values.numpy()[:, :, start:end] = k, v  # in place
                k, v = keys.numpy()[:, :, :end], values.numpy()[:, :, :end]  # (R, H, L+N, hd)
                kvs.append((keys[:, :, :end], values[:, :, :end]))
            else:
                kvs.append((_tensor(k), _tensor(v)))
            scores = q @ k.swapaxes(-1, -2) + mask  # (R, H, N, L+N)
            weights = np.exp(scores - scores.max(-1, keepdims=True))
            y = (weights @ v) / weights.sum(-1, keepdims=True)  # (R, H, N, hd)
            x = x + y.transpose(0, 2, 1, 3).reshape(rows, n, -1) @ layer.proj + layer.proj_b
            x = x + NumpyOps.gelu(self._normed(x, w) @ layer.fc + layer.fc_b) @ layer.out + layer.out_b
        return torch.from_numpy(self._normed(x, w) @ w.head + w.head_b), kvs

    def run(self, gpt: nn.Module, x: torch.Tensor, mask: torch.Tensor) -> tuple[None, KV]:
        """:meth:`TokenGPT._run` re-priming the window: embedded inputs x (R, N, C) and the
        additive mask (R, 1, N, N) it made; the keys and values (no logits)."""
        return self._blocks(gpt, x.detach().numpy(), mask.numpy(), None, logits=False)

    def __call__(
        self,
        gpt: nn.Module,
        tokens: torch.Tensor,
        path: torch.Tensor,
        text: torch.Tensor,
        pos: torch.Tensor,
        valid: torch.Tensor,
        past: tuple[KV, int],
    ) -> tuple[torch.Tensor, KV]:
        """Logits (R, 1, V) of one new input per row ((R, 1) `tokens`, (R, 1, path_dim) `path`)
        after a cache's past (its (R, C) `text`, (R,) `pos`, (R, L) `valid`, and `past`: its
        room's keys and values, each layer's window buffers, and L), and the keys and values with
        it appended (:meth:`TokenGPT._append` does the cache's bookkeeping as for torch's step).
        The embedding and the mask are made here too, on numpy's cheaper operations."""
        w = self.weights(gpt)
        p = path[:, 0].detach().numpy().astype(np.float32, copy=False)
        path_x = NumpyOps.gelu(p @ w.path_fc + w.path_fc_b) @ w.path_out + w.path_out_b
        x = (
            w.tok_emb[tokens[:, 0].numpy()] + path_x + text.detach().numpy() + w.pos_emb[pos.numpy()]
        )  # (R, C)
        # Additive mask over the cached positions and the new one (which always sees itself).
        seen = np.concatenate([valid.numpy(), np.ones((len(x), 1), bool)], 1)
        mask = np.where(seen, np.float32(0.0), np.float32(-np.inf))  # (R, L+1)
        if not (gpt.compiled and jit_enabled()):
            return self._blocks(gpt, x[:, None], mask[:, None, None], past)
        from motion_env.models.gpt_jit import step  # numba is imported only when a step runs compiled

        note_first_compile(step, "the GPT's token step")
        kv, start = past
        keys, values = (tuple(buffer.numpy() for buffer in buffers) for buffers in zip(*kv, strict=True))
        logits = step(
            x, mask, *w.stacked, w.head, w.head_b, w.eps, keys, values, start, gpt.config.n_head
        )  # writes each layer's new key and value into its window buffers
        end = start + 1
        return torch.from_numpy(logits[:, None]), [(k[:, :, :end], v[:, :, :end]) for k, v in kv]
