"""Training of the token GPT on the train clips, tokenised by a trained VQ-VAE.

Each clip is encoded once by the VQ-VAE (features normalised with the dataset's
:class:`~motion_env.models.normalizer.Normalizer`); a batch is random crops of the token
sequences (a clip drawn in proportion to its length), each with a random caption of its clip
(embeddings computed once, jittered per sample), path features from the clip's own gait-free root
path, and the null text for a share of samples (classifier-free guidance). Ends with the
teacher-forced token accuracy and perplexity on the val split (:func:`evaluate_gpt`). The loop,
the learning-rate schedule and the checkpoints are :mod:`motion_env.training.loop`'s. With
``init`` a fresh run fine-tunes a trained GPT (its weights and model config, a new optimizer and
schedule).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import torch

from motion_env.data.dataset import read_index
from motion_env.models.checkpoint import (
    check_text_encoder,
    config_from_dict,
    load_checkpoint,
    read_checkpoint,
    text_encoder_record,
)
from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.motion.skeleton import FPS
from motion_env.motion.validation import Fraction, NonNegativeFloat, PositiveFloat, PositiveInt
from motion_env.text.encoders import DEFAULT_TEXT_ENCODER, TextEncoder, jitter_embeddings
from motion_env.training import loop
from motion_env.training.config import TrainConfig

CHECKPOINT_KIND = "gpt"


@dataclass(kw_only=True)
class GPTTrainConfig(TrainConfig):
    """How to train the token GPT (stored in its checkpoint under ``"settings"``)."""

    steps: PositiveInt = 1500  # total optimisation steps (those of a resumed run included)
    batch_size: PositiveInt = 64  # token crops per step
    lr: PositiveFloat = 3e-4  # peak AdamW learning rate (linear warm-up, cosine decay to a tenth)
    text_drop: Fraction = 0.1  # share of samples trained with the null text (classifier-free guidance)
    start_crop: Fraction = 0.3  # share of crops that start at the clip's first token
    text_noise: NonNegativeFloat = 0.3  # expected norm of the noise added to caption embeddings (0: off)
    # Input tokens replaced by random ones (the targets stay), so that the model learns to go on
    # from a past it sampled itself, mistakes included: T2M-GPT's corrupted inputs (its pkeep; a
    # share drawn per sequence, its pkeep = -1, was its better setting on the smaller KIT-ML).
    token_keep: Annotated[float, "(0, 1]"] = 1.0  # share of input tokens kept (1: no corruption)
    token_keep_random: bool = False  # instead, each crop keeps a share drawn uniformly in [0, 1]
    # Each train clip is also tokenised from its 2nd, 3rd, ... frame (up to the VQ-VAE's rate):
    # the same motion cut into tokens at other phases, as many more token sequences to learn from.
    token_offsets: PositiveInt = 1  # phases each train clip is tokenised at (1: from its first frame only)
    # Rare actions (a goodbye: 26 train clips against 728 raised hands) are drawn more often: a
    # clip's chance is its length x (train clips of its action)^-action_balance (index.csv's
    # label; clips without one are one group); 0.5 is the caption adapter's square-root prior.
    action_balance: Annotated[float, "[0, 1]"] = 0.0  # A: length x (action clips)^-A; 0: length alone
    # Each train clip also played faster and slower (its joints resampled in time, its features
    # made again from them): the GPT sees three speeds of every motion (0: the clips as they are).
    time_stretch: Annotated[float, "[0, 0.5]"] = 0.0  # S: each train clip also at speeds 1 - S and 1 + S
    encoder: str = DEFAULT_TEXT_ENCODER  # text encoder name (motion_env.text.load_text_encoder)
    init: str | None = None  # GPT checkpoint (packaged ones too) a fresh run starts from: weights, config

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.init is not None and not (isinstance(self.init, str) and self.init.strip()):
            raise ValueError(f"GPTTrainConfig.init must be a checkpoint path or None, got {self.init!r}")


class _TokenSet:
    """Every clip of a split as tokens + per-token path features + caption indices + action
    labels (from the dataset's `index`, :func:`~motion_env.data.dataset.read_index`: a sub-clip
    reads its whole clip's row; none: no labels); with `offsets` > 1 each clip also from its
    frames 1, 2, ... (one entry per phase)."""

    def __init__(
        self,
        clips: list[Any],
        vq: VQVAE,
        normalizer: Normalizer,
        device: Any,
        offsets: int = 1,
        index: dict[str, dict[str, str]] | None = None,
        stretch: float = 0.0,
    ) -> None:
        from motion_env.models.path_features import token_path_features
        from motion_env.motion.trajectory import gait_free_path, root_path_from_joints

        rate = vq.rate
        if not 1 <= offsets <= rate:
            raise ValueError(
                f"token offsets must be 1 ... {rate} (the VQ-VAE's frames per token), got {offsets}"
            )
        self.codes: list[torch.Tensor] = []
        self.path: list[torch.Tensor] = []
        self.captions: list[list[str]] = []
        self.names: list[str] = []
        self.labels: list[str] = []  # each entry's action ("" without one)
        for clip in clips:
            if not clip.captions:
                continue
            label = (index or {}).get(clip.name.split(":")[0], {}).get("label", "")
            for name, features, joints in _speeds(clip, stretch):
                # The generator's paths come from the path controller, which has no gait in them.
                whole = gait_free_path(root_path_from_joints(joints))
                for o in range(offsets):
                    feats = features[o:]
                    n = feats.shape[0] // rate
                    if n < 2:
                        continue
                    x = torch.from_numpy(normalizer.normalize(feats[: n * rate]))[None].to(
                        device
                    )  # (1, n * rate, 263)
                    self.codes.append(vq.encode(x)[0].cpu())
                    self.path.append(torch.from_numpy(token_path_features(whole[o:], rate)[:n]))
                    self.captions.append(list(clip.captions))
                    self.names.append(name if o == 0 else f"{name}@{o}")
                    self.labels.append(label)
        if not self.codes:
            raise ValueError("no clip with at least two tokens and a caption")
        self.lengths = np.array([c.shape[0] for c in self.codes])  # tokens per clip

    def draw_weights(self, balance: float) -> np.ndarray:
        """Each entry's chance of being drawn: its length x (entries of its action)^-balance."""
        _, group, counts = np.unique(self.labels, return_inverse=True, return_counts=True)
        w = self.lengths * counts[group].astype(float) ** -balance
        return w / w.sum()

    def __len__(self) -> int:
        return len(self.codes)


def _speeds(clip: Any, stretch: float) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, features, joints) of `clip` as it is and, with `stretch` S > 0, played at speeds
    1 - S and 1 + S: its joints resampled in time (linearly), its features made from them
    (:func:`~motion_env.motion.features.joints_to_features`, one frame fewer), named ``name~speed``."""
    from motion_env.motion.features import joints_to_features
    from motion_env.motion.kinematics import resample

    joints = np.asarray(clip.joints, np.float32)
    out = [(clip.name, np.asarray(clip.features, np.float32), joints)]
    for speed in (1.0 - stretch, 1.0 + stretch) if stretch > 0 else ():
        moved = resample(joints, FPS * speed, FPS)
        if len(moved) < 3:
            continue
        features = joints_to_features(moved, floor=False)  # the clip is on the floor already
        out.append((f"{clip.name}~{speed:g}", features.astype(np.float32), moved[: len(features)]))
    return out


def _gpt_batch(
    data: _TokenSet,
    clip_idx: np.ndarray,
    starts: np.ndarray,
    length: int,
    start_token: int,
    text_table: torch.Tensor,
    caption_row: dict[str, int],
    caption_pick: np.ndarray | None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """Inputs, path features, targets (-1 padded) and text embeddings for crops of `length` tokens."""
    B = len(clip_idx)
    prev = torch.full((B, length), start_token, dtype=torch.long)
    targets = torch.full((B, length), -1, dtype=torch.long)
    path = torch.zeros(B, length, data.path[0].shape[1])
    rows = []
    for b, (i, s) in enumerate(zip(clip_idx, starts, strict=True)):
        codes = data.codes[i][s : s + length]
        n = codes.shape[0]
        targets[b, :n] = codes
        path[b, :n] = data.path[i][s : s + n]
        if s > 0:
            prev[b, 0] = data.codes[i][s - 1]
        prev[b, 1:n] = codes[: n - 1]
        caps = data.captions[i]
        pick = 0 if caption_pick is None else int(caption_pick[b] * len(caps))
        rows.append(caption_row[caps[pick]])
    return prev, path, targets, text_table[rows]


@torch.no_grad()
def evaluate_gpt(
    model: TokenGPT,
    data: _TokenSet,
    text_table: torch.Tensor,
    caption_row: dict[str, int],
    device: str | torch.device = "cpu",
    max_clips: int | None = None,
) -> dict[str, float]:
    """Teacher-forced next-token accuracy and perplexity over whole clips (first caption each).

    Clips longer than the window are cut into consecutive windows; each later window starts from
    the real previous token, as generation with the sliding window does. `max_clips` evaluates an
    evenly spaced subset.
    """
    model.eval()
    L = model.config.block_size
    total_loss, correct, count = 0.0, 0, 0
    picks = range(len(data))
    if max_clips is not None and max_clips < len(data):
        picks = np.linspace(0, len(data) - 1, max(1, max_clips)).astype(int)
    for i in picks:
        n = data.codes[i].shape[0]
        for s in range(0, n, L):
            prev, path, targets, text = _gpt_batch(
                data, np.array([i]), np.array([s]), min(L, n - s), model.config.start_token,
                text_table, caption_row, None,
            )  # fmt: skip
            logits, _ = model(prev.to(device), path.to(device), text.to(device))
            t = targets.to(device)
            total_loss += float(torch.nn.functional.cross_entropy(logits[0], t[0], reduction="sum"))
            correct += int((logits[0].argmax(-1) == t[0]).sum())
            count += t.shape[1]
    return {"accuracy": correct / count, "perplexity": math.exp(total_loss / count), "tokens": float(count)}


def _embed_captions(encoder: Any, sets: list[_TokenSet]) -> tuple[torch.Tensor, dict[str, int]]:
    unique = sorted({c for s in sets for caps in s.captions for c in caps})
    table = torch.cat([encoder.encode(unique[i : i + 256]) for i in range(0, len(unique), 256)])
    return table, {c: i for i, c in enumerate(unique)}


def train_gpt(
    data_dir: str | Path,
    vqvae_path: str | Path,
    out_path: str | Path,
    config: GPTTrainConfig | None = None,
    model_config: GPTConfig | None = None,
    text_encoder: TextEncoder | None = None,
) -> dict[str, float]:
    """Train the token GPT on the train clips, tokenised by the VQ-VAE at `vqvae_path`.

    Args:
        data_dir: HumanML3D-layout dataset.
        vqvae_path: a checkpoint written by :func:`motion_env.training.vqvae.train_vqvae`.
        out_path: GPT checkpoint (periodic, atomic, resumable).
        config: training settings (default GPTTrainConfig()).
        model_config: model config; vocab_size is taken from the VQ-VAE (default GPTConfig()
            with the text encoder's width); resuming needs the same.
        text_encoder: an already loaded encoder to use instead of ``config.encoder`` (whose
            name is then stored as ``config.encoder``).

    Returns:
        final metrics: "step", "loss", "seconds_per_step", "val_accuracy", "val_perplexity",
        "val_tokens", and the same on the train clips ("train_", for comparison).
    """
    data_dir, out_path = Path(data_dir), Path(out_path)
    config = config or GPTTrainConfig()
    device = config.device
    vq, vq_ckpt = load_checkpoint(vqvae_path, "vqvae", VQVAEConfig, VQVAE, device)
    config, text_encoder = loop.with_text_encoder(config, text_encoder)
    init = _init_checkpoint(config, model_config, text_encoder)
    if init is not None:
        model_config = config_from_dict(GPTConfig, init["config"])
    model_config = _model_config(model_config, vq, text_encoder)
    normalizer = loop.load_normalizer(data_dir)
    train_clips, index = loop.load_split(data_dir, "train"), read_index(data_dir)
    train = _TokenSet(train_clips, vq, normalizer, device, config.token_offsets, index, config.time_stretch)
    draw = train.draw_weights(config.action_balance)
    val = _TokenSet(loop.load_split(data_dir, "val"), vq, normalizer, device)
    table, caption_row = _embed_captions(text_encoder, [train, val])

    torch.manual_seed(config.seed)
    model = TokenGPT(model_config).to(device)
    opt = _optimizer(model, config.lr)
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, model_config)
    if ckpt is not None:
        check_text_encoder(ckpt, text_encoder, out_path)
    start = loop.restore(ckpt, model, opt)
    if ckpt is None and init is not None:
        model.load_state_dict(init["model"])  # a fine-tune: the weights, a new optimizer and schedule
    rng = np.random.default_rng([config.seed, start])
    save = loop.checkpoint_writer(
        out_path, kind=CHECKPOINT_KIND, model=model, optimizer=opt, settings=config,
        text_encoder=text_encoder_record(text_encoder),
        vqvae={"path": str(vqvae_path), "step": int(vq_ckpt.get("step", 0))},
    )  # fmt: skip

    def train_step(step: int) -> dict[str, float]:
        model.train()
        batch = _sample_batch(train, draw, rng, config, model_config, table, caption_row)
        prev, path, targets, text, drop = batch
        _, loss = model(
            prev.to(device), path.to(device), text.to(device), targets.to(device), drop.to(device)
        )
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        return {"loss": float(loss.detach())}

    result = loop.run_loop(
        CHECKPOINT_KIND, config, opt, train_step, warmup=min(100, config.steps // 10 + 1), start=start,
        save=save, evaluate=lambda: evaluate_gpt(model, val, table, caption_row, device),
        postfix={"loss": ".3f"},
    )  # fmt: skip
    val_metrics = evaluate_gpt(model, val, table, caption_row, device)
    train_metrics = evaluate_gpt(model, train, table, caption_row, device, max_clips=len(val.codes))
    metrics = loop.final_metrics(result, ckpt, {"val": val_metrics, "train": train_metrics})
    save(result.step, metrics)
    model.train(False)
    return metrics


def _init_checkpoint(
    config: GPTTrainConfig, model_config: GPTConfig | None, text_encoder: TextEncoder
) -> dict[str, Any] | None:
    """The ``init`` checkpoint of a fine-tune, checked against the run: the same text encoder and,
    when one is given, the same model config; None without ``init``."""
    if config.init is None:
        return None
    init = read_checkpoint(config.init, CHECKPOINT_KIND)
    check_text_encoder(init, text_encoder, config.init)
    stored = config_from_dict(GPTConfig, init["config"])
    if model_config is not None and model_config != stored:
        raise ValueError(f"{config.init}: holds a GPT with {stored}, not the given {model_config}")
    return init


def _model_config(model_config: GPTConfig | None, vq: VQVAE, text_encoder: TextEncoder) -> GPTConfig:
    """The GPT's config: `model_config` (default: GPTConfig() at the text encoder's width) with the
    VQ-VAE's codebook as its vocabulary; ValueError when its text width is not the encoder's."""
    model_config = model_config or GPTConfig(text_dim=int(text_encoder.dim))
    if model_config.vocab_size != vq.config.codebook_size:
        model_config = config_from_dict(
            GPTConfig, {**asdict(model_config), "vocab_size": vq.config.codebook_size}
        )
    if model_config.text_dim != text_encoder.dim:
        raise ValueError(
            f"GPTConfig.text_dim={model_config.text_dim} but the text encoder {text_encoder.name} "
            f"is {text_encoder.dim}-d"
        )
    return model_config


def _optimizer(model: TokenGPT, lr: float) -> torch.optim.AdamW:
    """AdamW with weight decay on the weight matrices only (not on embeddings, biases or norms)."""
    decay = [p for n, p in model.named_parameters() if p.ndim >= 2 and "emb" not in n]
    no_decay = [p for n, p in model.named_parameters() if not (p.ndim >= 2 and "emb" not in n)]
    return torch.optim.AdamW(
        [{"params": decay, "weight_decay": 0.1}, {"params": no_decay, "weight_decay": 0.0}],
        lr=lr, betas=(0.9, 0.95),
    )  # fmt: skip


def _sample_batch(
    data: _TokenSet,
    draw: np.ndarray,
    rng: np.random.Generator,
    config: GPTTrainConfig,
    model_config: GPTConfig,
    text_table: torch.Tensor,
    caption_row: dict[str, int],
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """A training batch ``(prev, path, targets, text, drop)`` of ``config.batch_size`` crops of at
    most a window: entries drawn with the chances `draw` (:meth:`_TokenSet.draw_weights`), a
    share of the crops at the clip's first token, a random caption of the clip (jittered), and
    `drop` marking the samples trained with the null text."""
    L, B = model_config.block_size, config.batch_size
    idx = rng.choice(len(data), size=B, p=draw)
    span = np.maximum(data.lengths[idx] - L, 0)
    starts = np.where(rng.random(B) < config.start_crop, 0, (rng.random(B) * (span + 1)).astype(int))
    # Pad only to the longest crop of the batch: most clips are far shorter than the window.
    length = int(min(L, (data.lengths[idx] - starts).max()))
    prev, path, targets, text = _gpt_batch(
        data, idx, starts, length, model_config.start_token, text_table, caption_row, rng.random(B)
    )
    text = jitter_embeddings(text, config.text_noise, rng)
    drop = torch.from_numpy(rng.random(B) < config.text_drop)
    keep = rng.random((B, 1)) if config.token_keep_random else np.full((B, 1), config.token_keep)
    return corrupt_inputs(prev, keep, model_config, rng), path, targets, text, drop


def corrupt_inputs(
    prev: torch.Tensor, keep: np.ndarray, model_config: GPTConfig, rng: np.random.Generator
) -> torch.Tensor:
    """(B, N) input tokens with each motion token of row b replaced, with probability
    ``1 - keep[b]`` ((B, 1) shares), by a token drawn uniformly from the vocabulary; START inputs
    stay (they mark a clip's start)."""
    if np.all(keep >= 1.0):
        return prev
    swap = torch.from_numpy(rng.random(prev.shape) >= keep) & (prev != model_config.start_token)
    noise = torch.from_numpy(rng.integers(0, model_config.vocab_size, size=prev.shape))
    return torch.where(swap, noise, prev)
