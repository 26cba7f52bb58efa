"""The VQ-VAE trainer on a tiny dataset: a few steps, the checkpoint, resuming, seeding."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from motion_env.data.dataset import load_stats
from motion_env.models.checkpoint import load_checkpoint, read_checkpoint, save_checkpoint
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.training.vqvae import (
    READ_CHANNELS,
    VQVAETrainConfig,
    context_windows,
    derivative_losses,
    read_channel_loss,
    scored,
    token_ripple,
    train_vqvae,
)

TINY_VQ = VQVAEConfig(width=16, code_dim=8, codebook_size=16, depth=1)
FAST = dict(batch_size=4, window=32, progress=False)


def test_train_vqvae_saves_resumes_and_evaluates(tiny_dataset: Path, tmp_path: Path) -> None:
    out = tmp_path / "vq.pt"
    config = VQVAETrainConfig(steps=6, save_every=3, log_every=3, **FAST)
    m1 = train_vqvae(tiny_dataset, out, config, TINY_VQ)
    assert m1["step"] == 6 and np.isfinite(m1["loss"])
    assert m1["val_mpjpe_cm"] > 0 and np.isfinite(m1["val_mpjpe_cm"])
    ckpt = read_checkpoint(out, "vqvae")
    assert ckpt["step"] == 6 and "optimizer" in ckpt and ckpt["settings"] == config.to_dict()
    assert ckpt["metrics"] == m1
    # The dataset's Mean/Std travel with the VQ-VAE, exactly, for the generator's Normalizer.
    mean, std = load_stats(tiny_dataset)
    normalizer = Normalizer.from_checkpoint(ckpt, out)
    np.testing.assert_array_equal(normalizer.mean, mean)
    np.testing.assert_array_equal(normalizer.std, std)
    assert ckpt["mean"].dtype == torch.float32 and ckpt["mean"].shape == (263,)
    model, _ = load_checkpoint(out, "vqvae", VQVAEConfig, VQVAE)
    assert model.config == TINY_VQ
    # Resuming continues from the saved step (6) to the new total (8).
    resumed = train_vqvae(tiny_dataset, out, VQVAETrainConfig(steps=8, **FAST), TINY_VQ)
    assert resumed["step"] == 8
    # Nothing left to do: the metrics of the last step come from the checkpoint.
    again = train_vqvae(tiny_dataset, out, VQVAETrainConfig(steps=8, **FAST), TINY_VQ)
    assert again["step"] == 8 and again["loss"] == resumed["loss"]
    other = VQVAEConfig(width=8, code_dim=8, codebook_size=16, depth=1)
    with pytest.raises(ValueError, match="cannot resume"):
        train_vqvae(tiny_dataset, out, VQVAETrainConfig(steps=9, **FAST), other)
    fresh = train_vqvae(tiny_dataset, out, VQVAETrainConfig(steps=2, resume=False, **FAST), other)
    assert fresh["step"] == 2


def test_train_vqvae_is_seeded(tiny_dataset: Path, tmp_path: Path) -> None:
    config = VQVAETrainConfig(steps=3, **FAST)
    a = train_vqvae(tiny_dataset, tmp_path / "a.pt", config, TINY_VQ)
    b = train_vqvae(tiny_dataset, tmp_path / "b.pt", config, TINY_VQ)
    assert a["loss"] == b["loss"] and a["val_mpjpe_cm"] == b["val_mpjpe_cm"]
    c = train_vqvae(tiny_dataset, tmp_path / "c.pt", VQVAETrainConfig(steps=3, seed=1, **FAST), TINY_VQ)
    assert c["loss"] != a["loss"]


def test_window_must_fit_the_rate(tiny_dataset: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="multiple of rate"):
        train_vqvae(tiny_dataset, tmp_path / "vq.pt", VQVAETrainConfig(steps=1, window=30), TINY_VQ)
    with pytest.raises(ValueError, match="no train clip has at least 512 frames"):
        train_vqvae(tiny_dataset, tmp_path / "vq.pt", VQVAETrainConfig(steps=1, window=512), TINY_VQ)


def _packaged_init(path: Path, mean: np.ndarray, std: np.ndarray) -> VQVAE:
    """A tiny trained-looking VQ-VAE saved as a shipped one is: float16, no optimizer, no step."""
    torch.manual_seed(0)
    model = VQVAE(TINY_VQ)
    model(torch.randn(2, 16, TINY_VQ.feature_dim))  # fills the codebook, as training does
    entries = Normalizer(mean, std).checkpoint_entries()
    save_checkpoint(
        path, kind="vqvae", config=TINY_VQ, model=model, half=True, training={"step": 1}, **entries
    )
    return load_checkpoint(path, "vqvae", VQVAEConfig, VQVAE)[0]


def test_decoder_fine_tuning_keeps_encoder_codebook_and_stats(tiny_dataset: Path, tmp_path: Path) -> None:
    mean, std = load_stats(tiny_dataset)
    # Statistics unlike the dataset's: the init's must be the ones that travel on.
    init = _packaged_init(tmp_path / "init.pt", mean + 0.5, std * 2.0)
    out = tmp_path / "fine.pt"
    smooth = dict(init=str(tmp_path / "init.pt"), freeze_encoder=True, vel_weight=0.5, acc_weight=1.0)
    config = VQVAETrainConfig(steps=3, lr=1e-2, jerk_weight=0.5, ripple_weight=1.0, **smooth, **FAST)
    metrics = train_vqvae(tiny_dataset, out, config)
    for term in ("loss", "recon", "vel_l1", "acc_l1", "jerk_l1", "ripple_l1"):
        assert np.isfinite(metrics[term]) and metrics[term] > 0, term
    tuned, ckpt = load_checkpoint(out, "vqvae", VQVAEConfig, VQVAE)
    before, after = init.state_dict(), tuned.state_dict()
    for name in before:
        if name.startswith(("encoder.", "quantizer.")):
            assert torch.equal(before[name], after[name]), name
    assert any(not torch.equal(before[n], after[n]) for n in before if n.startswith("decoder."))
    normalizer = Normalizer.from_checkpoint(ckpt, out)
    np.testing.assert_array_equal(normalizer.mean, (mean + 0.5).astype(np.float32))
    np.testing.assert_array_equal(normalizer.std, (std * 2.0).astype(np.float32))
    x = torch.randn(3, 32, TINY_VQ.feature_dim)
    assert torch.equal(init.encode(x), tuned.encode(x))
    # Resuming continues the decoder-only run; switching the freeze in between is refused.
    assert train_vqvae(tiny_dataset, out, VQVAETrainConfig(steps=4, **smooth, **FAST))["step"] == 4
    with pytest.raises(ValueError, match="freeze_encoder"):
        train_vqvae(tiny_dataset, out, VQVAETrainConfig(steps=5, init=smooth["init"], **FAST))


def test_token_ripple_keeps_only_the_token_periodic_error() -> None:
    t = torch.arange(24, dtype=torch.float32)
    ripple = torch.tensor([0.0, 0.0, -1.0, 1.0]).repeat(6)[None, :, None]
    assert torch.allclose(
        token_ripple(ripple + 0.3, 4)[0, :, 0], torch.tensor([0.0, 0.0, -1.0, 1.0]), atol=1e-6
    )
    # A slow drift leaks in by no more than it changes within one token.
    slow = (0.01 * t)[None, :, None]
    assert token_ripple(slow, 4).abs().max() <= 0.015 + 1e-6
    # A partial last token is left out rather than folded onto the wrong phases.
    assert token_ripple(ripple[:, :23], 4).shape == (1, 4, 1)
    with pytest.raises(ValueError, match="fewer than one token"):
        token_ripple(ripple[:, :3], 4)


def test_ripple_loss_sees_a_stalling_decoder_and_not_a_smooth_one() -> None:
    # A hand moving at constant speed, decoded with a stall at each token's end (lagging then
    # catching up at the boundary), against one decoded with a steady offset.
    t = torch.arange(48, dtype=torch.float32)
    target = torch.zeros(1, 48, 263)
    target[..., 4:] = 0.05 * t[None, :, None]
    stall = target.clone()
    stall[:, 3::4, 4:] -= 0.02
    offset = target + 0.01
    config = VQVAETrainConfig(ripple_weight=1.0)
    assert derivative_losses(stall, target, config)["ripple_l1"] > 1e-3
    assert derivative_losses(offset, target, config)["ripple_l1"] < 1e-6


def test_height_loss_sees_a_bobbing_root_and_nothing_else() -> None:
    # The root height (channel 3) is outside the RIC channels the joints' losses read: its own
    # acceleration loss sees a decoded bob there, not a steady offset, and not a bob of a joint.
    t = torch.arange(48, dtype=torch.float32)
    target = torch.zeros(1, 48, 263)
    target[..., 3] = 0.01 * t
    bob = target.clone()
    bob[:, ::2, 3] += 0.02
    config = VQVAETrainConfig(height_acc_weight=2.0)
    losses = derivative_losses(bob, target, config)
    assert losses["height_acc_l1"] > 1e-2 and losses["smooth"] == pytest.approx(2.0 * losses["height_acc_l1"])
    assert derivative_losses(target + 0.5, target, config)["height_acc_l1"] < 1e-6
    joint = target.clone()
    joint[:, ::2, 4] += 0.02
    assert derivative_losses(joint, target, config)["height_acc_l1"] == 0.0
    assert "height_acc_l1" not in derivative_losses(bob, target, VQVAETrainConfig())


def test_read_channels_weigh_what_the_generator_reads() -> None:
    # The body is built from the root channels and the joints' positions; the rotations and local
    # velocities are not read, so an error there adds nothing, and one in a read channel adds
    # (weight - 1) times its share of the model's all-channel mean.
    assert READ_CHANNELS.tolist() == [*range(0, 67), 259, 260, 261, 262]
    target = torch.zeros(2, 8, 263)
    unread = target.clone()
    unread[..., 67:259] = 0.5
    read = target.clone()
    read[..., 4:67] = 0.5
    assert float(read_channel_loss(unread, target, 4.0)) == 0.0
    assert float(read_channel_loss(read, target, 1.0)) == 0.0
    expected = 3.0 * (71 / 263) * F.smooth_l1_loss(read[..., READ_CHANNELS], target[..., READ_CHANNELS])
    assert torch.isclose(read_channel_loss(read, target, 4.0), expected)
    with pytest.raises(ValueError, match="read_weight"):
        VQVAETrainConfig(read_weight=0.0)


def test_smoothness_options_are_checked() -> None:
    with pytest.raises(ValueError, match="acc_weight"):
        VQVAETrainConfig(acc_weight=-1.0)
    with pytest.raises(ValueError, match="ripple_weight"):
        VQVAETrainConfig(ripple_weight=-1.0)
    with pytest.raises(ValueError, match="init"):
        VQVAETrainConfig(init=" ")
    with pytest.raises(ValueError, match="freeze_encoder"):
        VQVAETrainConfig(freeze_encoder=True, resume=False)


def test_freezing_needs_a_trained_model(tiny_dataset: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="set init"):
        train_vqvae(tiny_dataset, tmp_path / "vq.pt", VQVAETrainConfig(steps=1, freeze_encoder=True, **FAST))
    init = tmp_path / "init.pt"
    _packaged_init(init, *load_stats(tiny_dataset))
    other = VQVAEConfig(width=8, code_dim=8, codebook_size=16, depth=1)
    config = VQVAETrainConfig(steps=1, init=str(init), **FAST)
    with pytest.raises(ValueError, match="not the given"):
        train_vqvae(tiny_dataset, tmp_path / "vq.pt", config, other)


def test_context_windows_put_each_window_after_its_history() -> None:
    # Frame f of take i holds 100 * i + f in every channel, so a crop says where it comes from.
    feats = [
        torch.arange(n, dtype=torch.float32)[:, None].repeat(1, 3) + 100 * i for i, n in enumerate((40, 90))
    ]
    crops, first = context_windows(feats, np.array([1, 1, 0]), np.array([50, 13, 2]), 8, 24, 4)
    assert crops.shape == (3, 32, 3) and first.tolist() == [24, 12, 0]
    # Deep in a take: 24 frames of history, then the window, nothing padded.
    assert crops[0, :, 0].tolist() == [126.0 + f for f in range(32)]
    # Nearer its start than the context: the crop begins at the take's first frame (the decoder's
    # empty history is the take's start), the window moves back onto a token boundary (13 -> 12),
    # and zeros pad the crop after its end.
    assert crops[1, :20, 0].tolist() == [100.0 + f for f in range(20)] and not crops[1, 20:].any()
    assert scored(crops, first, 8)[1, :, 0].tolist() == [112.0 + f for f in range(8)]
    assert scored(crops, first, 8)[2, :, 0].tolist() == [float(f) for f in range(8)]


def test_context_is_checked_and_trains_the_decoder(tiny_dataset: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="context must be a multiple of 4"):
        VQVAETrainConfig(context=6, freeze_encoder=True, init="x.pt")
    with pytest.raises(ValueError, match="needs freeze_encoder"):
        VQVAETrainConfig(context=8)
    init = tmp_path / "init.pt"
    _packaged_init(init, *load_stats(tiny_dataset))
    config = VQVAETrainConfig(steps=2, init=str(init), freeze_encoder=True, context=16, lr=1e-2, **FAST)
    metrics = train_vqvae(tiny_dataset, tmp_path / "ctx.pt", config)
    assert np.isfinite(metrics["loss"]) and metrics["recon"] > 0
    before = load_checkpoint(init, "vqvae", VQVAEConfig, VQVAE)[0].state_dict()
    after = load_checkpoint(tmp_path / "ctx.pt", "vqvae", VQVAEConfig, VQVAE)[0].state_dict()
    assert all(torch.equal(before[k], after[k]) for k in before if k.startswith("encoder."))
    assert any(not torch.equal(before[k], after[k]) for k in before if k.startswith("decoder."))


def _acc_l1(joint: int, frames: slice | int, **settings: object) -> float:
    """The acceleration loss of a 2-cm jolt on `joint`'s x at `frames` of a still 48-frame window."""
    target = torch.zeros(1, 48, 263)
    decoded = target.clone()
    decoded[:, frames, 4 + (joint - 1) * 3] += 0.02
    config = VQVAETrainConfig(acc_weight=1.0, **settings)
    return float(derivative_losses(decoded, target, config)["acc_l1"])


