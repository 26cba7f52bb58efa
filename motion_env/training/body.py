"""Training of the body half of the generator: the motion VQ-VAE, then the token GPT.

Both trainers read a HumanML3D-layout dataset (:mod:`motion_env.dataset`), show a tqdm progress
bar with the loss, write a checkpoint periodically (atomically) and resume from it, run on any
device, are seeded, and end with an evaluation on the val split:

- :func:`train_vqvae`: random windows of normalised features (train split); val reconstruction
  MPJPE in cm (joints recovered from the denormalised reconstruction vs the ground truth).
- :func:`train_gpt`: token sequences of the train clips (each clip encoded once by the trained
  VQ-VAE), random crops, a random caption of the clip per sample (embeddings computed once),
  path features from the clip's own root path; val token accuracy and perplexity.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from motion_env.models.checkpoint import (
    check_text_encoder,
    config_from_dict,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
    text_encoder_record,
)
from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.vqvae import VQVAE, VQVAEConfig


def _lr_at(step: int, total: int, peak: float, warmup: int) -> float:
    """Linear warm-up, then cosine decay to 10 % of the peak."""
    if step < warmup:
        return peak * (step + 1) / warmup
    progress = min(1.0, (step - warmup) / max(1, total - warmup))
    return peak * (0.1 + 0.9 * 0.5 * (1.0 + math.cos(math.pi * progress)))


def _load_split(data_dir: Path, split: str) -> list[Any]:
    from motion_env.data.dataset import read_split

    clips = read_split(data_dir, split)
    if not clips:
        raise ValueError(f"{data_dir}: split {split!r} has no clips")
    return clips


def _stats(data_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    from motion_env.data.dataset import load_stats

    mean, std = load_stats(data_dir)
    return np.asarray(mean, np.float32), np.asarray(std, np.float32)


def _end_of_step(
    kind: str,
    bar: tqdm,
    step: int,
    steps: int,
    last: dict[str, float],
    done: int,
    t0: float,
    save: Callable[[int, dict[str, float]], None],
    log_every: int,
    save_every: int,
    max_minutes: float | None,
) -> bool:
    """Log, checkpoint and check the time limit after (0-based) `step`; True means stop now."""
    if (step + 1) % log_every == 0:
        terms = " ".join(f"{name} {value:.4f}" for name, value in last.items())
        bar.write(f"{kind} step {step + 1}/{steps} {terms} {(time.perf_counter() - t0) / done:.3f} s/step")
    timed_out = max_minutes is not None and time.perf_counter() - t0 > max_minutes * 60
    if (step + 1) % save_every == 0 or step + 1 == steps or timed_out:
        save(step + 1, last)
    if timed_out:
        bar.write(f"{kind}: stopping at step {step + 1} after {max_minutes} minutes")
    return timed_out


def _resume_state(out_path: Path, kind: str, config: Any, resume: bool) -> dict[str, Any] | None:
    """The checkpoint to continue from, or None for a fresh start."""
    if not (resume and out_path.is_file()):
        return None
    ckpt = read_checkpoint(out_path, kind)
    if ckpt["config"] != asdict(config):
        raise ValueError(
            f"{out_path}: cannot resume, it was trained with config {ckpt['config']}, not {asdict(config)}; "
            "pass resume=False or another out_path"
        )
    return ckpt


# --- VQ-VAE ----------------------------------------------------------------------------------


@torch.no_grad()
def evaluate_vqvae(
    model: VQVAE, clips: list[Any], mean: np.ndarray, std: np.ndarray, device: str | torch.device = "cpu"
) -> dict[str, float]:
    """Reconstruction quality on whole clips.

    Returns:
        "mpjpe_cm": mean per-joint position error (cm) of the joints recovered from the
        denormalised reconstruction vs those recovered from the ground-truth features (global
        positions, so root drift counts); "mpjpe_local_cm": the same with the pelvis aligned per
        frame; "feature_l1": mean |error| of the normalised features; "codes_used": distinct codes.
    """
    from motion_env.motion.features import features_to_joints

    model.eval()
    rate = model.rate
    errors, local_errors, l1, used = [], [], [], set()
    for clip in clips:
        feats = np.asarray(clip.features, np.float32)
        n = feats.shape[0] // rate * rate
        if n == 0:
            continue
        x = torch.from_numpy((feats[:n] - mean) / std)[None].to(device)
        codes = model.encode(x)
        recon = model.decode(codes)[0].cpu().numpy()
        used.update(codes.flatten().tolist())
        l1.append(float(np.abs(recon - x[0].cpu().numpy()).mean()))
        pred = features_to_joints(recon * std + mean)
        true = features_to_joints(feats[:n])
        errors.append(np.linalg.norm(pred - true, axis=-1).mean())
        local_errors.append(
            np.linalg.norm((pred - pred[:, :1]) - (true - true[:, :1]), axis=-1)[:, 1:].mean()
        )
    if not errors:
        raise ValueError(f"no clip of at least {rate} frames to evaluate")
    return {
        "mpjpe_cm": float(np.mean(errors) * 100),
        "mpjpe_local_cm": float(np.mean(local_errors) * 100),
        "feature_l1": float(np.mean(l1)),
        "codes_used": float(len(used)),
    }


def train_vqvae(
    data_dir: str | Path,
    out_path: str | Path,
    config: VQVAEConfig | None = None,
    steps: int = 3000,
    batch_size: int = 64,
    lr: float = 4e-4,
    window: int = 64,
    device: str | torch.device = "cpu",
    resume: bool = True,
    log_every: int = 50,
    save_every: int = 250,
    seed: int = 0,
    max_minutes: float | None = None,
) -> dict[str, float]:
    """Train the motion VQ-VAE on random windows of normalised train features.

    Args:
        data_dir: HumanML3D-layout dataset (train/val splits, Mean.npy/Std.npy).
        out_path: checkpoint written every `save_every` steps and at the end (with optimizer
            state and step, so a later call with resume=True continues).
        config: model config (default VQVAEConfig()).
        steps: total optimisation steps (including those of a resumed run).
        batch_size: windows per step.
        lr: peak AdamW learning rate (warm-up, then cosine decay).
        window: frames per training window (a multiple of config.rate).
        device: torch device.
        resume: continue from out_path if it exists (same config required).
        log_every: steps between loss lines in the log.
        save_every: steps between checkpoints.
        seed: seed of the model init and of the window sampling.
        max_minutes: stop early (with a checkpoint) after this much wall time.

    Returns:
        final metrics: "step", "loss", "seconds_per_step" and the val metrics of
        :func:`evaluate_vqvae` (prefixed "val_").
    """
    data_dir, out_path = Path(data_dir), Path(out_path)
    config = config or VQVAEConfig()
    if window % config.rate or window < config.rate:
        raise ValueError(f"window ({window}) must be a positive multiple of rate ({config.rate})")
    mean, std = _stats(data_dir)
    train = [c for c in _load_split(data_dir, "train") if len(c.features) >= window]
    if not train:
        raise ValueError(f"{data_dir}: no train clip has at least {window} frames")
    val = _load_split(data_dir, "val")
    feats = [torch.from_numpy((np.asarray(c.features, np.float32) - mean) / std) for c in train]
    lengths = np.array([f.shape[0] - window + 1 for f in feats], dtype=np.float64)
    weights = lengths / lengths.sum()  # every window equally likely

    torch.manual_seed(seed)
    model = VQVAE(config).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=lr, betas=(0.9, 0.99), weight_decay=0.0)
    start = 0
    ckpt = _resume_state(out_path, "vqvae", config, resume)
    if ckpt is not None:
        model.load_state_dict(ckpt["model"])
        opt.load_state_dict(ckpt["optimizer"])
        start = int(ckpt["step"])
    rng = np.random.default_rng([seed, start])  # resuming at step s draws what a fresh run would not repeat

    def save(step: int, metrics: dict[str, float]) -> None:
        save_checkpoint(
            out_path, kind="vqvae", config=config, model=model, optimizer=opt.state_dict(), step=step,
            metrics=metrics, mean=torch.from_numpy(mean), std=torch.from_numpy(std),
        )  # fmt: skip

    model.train()
    t0 = time.perf_counter()
    done, last = 0, {}
    bar = tqdm(total=steps, initial=start, desc="vqvae", mininterval=5.0)
    for step in range(start, steps):
        idx = rng.choice(len(feats), size=batch_size, p=weights)
        offs = (rng.random(batch_size) * lengths[idx]).astype(int)
        x = torch.stack([feats[i][o : o + window] for i, o in zip(idx, offs, strict=True)]).to(device)
        for group in opt.param_groups:
            group["lr"] = _lr_at(step, steps, lr, warmup=min(200, steps // 10 + 1))
        _, _, losses = model(x)
        opt.zero_grad(set_to_none=True)
        losses["loss"].backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        done += 1
        last = {k: float(v.detach()) for k, v in losses.items()}
        bar.update(1)
        bar.set_postfix(loss=f"{last['loss']:.4f}", ppl=f"{last['perplexity']:.0f}", refresh=False)
        if _end_of_step("vqvae", bar, step, steps, last, done, t0, save, log_every, save_every, max_minutes):
            break
    bar.close()
    final_step = start + done
    if done == 0 and ckpt is not None:
        last = dict(ckpt.get("metrics", {}))
    seconds_per_step = (time.perf_counter() - t0) / max(1, done)
    val_metrics = evaluate_vqvae(model, val, mean, std, device)
    metrics = {
        "step": float(final_step),
        **last,
        "seconds_per_step": seconds_per_step,
        **{f"val_{k}": v for k, v in val_metrics.items()},
    }
    save(final_step, metrics)
    model.train(False)
    return metrics


# --- GPT -------------------------------------------------------------------------------------


class _TokenSet:
    """Every clip of a split as tokens + per-token path features + caption indices."""

    def __init__(self, clips: list[Any], vq: VQVAE, mean: np.ndarray, std: np.ndarray, device: Any) -> None:
        from motion_env.models.path_features import token_path_features
        from motion_env.motion.trajectory import gait_free_path, root_path_from_joints

        rate = vq.rate
        self.codes: list[torch.Tensor] = []
        self.path: list[torch.Tensor] = []
        self.captions: list[list[str]] = []
        self.names: list[str] = []
        for clip in clips:
            feats = np.asarray(clip.features, np.float32)
            n = feats.shape[0] // rate
            if n < 2 or not clip.captions:
                continue
            x = torch.from_numpy((feats[: n * rate] - mean) / std)[None].to(device)
            self.codes.append(vq.encode(x)[0].cpu())
            # The generator's paths come from the path controller, which has no gait in them.
            path = gait_free_path(root_path_from_joints(np.asarray(clip.joints, np.float32)))
            pf = token_path_features(path, rate)
            self.path.append(torch.from_numpy(pf[:n]))
            self.captions.append(list(clip.captions))
            self.names.append(clip.name)
        if not self.codes:
            raise ValueError("no clip with at least two tokens and a caption")

    def __len__(self) -> int:
        return len(self.codes)


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
    config: GPTConfig | None = None,
    steps: int = 1500,
    batch_size: int = 64,
    lr: float = 3e-4,
    text_drop: float = 0.1,
    start_crop: float = 0.3,
    device: str | torch.device = "cpu",
    resume: bool = True,
    log_every: int = 50,
    save_every: int = 100,
    seed: int = 0,
    max_minutes: float | None = None,
    text_encoder: Any = None,
    text_noise: float = 0.3,
) -> dict[str, float]:
    """Train the token GPT on the train clips, tokenised by the VQ-VAE at `vqvae_path`.

    Args:
        data_dir: HumanML3D-layout dataset.
        vqvae_path: a checkpoint written by :func:`train_vqvae`.
        out_path: GPT checkpoint (periodic, atomic, resumable).
        config: model config; vocab_size is taken from the VQ-VAE (default GPTConfig()).
        steps: total optimisation steps (including those of a resumed run).
        batch_size: crops per step.
        lr: peak AdamW learning rate.
        text_drop: share of samples trained with the null text (classifier-free guidance).
        start_crop: share of crops forced to start at the clip's first token (the START slot).
        device, resume, log_every, save_every, seed, max_minutes: as in :func:`train_vqvae`.
        text_encoder: a :class:`motion_env.text.TextEncoder` (default: MiniLM with the side
            vector, ``load_text_encoder("minilm+sides")``); the default config takes its width.
        text_noise: expected norm of the noise added to caption embeddings
            (:func:`motion_env.text.jitter_embeddings`; 0 turns it off).

    Returns:
        final metrics: "step", "loss", "seconds_per_step", "val_accuracy", "val_perplexity",
        "train_accuracy", "train_perplexity" (the last two on the train clips, for comparison).
    """
    from motion_env.text.encoders import DEFAULT_TEXT_ENCODER, jitter_embeddings, load_text_encoder

    data_dir, out_path = Path(data_dir), Path(out_path)
    vq, vq_ckpt = load_checkpoint(vqvae_path, "vqvae", VQVAEConfig, VQVAE, device)
    encoder = text_encoder or load_text_encoder(DEFAULT_TEXT_ENCODER)
    config = config or GPTConfig(text_dim=int(encoder.dim))
    if config.vocab_size != vq.config.codebook_size:
        config = config_from_dict(GPTConfig, {**asdict(config), "vocab_size": vq.config.codebook_size})
    if config.text_dim != encoder.dim:
        raise ValueError(
            f"GPTConfig.text_dim={config.text_dim} but the text encoder {encoder.name} is {encoder.dim}-d"
        )
    mean, std = _stats(data_dir)
    train = _TokenSet(_load_split(data_dir, "train"), vq, mean, std, device)
    val = _TokenSet(_load_split(data_dir, "val"), vq, mean, std, device)
    table, caption_row = _embed_captions(encoder, [train, val])

    torch.manual_seed(seed)
    model = TokenGPT(config).to(device)
    decay = [p for n, p in model.named_parameters() if p.ndim >= 2 and "emb" not in n]
    no_decay = [p for n, p in model.named_parameters() if not (p.ndim >= 2 and "emb" not in n)]
    opt = torch.optim.AdamW(
        [{"params": decay, "weight_decay": 0.1}, {"params": no_decay, "weight_decay": 0.0}],
        lr=lr, betas=(0.9, 0.95),
    )  # fmt: skip
    start = 0
    ckpt = _resume_state(out_path, "gpt", config, resume)
    if ckpt is not None:
        check_text_encoder(ckpt, encoder, out_path)
        model.load_state_dict(ckpt["model"])
        opt.load_state_dict(ckpt["optimizer"])
        start = int(ckpt["step"])
    rng = np.random.default_rng([seed, start])
    L = config.block_size
    n_tokens = np.array([c.shape[0] for c in train.codes])
    weights = n_tokens / n_tokens.sum()  # a clip is drawn in proportion to its length

    def save(step: int, metrics: dict[str, float]) -> None:
        save_checkpoint(
            out_path, kind="gpt", config=config, model=model, optimizer=opt.state_dict(), step=step,
            metrics=metrics, text_encoder=text_encoder_record(encoder),
            vqvae={"path": str(vqvae_path), "step": int(vq_ckpt.get("step", 0))},
        )  # fmt: skip

    model.train()
    t0 = time.perf_counter()
    done, last = 0, {}
    bar = tqdm(total=steps, initial=start, desc="gpt", mininterval=5.0)
    for step in range(start, steps):
        idx = rng.choice(len(train), size=batch_size, p=weights)
        span = np.maximum(n_tokens[idx] - L, 0)
        starts = np.where(
            rng.random(batch_size) < start_crop, 0, (rng.random(batch_size) * (span + 1)).astype(int)
        )
        # Pad only to the longest crop of the batch: most clips are far shorter than the window.
        length = int(min(L, (n_tokens[idx] - starts).max()))
        prev, path, targets, text = _gpt_batch(
            train, idx, starts, length, config.start_token, table, caption_row, rng.random(batch_size)
        )
        text = jitter_embeddings(text, text_noise, rng)
        drop = torch.from_numpy(rng.random(batch_size) < text_drop)
        for group in opt.param_groups:
            group["lr"] = _lr_at(step, steps, lr, warmup=min(100, steps // 10 + 1))
        _, loss = model(
            prev.to(device), path.to(device), text.to(device), targets.to(device), drop.to(device)
        )
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        done += 1
        last = {"loss": float(loss.detach())}
        bar.update(1)
        bar.set_postfix(loss=f"{last['loss']:.3f}", refresh=False)
        if _end_of_step("gpt", bar, step, steps, last, done, t0, save, log_every, save_every, max_minutes):
            break
    bar.close()
    final_step = start + done
    if done == 0 and ckpt is not None:
        last = dict(ckpt.get("metrics", {}))
    seconds_per_step = (time.perf_counter() - t0) / max(1, done)
    val_metrics = evaluate_gpt(model, val, table, caption_row, device)
    train_metrics = evaluate_gpt(model, train, table, caption_row, device, max_clips=len(val.codes))
    metrics = {
        "step": float(final_step),
        **last,
        "seconds_per_step": seconds_per_step,
        **{f"val_{k}": v for k, v in val_metrics.items()},
        **{f"train_{k}": v for k, v in train_metrics.items()},
    }
    save(final_step, metrics)
    model.train(False)
    return metrics
