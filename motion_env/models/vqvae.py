"""Motion VQ-VAE: normalised 263-d HumanML3D features <-> discrete motion tokens.

Causal throughout, as C-T2M's streaming needs: every convolution pads on the left only, so an
encoded token depends only on frames up to its own, and decoded frames depend only on tokens up to
their own. The decoder's receptive field is finite (:attr:`VQVAE.decoder_context_tokens`), which
gives exact streaming decoding: the frames of the newest token, decoded from just the last
``decoder_context_tokens`` tokens (:meth:`VQVAE.decode_stream`), equal those of a full decode.

Sizes (defaults): width 192, codebook 512 x 128, rate 4 (one token per 4 frames = 0.2 s),
about 2.3 M parameters (4.6 MB as float16). The papers use 2048 codes for HumanML3D's ~29 h of
motion; our training set is ~4 h of far less varied motion (walks, runs, waves, turns with
styles), where 2048 codes would leave most of them dead or nearly unused (few samples per code,
poor EMA estimates), while 512 codes are all exercised within a CPU-sized training budget.
The quantizer keeps an EMA codebook and re-seeds unused codes with random encoder outputs
(T2M-GPT's "QuantizeEMAReset").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from motion_env.models.frame_ops import gradients_state, numpy_chosen
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.skeleton import FEATURE_DIM, NUM_JOINTS, RIC
from motion_env.motion.validation import CheckedConfig, NonNegativeFloat, PositiveInt


@dataclass
class VQVAEConfig(CheckedConfig):
    """VQ-VAE hyper-parameters.

    Attributes:
        feature_dim: input width (the 263-d HumanML3D features).
        width: channels of the convolutional encoder and decoder.
        code_dim: width of a codebook vector.
        codebook_size: number of codes (the token vocabulary).
        rate: temporal downsampling (frames per token), 2 or 4.
        depth: residual blocks per resolution.
        dilation_growth: dilation factor between consecutive residual blocks (1, g, g^2, ...).
        ema_decay: EMA decay of the codebook statistics.
        commit_weight: weight of the commitment loss.
        velocity_weight: weight of the loss on frame-to-frame differences of the joint positions.
    """

    feature_dim: PositiveInt = FEATURE_DIM
    width: PositiveInt = 192
    code_dim: PositiveInt = 128
    codebook_size: PositiveInt = 512
    rate: Annotated[int, (2, 4)] = 4
    depth: PositiveInt = 2
    dilation_growth: PositiveInt = 3
    ema_decay: Annotated[float, "(0, 1)"] = 0.99
    commit_weight: NonNegativeFloat = 0.02
    velocity_weight: NonNegativeFloat = 0.5

    @property
    def num_down(self) -> int:
        return int(math.log2(self.rate))


class CausalConv1d(nn.Conv1d):
    """Conv1d over (B, C, T) that pads only on the left: output t sees inputs <= t (times stride)."""

    def __init__(self, cin: int, cout: int, kernel: int, stride: int = 1, dilation: int = 1) -> None:
        super().__init__(cin, cout, kernel, stride=stride, dilation=dilation)
        self.left = (kernel - 1) * dilation - (stride - 1)
        self.lookback = (kernel - 1) * dilation  # how many earlier inputs one output reads

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return super().forward(F.pad(x, (self.left, 0)))


class ResBlock(nn.Module):
    def __init__(self, width: int, dilation: int) -> None:
        super().__init__()
        self.conv = CausalConv1d(width, width, 3, dilation=dilation)
        self.mix = nn.Conv1d(width, width, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.mix(F.relu(self.conv(F.relu(x))))


def _res_stack(width: int, depth: int, growth: int) -> list[nn.Module]:
    # Largest dilation first, as in T2M-GPT's Resnet1D(reverse_dilation=True).
    return [ResBlock(width, growth**i) for i in reversed(range(depth))]


class Upsample(nn.Module):
    """Nearest-neighbour x2 in time: frames 2j and 2j+1 copy input j (so causality is kept)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x.repeat_interleave(2, dim=-1)


