"""Training of the motion VQ-VAE on random windows of normalised train features.

Reads a HumanML3D-layout dataset (:mod:`motion_env.data.dataset`); the features are normalised
with the dataset's Mean/Std (:class:`~motion_env.models.normalizer.Normalizer`), which the
checkpoint stores (``mean``, ``std``) for the generator. Every window of the train clips is
equally likely. Ends with the val reconstruction error (:func:`evaluate_vqvae`). The loop, the
learning-rate schedule and the checkpoints are :mod:`motion_env.training.loop`'s.

Fine-tuning the decoder alone (``init`` = a trained VQ-VAE, ``freeze_encoder``): the encoder and
the codebook stay as they are, so every clip keeps its tokens and a body GPT trained on them stays
valid, while extra losses on the differences of the decoded joint positions (``vel_weight``,
``acc_weight``, ``jerk_weight``; on the joints ``smooth_joints`` names, the legs' share set by
``leg_weight``, a window's first frames' by ``start_weight``) teach the decoder to stop rippling at
the token rate;
``ripple_weight`` aims at that ripple alone (:func:`token_ripple`), and ``read_weight`` puts the
decoder's capacity on the channels the generator builds its body from (:data:`READ_CHANNELS`).
``context`` decodes each window after the frames before it (:func:`context_windows`): the
generator decodes whole clips, so its decoder meets an empty history only at a clip's first frame,
while a window cut from the middle of a take starts one at a frame where the take is in motion.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from motion_env.models.checkpoint import config_from_dict, read_checkpoint
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.motion.skeleton import FOOT_CONTACT, NUM_JOINTS, RIC, ROOT_ROT_VEL, ROOT_Y
from motion_env.motion.validation import NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt
from motion_env.training import loop
from motion_env.training.config import TrainConfig

CHECKPOINT_KIND = "vqvae"


@dataclass(kw_only=True)
class VQVAETrainConfig(TrainConfig):
    """How to train the VQ-VAE (stored in its checkpoint under ``"settings"``)."""

    steps: PositiveInt = 3000  # total optimisation steps (those of a resumed run included)
    batch_size: PositiveInt = 64  # windows per step
    lr: PositiveFloat = 4e-4  # peak AdamW learning rate (linear warm-up, cosine decay to a tenth)
    window: PositiveInt = 64  # frames per training window (a multiple of the VQ-VAE's rate)
    save_every: PositiveInt = 250  # steps between checkpoints (one is also written at the end)
    init: str | None = None  # VQ-VAE checkpoint (packaged ones too) a fresh run starts from, Mean/Std kept
    freeze_encoder: bool = False  # train the decoder only: encoder and codebook stay, so do all tokens
    vel_weight: NonNegativeFloat = 0.0  # L1 loss on frame-to-frame changes of root-relative joint positions
    acc_weight: NonNegativeFloat = 0.0  # L1 loss on their second differences (acceleration)
    jerk_weight: NonNegativeFloat = 0.0  # L1 loss on their third differences (jerk)
    ripple_weight: NonNegativeFloat = 0.0  # L1 loss on the token-periodic part of the acceleration error
    height_acc_weight: NonNegativeFloat = 0.0  # L1 loss on the second differences of the root height
    smooth_joints: str = "all"  # joints those losses apply to: "all", "upper", "upper+feet", "upper+toes"
    leg_weight: NonNegativeFloat = 1.0  # those losses' weight on the legs (of smooth_joints) against the rest
    read_weight: PositiveFloat = 1.0  # reconstruction weight of the channels the body is read from
    context: NonNegativeInt = 0  # frames before each window decoded as its history, not scored (decoder only)
    start_weight: PositiveFloat = 1.0  # difference losses' weight on a window's first START_FRAMES frames

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.smooth_joints not in SMOOTH_JOINTS:
            raise ValueError(
                f"VQVAETrainConfig.smooth_joints must be one of {tuple(SMOOTH_JOINTS)}, "
                f"got {self.smooth_joints!r}"
            )
        if self.leg_weight != 1.0 and not set(SMOOTH_JOINTS[self.smooth_joints]) & set(LEG_JOINTS):
            raise ValueError(
                f"VQVAETrainConfig.leg_weight weighs the legs' difference losses, and that set of "
                f"joints has no leg joint; got leg_weight={self.leg_weight!r} "
                f"with smooth_joints={self.smooth_joints!r}"
            )
        if self.start_weight != 1.0 and self.context:
            raise ValueError(
                f"VQVAETrainConfig.start_weight weighs a window's first frames, decoded from an empty "
                f"history, which a window with context has not; got start_weight={self.start_weight!r} "
                f"with context={self.context!r}"
            )
        if self.init is not None and not (isinstance(self.init, str) and self.init.strip()):
            raise ValueError(f"VQVAETrainConfig.init must be a checkpoint path or None, got {self.init!r}")
        if self.context % 4 or (self.context and not self.freeze_encoder):
            # A multiple of any rate (2 or 4) keeps the scored window on a token boundary; the
            # encoder's commitment loss would also score the history and the padding after it.
            raise ValueError(
                f"VQVAETrainConfig.context must be a multiple of 4 frames and needs freeze_encoder, "
                f"got context={self.context!r}, freeze_encoder={self.freeze_encoder!r}"
            )
        if self.freeze_encoder and self.init is None and not self.resume:
            # A frozen random encoder and an empty codebook would give every frame the same token.
            raise ValueError("VQVAETrainConfig.freeze_encoder needs a trained VQ-VAE: set init (or resume)")


# The joints the difference losses may cover (the root is not among the RIC channels). "upper":
# the legs keep the plain reconstruction loss alone, because smoothing them too blurred steps,
# raising foot skating and floor contacts of walks and runs in the MuJoCo replay. "upper+feet"
# (shipped since session 29) adds the ankles and toes, whose toe-off pops are the decoder's (val
# backward walks 44 -> 12 % of clips with a pop) without the whole legs' larger Fréchet distance;
# "upper+toes" the toes alone (measured: the same pops, runs' skating 0.93 -> 1.10x on test).
_UPPER = (3, 6, 9, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21)  # spine, neck, head, collars, arms
_ANKLES, _TOES = (7, 8), (10, 11)
SMOOTH_JOINTS = {
    "all": tuple(range(1, NUM_JOINTS)),
    "upper": _UPPER,
    "upper+toes": tuple(sorted(_UPPER + _TOES)),
    "upper+feet": tuple(sorted(_UPPER + _ANKLES + _TOES)),
}
# Hips, knees, ankles and toes: "all" but "upper" (``leg_weight`` weighs those a set has).
LEG_JOINTS = tuple(sorted(set(SMOOTH_JOINTS["all"]) - set(_UPPER)))
# Frames at a window's start, decoded from an empty history as a generated clip's first frames are
# (where most pops were), that ``start_weight`` weighs in the difference losses: two tokens.
START_FRAMES = 8


# The channels the generator builds its body from (:func:`motion_env.motion.features.features_to_joints`:
# root velocities and height, the joints' positions) and its foot contacts. The rotations and local
# velocities (192 of the 263 channels) are only targets of training; weighting what is read
# (``read_weight`` > 1) gives the decoder's capacity to the body it actually puts out.
READ_CHANNELS = np.r_[ROOT_ROT_VEL.start : RIC.stop, FOOT_CONTACT]


def context_windows(
    feats: list[torch.Tensor], clips: np.ndarray, starts: np.ndarray, window: int, context: int, rate: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """Windows of `window` frames, each with up to `context` frames of its take before it.

    Window n is frames ``starts[n] ...`` of ``feats[clips[n]]``. Its crop begins `context` frames
    earlier, or at the take's first frame when the window starts sooner (then the window moves
    back to a multiple of `rate` frames into the take, so that it starts on a token boundary, as
    it does after a full history); crops are laid from index 0 (the decoder's empty history is
    the crop's start) and padded with zeros after their end (a causal decoder never reads them).

    Returns:
        ((B, context + window, C) crops, (B,) long index of each window's first frame in its crop).
    """
    crops, first = [], []
    for i, o in zip(clips, starts, strict=True):
        o = int(o)
        begin = o - context if o >= context else 0
        if begin == 0:
            o -= o % rate
        crop = feats[int(i)][begin : o + window]
        crops.append(F.pad(crop, (0, 0, 0, context + window - crop.shape[0])))
        first.append(o - begin)
    return torch.stack(crops), torch.as_tensor(first, dtype=torch.long)


def scored(x: torch.Tensor, first: torch.Tensor, window: int) -> torch.Tensor:
    """(B, T, C) -> (B, window, C): each row's `window` frames from its index ``first[b]``."""
    frames = first.to(x.device)[:, None] + torch.arange(window, device=x.device)
    return x[torch.arange(x.shape[0], device=x.device)[:, None], frames]


def read_channel_loss(recon: torch.Tensor, target: torch.Tensor, weight: float) -> torch.Tensor:
    """The extra reconstruction loss that makes each read channel weigh `weight` (others 1)."""
    if weight == 1.0:
        return recon.new_zeros(())
    share = len(READ_CHANNELS) / recon.shape[-1]  # the model's own loss is a mean over all channels
    return (weight - 1.0) * share * F.smooth_l1_loss(recon[..., READ_CHANNELS], target[..., READ_CHANNELS])


def token_ripple(error: torch.Tensor, rate: int) -> torch.Tensor:
    """The part of a per-frame error that repeats once per token: (B, rate, C).

    Args:
        error: (B, T, C), frame t of the window at phase t % rate of its token (windows start
            on a token boundary).
        rate: frames per token.

    Returns:
        the error averaged over the window's tokens at each phase, less its mean over phases:
        what a decoder that stalls towards each token's end and catches up at the next adds,
        while an error shared by all phases is left to the other losses (a slow drift leaks in
        by no more than it changes within one token).
    """
    whole = error.shape[1] // rate * rate
    if whole == 0:
        raise ValueError(f"token_ripple: {error.shape[1]} frames, fewer than one token of {rate}")
    per_phase = error[:, :whole].reshape(error.shape[0], whole // rate, rate, -1).mean(dim=1)
    return per_phase - per_phase.mean(dim=1, keepdim=True)


def derivative_losses(
    recon: torch.Tensor, target: torch.Tensor, config: VQVAETrainConfig, rate: int = 4
) -> dict:
    """L1 losses on the 1st/2nd/3rd frame differences of the root-relative joint positions (and
    on the 2nd of the root height).

    Args:
        recon, target: (B, T, 263) normalised features, T starting on a token boundary.
        config: the weights; a term whose weight is 0 is not computed.
        rate: frames per token (for ``ripple_weight``).

    Returns:
        {"vel_l1", "acc_l1", "jerk_l1", "ripple_l1", "height_acc_l1"} (those with a weight) and
        "smooth": their weighted sum.
    """
    # One Std for all RIC channels (HumanML3D's grouped statistics), so differences of the
    # normalised channels are the joints' differences in one scale. They are far below 1, where
    # the smooth L1 of the model's own velocity loss is a tiny quadratic: L1 keeps a pull on
    # the small token-rate ripple.
    joints = np.array(SMOOTH_JOINTS[config.smooth_joints])
    channels = RIC.start + ((joints[:, None] - 1) * 3 + np.arange(3)).ravel()
    pred, true = recon[..., channels], target[..., channels]
    # Each channel's share of a term: the legs' scaled by leg_weight (1: a plain mean).
    legs = np.repeat(np.isin(joints, LEG_JOINTS), 3)
    share = torch.as_tensor(np.where(legs, config.leg_weight, 1.0), dtype=recon.dtype, device=recon.device)
    share = share / share.mean()
    # Each frame's share too: a window's first START_FRAMES scaled by start_weight (1: a plain mean).
    steps = torch.ones(recon.shape[1], 1, dtype=recon.dtype, device=recon.device)
    steps[:START_FRAMES] = config.start_weight
    errors: dict[int, torch.Tensor] = {}  # the error of each order of frame differences, made once

    def error(order: int) -> torch.Tensor:
        if order not in errors:
            errors[order] = torch.diff(pred, n=order, dim=1) - torch.diff(true, n=order, dim=1)
        return errors[order]

    terms, total = {}, recon.new_zeros(())
    for order, name, weight in ((1, "vel_l1", config.vel_weight), (2, "acc_l1", config.acc_weight),
                                (3, "jerk_l1", config.jerk_weight)):  # fmt: skip
        if weight > 0:
            terms[name] = (error(order).abs() * share * steps[order:]).mean()
            total = total + weight * terms[name]
    if config.ripple_weight > 0:
        # error(2)[:, k] is centred on frame k + 1: dropping the first rate - 1 puts a token
        # boundary (frame rate) at phase 0.
        terms["ripple_l1"] = (token_ripple(error(2)[:, rate - 1 :], rate).abs() * share).mean()
        total = total + config.ripple_weight * terms["ripple_l1"]
    if config.height_acc_weight > 0:
        # The root height is not among the RIC channels: without this its decoded quantisation
        # noise bobs a standing body's pelvis at 1.3 m/s^2 where a real one moves at 0.05.
        height_error = recon[..., ROOT_Y.start] - target[..., ROOT_Y.start]
        terms["height_acc_l1"] = torch.diff(height_error, n=2, dim=1).abs().mean()
        total = total + config.height_acc_weight * terms["height_acc_l1"]
    return {**terms, "smooth": total}


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


def _starting_point(
    out_path: Path, config: VQVAETrainConfig, model_config: VQVAEConfig | None
) -> tuple[VQVAEConfig, dict[str, Any] | None, dict[str, Any] | None]:
    """(model config, the checkpoint to resume or None, the ``init`` checkpoint or None)."""
    init = read_checkpoint(config.init, CHECKPOINT_KIND) if config.init is not None else None
    if init is not None:
        stored = config_from_dict(VQVAEConfig, init["config"])
        if model_config is not None and model_config != stored:
            raise ValueError(f"{config.init}: holds a VQ-VAE with {stored}, not the given {model_config}")
        model_config = stored
    model_config = model_config or VQVAEConfig()
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, model_config)
    frozen = ckpt is not None and bool(ckpt.get("settings", {}).get("freeze_encoder", False))
    if ckpt is not None and frozen != config.freeze_encoder:
        raise ValueError(
            f"{out_path}: cannot resume with freeze_encoder={config.freeze_encoder}, it was trained "
            "with the other setting; pass resume=False (--no-resume) or another out_path"
        )
    if config.freeze_encoder and ckpt is None and init is None:
        raise ValueError("freeze_encoder needs a trained VQ-VAE to start from: set init")
    return model_config, ckpt, init


def _normalizer(
    data_dir: Path, out_path: Path, config: VQVAETrainConfig, ckpt: dict | None, init: dict | None
) -> Normalizer:
    """The Mean/Std of the checkpoint continued (the run's own, else ``init``'s), else the dataset's."""
    # A trained model's input space is defined by the statistics it was trained with.
    if ckpt is not None and "mean" in ckpt:
        return Normalizer.from_checkpoint(ckpt, out_path)
    if init is not None and "mean" in init:
        return Normalizer.from_checkpoint(init, str(config.init))
    return loop.load_normalizer(data_dir)


def _train_mode(model: VQVAE, freeze_encoder: bool) -> None:
    model.train()
    if freeze_encoder:
        # A quantizer in training mode moves its codes (EMA) and re-seeds unused ones.
        model.encoder.eval()
        model.quantizer.eval()


def _batch_losses(
    model: VQVAE, config: VQVAETrainConfig, feats: list[torch.Tensor], clips: np.ndarray, starts: np.ndarray
) -> dict[str, torch.Tensor]:
    """The losses of one batch: windows ``starts`` of ``feats[clips]`` (after their history, with
    ``config.context``), "loss" the total to minimise."""
    window, device = config.window, config.device
    if config.context:
        crops, first = context_windows(feats, clips, starts, window, config.context, model.rate)
        crops = crops.to(device)
        full, _, q = model(crops)
        recon, x = scored(full, first, window), scored(crops, first, window)
        # No commitment term (the encoder is frozen); "commit" and "perplexity" are logged over
        # the whole crops.
        losses = {**q, **model.reconstruction_losses(recon, x)}
    else:
        x = torch.stack([feats[i][o : o + window] for i, o in zip(clips, starts, strict=True)]).to(device)
        recon, _, losses = model(x)
    extra = derivative_losses(recon, x, config, model.rate)
    losses["loss"] = losses["loss"] + extra.pop("smooth") + read_channel_loss(recon, x, config.read_weight)
    return {**losses, **extra}


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
        config: training settings (default VQVAETrainConfig()). With ``config.init``, a fresh
            run starts from that checkpoint's weights and keeps its Mean/Std (those of a
            resumed run come from the run's own checkpoint); otherwise from the dataset's.
        model_config: model config (default: that of ``config.init``, else VQVAEConfig());
            resuming needs the same.

    Returns:
        final metrics: "step", the loss terms of the last step ("loss", ...),
        "seconds_per_step" and the val metrics of :func:`evaluate_vqvae` (prefixed "val_").
    """
    data_dir, out_path = Path(data_dir), Path(out_path)
    config = config or VQVAETrainConfig()
    model_config, ckpt, init = _starting_point(out_path, config, model_config)
    window, device = config.window, config.device
    if window % model_config.rate or window < model_config.rate:
        raise ValueError(f"window ({window}) must be a positive multiple of rate ({model_config.rate})")
    normalizer = _normalizer(data_dir, out_path, config, ckpt, init)
    train = [c for c in loop.load_split(data_dir, "train") if len(c.features) >= window]
    if not train:
        raise ValueError(f"{data_dir}: no train clip has at least {window} frames")
    val = loop.load_split(data_dir, "val")
    feats = [torch.from_numpy(normalizer.normalize(c.features)) for c in train]
    lengths = np.array([f.shape[0] - window + 1 for f in feats], dtype=np.float64)
    weights = lengths / lengths.sum()  # every window equally likely

    torch.manual_seed(config.seed)
    model = VQVAE(model_config).to(device)
    if ckpt is None and init is not None:
        model.load_state_dict(init["model"])
    if config.freeze_encoder:
        model.encoder.requires_grad_(False)  # the quantizer has no parameters, only buffers
    params = [p for p in model.parameters() if p.requires_grad]
    opt = torch.optim.AdamW(params, lr=config.lr, betas=(0.9, 0.99), weight_decay=0.0)
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
        _train_mode(model, config.freeze_encoder)
        idx = rng.choice(len(feats), size=config.batch_size, p=weights)
        offs = (rng.random(config.batch_size) * lengths[idx]).astype(int)
        losses = _batch_losses(model, config, feats, idx, offs)
        opt.zero_grad(set_to_none=True)
        losses["loss"].backward()
        torch.nn.utils.clip_grad_norm_(params, 1.0)
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
