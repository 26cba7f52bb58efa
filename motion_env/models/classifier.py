"""The action/style classifier of real takes: the judge of generated motion, not part of the generator.

It answers "which action, in which style, does this clip show?" for the Bandai Namco actions and
styles the generator was trained on, so generated clips can be scored against the caption that
asked for them (``motion-env eval captions``), and its pooled features measure how far generated
clips lie from real ones (Fréchet distance and diversity, ``motion-env eval natural``).

What it reads (:func:`pose_features`, per frame, numpy): every joint relative to the pelvis in
the body's own heading frame (x, z) and above the floor (y), the pelvis velocity in the heading
frame and the heading's turn rate. Nothing depends on where the clip starts or which way it faces
(a test checks it). Clips are cut into windows of ``config.window`` frames (4 s); a shorter clip
is padded and masked, a longer one is scored by the mean of its windows' log-probabilities.

The network (:class:`MotionClassifier`): a linear input layer, ``layers`` residual 1-D
convolutions, a masked mean + max over time (:meth:`MotionClassifier.pool`, the features) and two
heads, action and style. Style is learnt only from takes that have one of ``config.styles`` (CMU
takes have an action only). The feature normalisation travels with the weights as buffers; the
checkpoint is the project's format (:mod:`motion_env.models.checkpoint`, kind
``"motion_classifier"``). Trained by ``motion-env train classifier``
(:mod:`motion_env.training.classifier`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from motion_env.models.checkpoint import load_checkpoint, save_checkpoint
from motion_env.motion.kinematics import floor_height, heading_from_joints, rotate_y, to_heading_frame
from motion_env.motion.skeleton import FPS, NUM_JOINTS
from motion_env.motion.validation import CheckedConfig, PositiveInt

__all__ = [
    "CHECKPOINT_KIND",
    "DEFAULT_CLASSIFIER",
    "FEATURE_DIM",
    "ClassifierConfig",
    "MotionClassifier",
    "classify",
    "clip_embeddings",
    "load_classifier",
    "pose_features",
    "save_classifier",
]

CHECKPOINT_KIND = "motion_classifier"
DEFAULT_CLASSIFIER = Path(__file__).resolve().parents[1] / "weights" / "classifier.pt"
FEATURE_DIM = NUM_JOINTS * 3 + 3  # local joints + (lateral, forward) pelvis velocity + turn rate


@dataclass
class ClassifierConfig(CheckedConfig):
    """The classifier's architecture and the labels it knows.

    Attributes:
        actions: action labels, in the order of the action head.
        styles: style labels, in the order of the style head.
        window: frames per window (20 fps; 80 = 4 s).
        width: channels of the convolutions.
        layers: residual convolution blocks.
        kernel: temporal kernel size (odd).
        dropout: dropout in the blocks and before the heads.
    """

    actions: tuple[str, ...] = ()
    styles: tuple[str, ...] = ()
    window: PositiveInt = 80
    width: PositiveInt = 96
    layers: PositiveInt = 3
    kernel: PositiveInt = 5
    dropout: Annotated[float, "[0, 1)"] = 0.1

    def __post_init__(self) -> None:
        super().__post_init__()
        self.actions, self.styles = tuple(self.actions), tuple(self.styles)
        for name, labels in (("actions", self.actions), ("styles", self.styles)):
            if len(labels) < 2 or len(set(labels)) != len(labels):
                raise ValueError(f"ClassifierConfig.{name} must be two or more distinct labels, got {labels}")
        if self.kernel % 2 == 0:
            raise ValueError(f"ClassifierConfig.kernel must be odd, got {self.kernel}")


# --------------------------------------------------------------------------------------------
# Features: what the classifier sees of a clip.
# --------------------------------------------------------------------------------------------


def pose_features(joints: np.ndarray) -> np.ndarray:
    """Per-frame features of a clip, invariant to its start position and heading.

    Args:
        joints: (T, 22, 3) world joint positions (Y up, metres, 20 fps), T >= 2.
    Returns:
        (T, 69) float32: the 22 joints relative to the pelvis in the frame's heading frame
        (x, z) with their height above the floor (y), then the pelvis velocity (lateral, forward;
        m/s) in the heading frame and the turn rate (rad/s; > 0 turns left). The last frame
        repeats the previous frame's velocities.
    """
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3) or joints.shape[0] < 2:
        raise ValueError(f"joints must have shape (T >= 2, {NUM_JOINTS}, 3), got {joints.shape}")
    if not np.isfinite(joints).all():
        raise ValueError("joints must be finite")
    theta = heading_from_joints(joints)  # (T,)
    local = joints.copy()
    local[..., [0, 2]] -= joints[:, :1, [0, 2]]
    local[..., 1] -= floor_height(joints)
    local = rotate_y(local, -theta[:, None])  # (T, 22, 3): every frame faces +Z
    step = to_heading_frame(np.diff(joints[:, 0, [0, 2]], axis=0), theta[:-1]) * FPS  # (T-1, 2)
    turn = np.angle(np.exp(1j * np.diff(theta)))[:, None] * FPS  # (T-1, 1), wrapped to (-π, π]
    motion = np.concatenate([step, turn], axis=1)
    motion = np.concatenate([motion, motion[-1:]], axis=0)  # (T, 3)
    return np.concatenate([local.reshape(len(joints), -1), motion], axis=1).astype(np.float32)


def clip_windows(features: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Cut (T, F) into windows: ((W, window, F) zero-padded, (W, window) bool mask).

    Windows start every half window and the last one ends at the clip's end.
    """
    t = len(features)
    if t <= window:
        x = np.zeros((1, window, features.shape[1]), np.float32)
        x[0, :t] = features
        mask = np.zeros((1, window), bool)
        mask[0, :t] = True
        return x, mask
    starts = sorted(set(range(0, t - window + 1, max(1, window // 2))) | {t - window})
    x = np.stack([features[s : s + window] for s in starts])
    return x, np.ones(x.shape[:2], bool)


# --------------------------------------------------------------------------------------------
# The network.
# --------------------------------------------------------------------------------------------


class _Block(nn.Module):
    def __init__(self, cfg: ClassifierConfig, dilation: int) -> None:
        super().__init__()
        pad = dilation * (cfg.kernel // 2)
        self.conv = nn.Conv1d(cfg.width, cfg.width, cfg.kernel, padding=pad, dilation=dilation)
        self.norm = nn.GroupNorm(1, cfg.width)
        self.drop = nn.Dropout(cfg.dropout)

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:  # (B, C, T), (B, 1, T)
        return (x + self.drop(F.gelu(self.norm(self.conv(x))))) * mask


class MotionClassifier(nn.Module):
    """Pose features (B, T, 69) -> (action logits (B, A), style logits (B, S))."""

    def __init__(self, config: ClassifierConfig) -> None:
        super().__init__()
        self.config = config
        # Feature normalisation, set from the training data by the trainer (saved with the weights).
        self.register_buffer("feature_mean", torch.zeros(FEATURE_DIM))
        self.register_buffer("feature_std", torch.ones(FEATURE_DIM))
        self.inp = nn.Linear(FEATURE_DIM, config.width)
        self.blocks = nn.ModuleList(_Block(config, 2**i) for i in range(config.layers))
        self.drop = nn.Dropout(config.dropout)
        self.action_head = nn.Linear(2 * config.width, len(config.actions))
        self.style_head = nn.Linear(2 * config.width, len(config.styles))

    def pool(self, features: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """features (B, T, 69), mask (B, T) bool (True = a real frame) -> (B, 2 * width): the
        masked mean and max over time of the last block (what both heads read)."""
        x = (features - self.feature_mean) / self.feature_std
        m = mask.to(x.dtype).unsqueeze(1)  # (B, 1, T)
        x = self.inp(x).transpose(1, 2) * m  # (B, C, T)
        for block in self.blocks:
            x = block(x, m)
        count = m.sum(-1).clamp_min(1.0)  # (B, 1)
        mean = x.sum(-1) / count  # (B, C)
        peak = x.masked_fill(m == 0, float("-inf")).amax(-1)  # (B, C)
        return torch.cat([mean, peak], dim=-1)  # (B, 2C)

    def forward(self, features: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """features (B, T, 69), mask (B, T) bool (True = a real frame) -> logits (B, A), (B, S)."""
        pooled = self.drop(self.pool(features, mask))  # (B, 2C)
        return self.action_head(pooled), self.style_head(pooled)


def _clip_tensors(model: MotionClassifier, joints: np.ndarray) -> tuple[torch.Tensor, torch.Tensor]:
    """A clip's windows as tensors on the model's device: (W, window, 69), (W, window)."""
    x, mask = clip_windows(pose_features(joints), model.config.window)
    device = model.feature_mean.device
    return torch.from_numpy(x).to(device), torch.from_numpy(mask).to(device)


@torch.no_grad()
def classify(model: MotionClassifier, clips: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Action and style probabilities of whole clips.

    Args:
        model: a trained classifier (its mode is left as found; eval mode is used inside).
        clips: N arrays of world joints (T_i, 22, 3), any lengths >= 2, any start and heading.
    Returns:
        (N, A) action and (N, S) style probabilities: the softmax of each clip's windows' mean
        log-probabilities.
    """
    was_training = model.training
    model.eval()
    actions, styles = [], []
    for joints in clips:
        a, s = model(*_clip_tensors(model, joints))
        actions.append(torch.softmax(F.log_softmax(a, -1).mean(0), -1).cpu().numpy())
        styles.append(torch.softmax(F.log_softmax(s, -1).mean(0), -1).cpu().numpy())
    model.train(was_training)
    a_dim, s_dim = len(model.config.actions), len(model.config.styles)
    return (
        np.stack(actions) if actions else np.zeros((0, a_dim), np.float32),
        np.stack(styles) if styles else np.zeros((0, s_dim), np.float32),
    )


@torch.no_grad()
def clip_embeddings(model: MotionClassifier, clips: Sequence[np.ndarray]) -> np.ndarray:
    """The classifier's features of whole clips (for Fréchet distance and diversity).

    Args:
        model: a trained classifier (its mode is left as found; eval mode is used inside).
        clips: N arrays of world joints (T_i, 22, 3), any lengths >= 2, any start and heading.
    Returns:
        (N, 2 * width) float32: per clip, the mean over its windows of :meth:`MotionClassifier.pool`.
    """
    was_training = model.training
    model.eval()
    out = [model.pool(*_clip_tensors(model, joints)).mean(0).cpu().numpy() for joints in clips]
    model.train(was_training)
    return np.stack(out) if out else np.zeros((0, 2 * model.config.width), np.float32)


def save_classifier(path: str | Path, model: MotionClassifier, half: bool = True, **extra: Any) -> Path:
    """Write the classifier to `path` (float16 weights unless `half` is False; `extra`: metrics,
    training settings, data record)."""
    return save_checkpoint(path, kind=CHECKPOINT_KIND, config=model.config, model=model, half=half, **extra)


def load_classifier(
    path: str | Path | None = None, device: str | torch.device = "cpu"
) -> tuple[MotionClassifier, dict[str, Any]]:
    """Rebuild a classifier from its checkpoint (default: the shipped ``weights/classifier.pt``).

    Returns (model in eval mode, the whole checkpoint dict: ``metrics``, ``data``, ...).
    """
    path = DEFAULT_CLASSIFIER if path is None else Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"no classifier at {path}: train one with "
            f"motion-env train classifier --data data/mocap --out {path}"
        )
    return load_checkpoint(path, CHECKPOINT_KIND, ClassifierConfig, MotionClassifier, device)