class EMAQuantizer(nn.Module):
    """Nearest-code quantizer with an EMA codebook and reset of unused codes.

    The codebook is not trained by gradients: each training step moves every code towards the
    mean of the encoder outputs assigned to it (EMA), and codes whose EMA usage falls below one
    vector per step are replaced by random encoder outputs of the current batch.
    """

    def __init__(self, size: int, dim: int, decay: float) -> None:
        super().__init__()
        self.size, self.dim, self.decay = size, dim, decay
        self.register_buffer("codebook", torch.zeros(size, dim))
        self.register_buffer("code_sum", torch.zeros(size, dim))
        self.register_buffer("code_count", torch.zeros(size))
        self.register_buffer("initialized", torch.zeros((), dtype=torch.bool))

    def _random_rows(self, z: torch.Tensor, n: int) -> torch.Tensor:
        # Enough (noisy) copies of the batch's vectors to draw n distinct-ish rows from.
        if z.shape[0] < n:
            reps = math.ceil(n / z.shape[0])
            z = z.repeat(reps, 1) + torch.randn(z.shape[0] * reps, z.shape[1], device=z.device) * 0.01
        return z[torch.randperm(z.shape[0], device=z.device)[:n]]

    def nearest(self, z: torch.Tensor) -> torch.Tensor:
        """(M, dim) vectors -> (M,) long indices of the nearest codes."""
        dist = z.pow(2).sum(1, keepdim=True) - 2 * z @ self.codebook.t() + self.codebook.pow(2).sum(1)[None]
        return dist.argmin(dim=1)

    @torch.no_grad()
    def _update(self, z: torch.Tensor, codes: torch.Tensor) -> None:
        onehot = F.one_hot(codes, self.size).type(z.dtype)  # (M, K)
        count = onehot.sum(0)
        total = onehot.t() @ z  # (K, dim)
        self.code_sum.mul_(self.decay).add_(total, alpha=1 - self.decay)
        self.code_count.mul_(self.decay).add_(count, alpha=1 - self.decay)
        # T2M-GPT's rule: a code is dead when its EMA usage falls below one vector per step. It
        # is aggressive (a code of average use can miss a step or two) but it is what keeps the
        # codebook from collapsing early on; a softer threshold collapsed to ~10 codes here.
        used = (self.code_count >= 1.0).unsqueeze(1)
        fresh = self._random_rows(z, self.size)
        self.codebook.copy_(
            torch.where(used, self.code_sum / self.code_count.clamp_min(1e-5)[:, None], fresh)
        )
        # A reset code starts over with the statistics of one vector sitting at `fresh`.
        reset_count = torch.ones_like(self.code_count)
        self.code_sum.copy_(torch.where(used, self.code_sum, fresh * reset_count[:, None]))
        self.code_count.copy_(torch.where(used.squeeze(1), self.code_count, reset_count))

    def forward(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
        """(B, T, dim) -> quantized (B, T, dim) with straight-through gradients, codes (B, T), stats."""
        flat = z.reshape(-1, self.dim)
        if self.training and not bool(self.initialized):
            with torch.no_grad():
                fresh = self._random_rows(flat.detach(), self.size)
                self.codebook.copy_(fresh)
                self.code_sum.copy_(fresh)
                self.code_count.fill_(1.0)
                self.initialized.fill_(True)
        codes = self.nearest(flat.detach())
        if self.training:
            self._update(flat.detach(), codes)
        quant = self.codebook[codes].view_as(z)
        commit = F.mse_loss(z, quant.detach())
        probs = torch.bincount(codes, minlength=self.size).float() / codes.numel()
        perplexity = torch.exp(-(probs * (probs + 1e-10).log()).sum())
        quant = z + (quant - z).detach()
        return quant, codes.view(z.shape[:-1]), {"commit": commit, "perplexity": perplexity}


class VQVAE(nn.Module):
    """Causal convolutional VQ-VAE over normalised (B, T, 263) features; T must be a multiple of rate."""

    def __init__(self, config: VQVAEConfig) -> None:
        super().__init__()
        self.config = c = config
        enc: list[nn.Module] = [CausalConv1d(c.feature_dim, c.width, 3), nn.ReLU()]
        for _ in range(c.num_down):
            enc += [
                CausalConv1d(c.width, c.width, 4, stride=2),
                *_res_stack(c.width, c.depth, c.dilation_growth),
            ]
        enc += [CausalConv1d(c.width, c.code_dim, 3)]
        self.encoder = nn.Sequential(*enc)
        self.quantizer = EMAQuantizer(c.codebook_size, c.code_dim, c.ema_decay)
        dec: list[nn.Module] = [CausalConv1d(c.code_dim, c.width, 3), nn.ReLU()]
        for _ in range(c.num_down):
            dec += [
                *_res_stack(c.width, c.depth, c.dilation_growth),
                Upsample(),
                CausalConv1d(c.width, c.width, 3),
            ]
        dec += [CausalConv1d(c.width, c.width, 3), nn.ReLU(), CausalConv1d(c.width, c.feature_dim, 3)]
        self.decoder = nn.Sequential(*dec)
        self._context = self._receptive_field_tokens()

    def _receptive_field_tokens(self) -> int:
        """Tokens (the newest included) that the frames of the newest token depend on."""
        # Walk the decoder backwards from the first frame of token n, tracking the earliest
        # input index it reads at each resolution (a residual block reads its conv's lookback).
        n = 10_000  # any token index far from the start; the distance does not depend on it
        first = n * self.config.rate
        for layer in reversed(list(self.decoder)):
            if isinstance(layer, CausalConv1d):
                first -= layer.lookback
            elif isinstance(layer, ResBlock):
                first -= layer.conv.lookback
            elif isinstance(layer, Upsample):
                first //= 2
        return n - first + 1

    @property
    def rate(self) -> int:
        return self.config.rate

    @property
    def decoder_context_tokens(self) -> int:
        """How many tokens (the newest included) determine the newest token's decoded frames."""
        return self._context

    def _check_features(self, x: torch.Tensor) -> None:
        if x.ndim != 3 or x.shape[-1] != self.config.feature_dim:
            raise ValueError(f"expected features (B, T, {self.config.feature_dim}), got {tuple(x.shape)}")
        if x.shape[1] == 0 or x.shape[1] % self.rate:
            raise ValueError(f"feature length {x.shape[1]} must be a positive multiple of rate {self.rate}")

    def encode_latent(self, x: torch.Tensor) -> torch.Tensor:
        """(B, T, feature_dim) normalised features -> (B, T / rate, code_dim) latents before quantising."""
        return self.encoder(x.transpose(1, 2)).transpose(1, 2)  # (B, T/rate, code_dim)

    def decode_latent(self, z: torch.Tensor) -> torch.Tensor:
        """(B, N, code_dim) latents -> (B, N * rate, feature_dim) normalised features.

        Differentiable in `z`: the test-time refinement optimises latents (or a softmax over the
        codebook) through it; :meth:`decode` is its case with `z` the codebook rows of the tokens.
        """
        return self.decoder(z.transpose(1, 2)).transpose(1, 2)  # (B, N*rate, feature_dim)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
        """Reconstruct normalised features.

        Args:
            x: (B, T, 263) normalised features, T a multiple of rate.

        Returns:
            recon (B, T, 263), codes (B, T/rate) long, losses: "loss" (the total to minimise),
            "recon", "velocity", "commit", and "perplexity" (codebook usage, for logging).
        """
        self._check_features(x)
        quant, codes, q = self.quantizer(self.encode_latent(x))
        recon = self.decode_latent(quant)
        losses = self.reconstruction_losses(recon, x)
        losses["loss"] = losses["loss"] + self.config.commit_weight * q["commit"]
        return recon, codes, {**losses, **q}

    def reconstruction_losses(self, recon: torch.Tensor, x: torch.Tensor) -> dict[str, torch.Tensor]:
        """The decoder's losses of a reconstruction `recon` of `x` (both (B, T, 263), normalised):
        "recon", "velocity" and their weighted sum "loss" (without the commitment term)."""
        rec = F.smooth_l1_loss(recon, x)
        # Frame-to-frame change of the root-relative joint positions: penalises jitter that a
        # per-frame loss lets through.
        ric = slice(RIC.start, RIC.start + (NUM_JOINTS - 1) * 3)
        vel = F.smooth_l1_loss(recon[:, 1:, ric] - recon[:, :-1, ric], x[:, 1:, ric] - x[:, :-1, ric])
        return {"loss": rec + self.config.velocity_weight * vel, "recon": rec, "velocity": vel}

    @torch.no_grad()
    def encode(self, x: torch.Tensor) -> torch.Tensor:
        """(B, T, 263) normalised features -> (B, T // rate) long codes (T a multiple of rate)."""
        self._check_features(x)
        z = self.encode_latent(x)
        return self.quantizer.nearest(z.reshape(-1, z.shape[-1])).view(z.shape[:-1])

    def decode(self, codes: torch.Tensor) -> torch.Tensor:
        """(B, N) long codes -> (B, N * rate, 263) normalised features (differentiable in the codebook)."""
        if codes.ndim != 2 or codes.shape[1] == 0:
            raise ValueError(f"expected codes (B, N) with N >= 1, got {tuple(codes.shape)}")
        if codes.min() < 0 or codes.max() >= self.config.codebook_size:
            raise ValueError(
                f"codes must lie in [0, {self.config.codebook_size}), got {codes.min()}..{codes.max()}"
            )
        return self.decode_latent(self.quantizer.codebook[codes])

    def decoder_stream(self, batch: int) -> DecoderStream:
        """A :class:`DecoderStream` of `batch` rows: the decoder run one token at a time."""
        return DecoderStream(self, batch)

    @torch.no_grad()
    def decode_stream(self, recent_codes: torch.Tensor) -> torch.Tensor:
        """Frames of the newest token only, from the latest tokens.

        Args:
            recent_codes: (B, n) the most recent codes, the newest last: either the last
                ``decoder_context_tokens`` codes (or more), or every code since the start when
                fewer have been generated.

        Returns:
            (B, rate, 263): exactly ``decode(all_codes)[:, -rate:]``, because those frames depend
            on no earlier token (causal decoder, finite receptive field).
        """
        recent = recent_codes[:, -self.decoder_context_tokens :]
        return self.decode(recent)[:, -self.rate :]


# The most frames (rows x frames of a layer) a compiled product of DecoderStream takes
# (vqvae_jit.few_rows_linear); more go to BLAS's blocked product, faster there (the development
# CPU, a 768 x 256 weight: 4 frames 50 against 74 µs, 8 frames 177 against 80).
FEW_ROWS = 4
# The most rows a step runs on numpy when DecoderStream.backend is "auto".
NUMPY_MAX_ROWS = 8


class DecoderStream:
    """The VQ-VAE decoder run one token at a time, for B rows, each with its own history.

    Every causal convolution keeps the last inputs it looks back over (zeros at the start, as its
    left padding), so a token costs the decoder's work on ``rate`` frames instead of a re-decode of
    its whole receptive field. :meth:`step` gives what ``decode(all codes so far)[:, -rate:]``
    gives, to float rounding (the tests hold it to 1e-5).

    The stream runs time-major, (N, t, C): each convolution is one matrix product of its taps side
    by side (N * t, kernel * C) with its weight laid out as (C_out, kernel * C), made once here
    from the decoder's weights (a stream sees the weights as they were when it was made). On a
    few frames of many rows that is faster than ``conv1d`` on a CPU: a token of 64 rows 2-2.5x,
    of one row about 1.3x (one thread). A step of up to :data:`NUMPY_MAX_ROWS` rows on the CPU
    without gradients runs the same products on numpy (:attr:`backend`), whose cost per operation
    is a fraction of torch's at these sizes (a one-row token 0.87 -> 0.51 ms); the histories are
    the same tensors either way (numpy writes through views of them), the outputs agree to float32
    rounding.
    """

    def __init__(self, vqvae: VQVAE, batch: int) -> None:
        self.vqvae = vqvae
        self.batch = int(batch)
        self._layers = list(vqvae.decoder)
        ref = vqvae.quantizer.codebook
        convs = self._convs()
        if any(conv.stride[0] != 1 for conv in convs):
            raise ValueError("the decoder streams only stride-1 convolutions")
        other = [
            type(m).__name__
            for m in self._layers
            if not isinstance(m, (CausalConv1d, ResBlock, Upsample, nn.ReLU))
        ]
        if other:
            raise ValueError(
                f"the decoder streams causal convs, ResBlocks, Upsample and ReLU only, not {other}"
            )
        # One cache per causal conv (the ResBlocks' inner one included), in decoder order: its
        # last `lookback` inputs, (B, lookback, C).
        self._caches = [
            torch.zeros(self.batch, conv.lookback, conv.in_channels, dtype=ref.dtype, device=ref.device)
            for conv in convs
        ]
        with torch.no_grad():
            # (C_out, C_in, k) -> (C_out, k * C_in): tap j's inputs are columns j * C_in ...
            self._weights = [
                conv.weight.permute(0, 2, 1).reshape(conv.out_channels, -1).clone() for conv in convs
            ]
            self._mixes = [
                m.mix.weight[:, :, 0].clone() for m in self._layers if isinstance(m, ResBlock)
            ]  # the ResBlocks' 1x1 convs as (C_out, C_in)
        # Where a step runs (frame_ops.BACKENDS): "auto" (numpy for a few rows on the CPU without
        # gradients, else torch), "torch" or "numpy"; the numpy copies are made here once.
        self.backend = "auto"
        # Whether a numpy step gathers its taps and multiplies a few rows in compiled loops
        # (vqvae_jit, numba) or on numpy's operations (the reference it is tested against).
        self.compiled = True
        self._numpy_ok = ref.device.type == "cpu" and ref.dtype == torch.float32
        if self._numpy_ok:
            mix_biases = [m.mix.bias for m in self._layers if isinstance(m, ResBlock)]
            self._np = {
                "codebook": ref.detach().numpy().copy(),
                "caches": [cache.numpy() for cache in self._caches],  # views: one history
                "weights": [np.ascontiguousarray(w.numpy().T) for w in self._weights],
                "biases": [_numpy_bias(conv.bias, conv.out_channels) for conv in convs],
                "mixes": [np.ascontiguousarray(w.numpy().T) for w in self._mixes],
                "mix_biases": [
                    _numpy_bias(b, w.shape[0]) for b, w in zip(mix_biases, self._mixes, strict=True)
                ],
            }

    def _convs(self) -> list[CausalConv1d]:
        return [
            m.conv if isinstance(m, ResBlock) else m
            for m in self._layers
            if isinstance(m, (ResBlock, CausalConv1d))
        ]

    def reset(self, rows: Sequence[int] | None = None) -> None:
        """Start `rows` (default: all) over: their next token is a first token."""
        for cache in self._caches:
            if rows is None:
                cache.zero_()
            else:
                cache[torch.as_tensor(list(rows), dtype=torch.long, device=cache.device)] = 0.0

    def state(self) -> list[torch.Tensor]:
        """A copy of every row's history, for :meth:`restore` (undoing steps taken ahead of time)."""
        return [cache.clone() for cache in self._caches]

    def restore(self, state: list[torch.Tensor]) -> None:
        """Put back the histories of :meth:`state` (every row)."""
        if len(state) != len(self._caches) or any(a.shape != b.shape for a, b in zip(state, self._caches)):
            raise ValueError("restore() takes a state() of this DecoderStream")
        for cache, saved in zip(self._caches, state):
            cache.copy_(saved)

    @torch.no_grad()
    def step(self, codes: torch.Tensor, rows: Sequence[int] | None = None) -> torch.Tensor:
        """Decode the next token of `rows` (default: all, in order).

        Args:
            codes: (len(rows),) long, each row's newest code.

        Returns:
            (len(rows), rate, feature_dim) normalised features of that token's frames.
        """
        index = torch.arange(self.batch) if rows is None else torch.as_tensor(list(rows), dtype=torch.long)
        if self._on_numpy(len(index)):
            return self._step_numpy(codes, index.numpy())
        device = self._caches[0].device
        # Every row in order (a vector env's token): the histories as views, not gathered and
        # scattered back (the same numbers; 64 rows' token 0.9 ms less).
        every = len(index) == self.batch and bool((index == torch.arange(self.batch)).all())
        index = slice(None) if every else index.to(device)
        x = self.vqvae.quantizer.codebook[codes.to(device)][:, None, :]  # (N, 1, code_dim)
        n = m = 0
        for layer in self._layers:
            if isinstance(layer, CausalConv1d):
                x, n = self._conv(layer, x, index, n), n + 1
            elif isinstance(layer, ResBlock):
                h = F.relu(self._conv(layer.conv, F.relu(x), index, n))
                x, n, m = x + F.linear(h, self._mixes[m], layer.mix.bias), n + 1, m + 1
            elif isinstance(layer, Upsample):
                x = x.repeat_interleave(2, dim=1)  # time is dim 1 here
            else:  # ReLU
                x = F.relu(x)
        return x  # (N, rate, feature_dim)

    def _on_numpy(self, rows: int) -> bool:
        """Whether a step of `rows` rows runs on numpy (:attr:`backend`)."""
        codebook = self.vqvae.quantizer.codebook
        return numpy_chosen(
            "DecoderStream.backend", self.backend, rows, NUMPY_MAX_ROWS,
            self._numpy_ok and not torch.is_grad_enabled(), "float32 steps without gradients on the CPU",
            lambda: f"{gradients_state()}, {codebook.dtype} on {codebook.device}",
        )  # fmt: skip

    def _step_numpy(self, codes: torch.Tensor, index: np.ndarray) -> torch.Tensor:
        """:meth:`step` on numpy: the same layers, the same products."""
        arrays = self._np
        compiled = self.compiled and jit_enabled()
        x = arrays["codebook"][codes.cpu().numpy()][:, None, :]  # (N, 1, code_dim)
        n = m = 0
        for layer in self._layers:
            if isinstance(layer, CausalConv1d):
                x, n = self._conv_numpy(layer, x, index, n, compiled), n + 1
            elif isinstance(layer, ResBlock):
                h = np.maximum(self._conv_numpy(layer.conv, np.maximum(x, 0.0), index, n, compiled), 0.0)
                x = x + _product(h, arrays["mixes"][m], arrays["mix_biases"][m], compiled)
                n, m = n + 1, m + 1
            elif isinstance(layer, Upsample):
                x = np.repeat(x, 2, axis=1)
            else:  # ReLU
                x = np.maximum(x, 0.0)
        return torch.from_numpy(x)

    def _conv_numpy(
        self, conv: CausalConv1d, x: np.ndarray, index: np.ndarray, n: int, compiled: bool
    ) -> np.ndarray:
        """:meth:`_conv` on numpy, writing the history through its view of the cache tensor."""
        cache, d, t = self._np["caches"][n], conv.dilation[0], x.shape[1]
        if compiled:
            from motion_env.models.vqvae_jit import causal_taps

            note_first_compile(causal_taps, "the VQ-VAE decoder's streaming step")
            taps = causal_taps(cache, np.ascontiguousarray(x), index, d, conv.kernel_size[0])
            taps = taps.reshape(len(index), t, -1)
        else:
            full = np.concatenate([cache[index], x], axis=1)  # (N, lookback + t, C)
            cache[index] = full[:, full.shape[1] - conv.lookback :]
            taps = np.concatenate([full[:, j * d : j * d + t] for j in range(conv.kernel_size[0])], axis=-1)
        return _product(taps, self._np["weights"][n], self._np["biases"][n], compiled)  # (N, t, C_out)

    def _conv(self, conv: CausalConv1d, x: torch.Tensor, index: torch.Tensor | slice, n: int) -> torch.Tensor:
        """`conv` on the new inputs `x` (N, t, C) after the cached ones of rows `index` (a slice:
        every row); the cache moves on."""
        cache = self._caches[n]
        full = torch.cat([cache[index], x], dim=1)  # (N, lookback + t, C)
        cache[index] = full[:, full.shape[1] - conv.lookback :]
        d, t = conv.dilation[0], x.shape[1]
        taps = torch.cat([full[:, j * d : j * d + t] for j in range(conv.kernel_size[0])], dim=-1)
        return F.linear(taps, self._weights[n], conv.bias)  # (N, t, C_out)


def _product(x: np.ndarray, w: np.ndarray, b: np.ndarray, compiled: bool) -> np.ndarray:
    """x (N, t, K) @ w (K, C) + b: compiled for a few frames in all (BLAS copies the weight
    first, :mod:`~motion_env.models.vqvae_jit`), BLAS's product otherwise."""
    if compiled and x.shape[0] * x.shape[1] <= FEW_ROWS:
        from motion_env.models.vqvae_jit import few_rows_linear

        flat = np.ascontiguousarray(x.reshape(-1, x.shape[-1]))
        return few_rows_linear(flat, w, b).reshape(x.shape[0], x.shape[1], -1)
    return x @ w + b


def _numpy_bias(bias: torch.Tensor | None, size: int) -> np.ndarray:
    """A layer's bias as a float32 array (zeros for a layer without one)."""
    return np.zeros(size, np.float32) if bias is None else bias.detach().numpy().copy()
