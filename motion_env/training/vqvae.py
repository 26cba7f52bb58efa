"""Training of the motion VQ-VAE on random windows of normalised train features.

Reads a HumanML3D-layout dataset (:mod:`motion_env.data.dataset`); the features are normalised
with the dataset's Mean/Std (:class:`~motion_env.models.normalizer.Normalizer`), which the
checkpoint stores (``mean``, ``std``) for the generator. Every window of the train clips is
equally likely. Ends with the val reconstruction error (:func:`evaluate_vqvae`). The loop, the
learning-rate schedule and the checkpoints are :mod:`motion_env.training.loop`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.motion.checks import check_above, check_at_least
from motion_env.training import loop
from motion_env.training.config import TrainConfig

CHECKPOINT_KIND = "vqvae"


@dataclass(kw_only=True)
class VQVAETrainConfig(TrainConfig):
    """How to train the VQ-VAE (stored in its checkpoint under ``"settings"``)."""

    steps: int = 3000  # total optimisation steps (those of a resumed run included)
    batch_size: int = 64  # windows per step
    lr: float = 4e-4  # peak AdamW learning rate (linear warm-up, cosine decay to a tenth)
    window: int = 64  # frames per training window (a multiple of the VQ-VAE's rate)
    save_every: int = 250  # steps between checkpoints (one is also written at the end)

    def __post_init__(self) -> None:
        super().__post_init__()
        check_at_least(self, 1, "steps", "batch_size", "window")
        check_above(self, 0, "lr")


@torch.no_grad()
def evaluate_vqvae(
    model: VQVAE, clips: list[Any], normalizer: Normalizer, device: str | torch.device = "cpu"
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
        x = torch.from_numpy(normalizer.normalize(feats[:n]))[None].to(device)  # (1, n, 263)
        codes = model.encode(x)
        recon = model.decode(codes)[0].cpu().numpy()
        used.update(codes.flatten().tolist())
        l1.append(float(np.abs(recon - x[0].cpu().numpy()).mean()))
        pred = features_to_joints(normalizer.denormalize(recon))
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
    config: VQVAETrainConfig | None = None,
    model_config: VQVAEConfig | None = None,
) -> dict[str, float]:
    """Train the motion VQ-VAE on random windows of normalised train features.

    Args:
        data_dir: HumanML3D-layout dataset (train/val splits, Mean.npy/Std.npy).
        out_path: checkpoint written every ``config.save_every`` steps and at the end (with
            optimizer state and step, so a later call with ``config.resume`` continues).
        config: training settings (default VQVAETrainConfig()).
        model_config: model config (default VQVAEConfig()); resuming needs the same.

    Returns:
        final metrics: "step", the loss terms of the last step ("loss", ...),
        "seconds_per_step" and the val metrics of :func:`evaluate_vqvae` (prefixed "val_").
    """
    data_dir, out_path = Path(data_dir), Path(out_path)
    config = config or VQVAETrainConfig()
    model_config = model_config or VQVAEConfig()
    window, device = config.window, config.device
    if window % model_config.rate or window < model_config.rate:
        raise ValueError(f"window ({window}) must be a positive multiple of rate ({model_config.rate})")
    normalizer = loop.load_normalizer(data_dir)
    train = [c for c in loop.load_split(data_dir, "train") if len(c.features) >= window]
    if not train:
        raise ValueError(f"{data_dir}: no train clip has at least {window} frames")
    val = loop.load_split(data_dir, "val")
    feats = [torch.from_numpy(normalizer.normalize(c.features)) for c in train]
    lengths = np.array([f.shape[0] - window + 1 for f in feats], dtype=np.float64)
    weights = lengths / lengths.sum()  # every window equally likely

    torch.manual_seed(config.seed)
    model = VQVAE(model_config).to(device)
    opt = torch.optim.AdamW(model.parameters(), lr=config.lr, betas=(0.9, 0.99), weight_decay=0.0)
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, model_config)
    start = loop.restore(ckpt, model, opt)
    rng = np.random.default_rng(
        [config.seed, start]
    )  # resuming at step s draws what a fresh run would not repeat

    def save(step: int, metrics: dict[str, float]) -> None:
        loop.save_training_checkpoint(
            out_path, kind=CHECKPOINT_KIND, model=model, optimizer=opt, step=step, settings=config,
            metrics=metrics, **normalizer.checkpoint_entries(),
        )  # fmt: skip

    def train_step(step: int) -> dict[str, float]:
        model.train()
        idx = rng.choice(len(feats), size=config.batch_size, p=weights)
        offs = (rng.random(config.batch_size) * lengths[idx]).astype(int)
        x = torch.stack([feats[i][o : o + window] for i, o in zip(idx, offs, strict=True)]).to(device)
        _, _, losses = model(x)
        opt.zero_grad(set_to_none=True)
        losses["loss"].backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        opt.step()
        return {k: float(v.detach()) for k, v in losses.items()}

    result = loop.run_loop(
        CHECKPOINT_KIND, config, opt, train_step, warmup=min(200, config.steps // 10 + 1), start=start,
        save=save, evaluate=lambda: evaluate_vqvae(model, val, normalizer, device),
        postfix={"loss": ".4f", "perplexity": ".0f"},
    )  # fmt: skip
    metrics = loop.final_metrics(result, ckpt, {"val": evaluate_vqvae(model, val, normalizer, device)})
    save(result.step, metrics)
    model.train(False)
    return metrics