def test_leg_weight_scales_the_legs_share_of_the_difference_losses() -> None:
    # A decoded jitter on the left knee (joint 4) alone, and one on the left wrist (joint 20).
    def acc(joint: int, leg_weight: float) -> float:
        return _acc_l1(joint, slice(None, None, 2), leg_weight=leg_weight)

    knee, wrist = 4, 20
    assert acc(knee, 0.0) == 0.0 < acc(knee, 0.3) < acc(knee, 1.0) == pytest.approx(acc(wrist, 1.0))
    assert acc(wrist, 0.3) > acc(wrist, 1.0)  # the rest's share grows as the legs' shrinks
    with pytest.raises(ValueError, match="leg_weight"):
        VQVAETrainConfig(smooth_joints="upper", leg_weight=0.5)


def test_the_feet_sets_smooth_the_ankles_and_toes_but_not_the_knees() -> None:
    def acc(joint: int, smooth_joints: str) -> float:
        return _acc_l1(joint, slice(None, None, 2), smooth_joints=smooth_joints)

    ankle, toe, knee, wrist = 7, 10, 4, 20
    assert acc(ankle, "upper") == acc(toe, "upper") == acc(knee, "upper") == 0.0
    assert acc(ankle, "upper+feet") > 0 and acc(toe, "upper+feet") > 0 and acc(knee, "upper+feet") == 0.0
    assert acc(toe, "upper+toes") > 0 and acc(ankle, "upper+toes") == 0.0
    assert acc(wrist, "upper+feet") > 0


def test_start_weight_scales_the_first_frames_share_of_the_difference_losses() -> None:
    # A wrist's jolt in the window's first frames (frame 2), and the same jolt later on (frame 30).
    def acc(frame: int, start_weight: float) -> float:
        return _acc_l1(20, frame, start_weight=start_weight)

    start, later = 2, 30
    assert acc(start, 1.0) == pytest.approx(acc(later, 1.0))
    assert acc(start, 4.0) == pytest.approx(4 * acc(start, 1.0))
    assert acc(later, 4.0) == acc(later, 1.0)
    with pytest.raises(ValueError, match="start_weight"):
        VQVAETrainConfig(start_weight=2.0, context=8, freeze_encoder=True, init="x.pt")
