"""An action/style classifier trained on real takes: the judge of caption steering (issue #11).

It answers "which action, in which style, does this clip show?" for the Bandai Namco actions and
styles the generator was trained on, so generated clips can be scored against the caption that
asked for them (``scripts/evaluate_captions.py``, ``motion-env eval captions``).

What it reads (:func:`pose_features`, per frame, numpy): every joint relative to the pelvis in
the body's own heading frame (x, z) and above the floor (y), the pelvis velocity in the heading
frame and the heading's turn rate. Nothing depends on where the clip starts or which way it faces
(a test checks it). Clips are cut into windows of ``config.window`` frames (4 s); a shorter clip
is padded and masked, a longer one is scored by the mean of its windows' log-probabilities.

The network (:class:`MotionClassifier`): a linear input layer, ``layers`` residual 1-D
convolutions, a masked mean + max over time and two heads, action and style. Style is learnt only
from takes that have one of ``config.styles`` (CMU takes have an action only). The feature
normalisation travels with the weights as buffers; the checkpoint is the project's format
(:mod:`motion_env.models.checkpoint`, kind ``"motion_classifier"``).

Train it with ``python scripts/train_classifier.py --data data/mocap`` (:func:`train_classifier`).
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.nn import functional as F

from motion_env.models.checkpoint import load_checkpoint, save_checkpoint
from motion_env.motion.kinematics import floor_height, heading_from_joints, rotate_y, to_heading_frame
from motion_env.motion.skeleton import FPS, NUM_JOINTS

__all__ = [
    "CHECKPOINT_KIND",
    "DEFAULT_CLASSIFIER",
    "FEATURE_DIM",
    "ClassifierConfig",
    "MotionClassifier",
    "classify",
    "labelled_clips",
    "load_classifier",
    "pose_features",
    "save_classifier",
    "train_classifier",
]

CHECKPOINT_KIND = "motion_classifier"
DEFAULT_CLASSIFIER = Path(__file__).resolve().parents[1] / "weights" / "classifier.pt"
FEATURE_DIM = NUM_JOINTS * 3 + 3  # local joints + (lateral, forward) pelvis velocity + turn rate


@dataclass
class ClassifierConfig:
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
    window: int = 80
    width: int = 96
    layers: int = 3
    kernel: int = 5
    dropout: float = 0.1

    def __post_init__(self) -> None:
        self.actions, self.styles = tuple(self.actions), tuple(self.styles)
        if len(self.actions) < 2 or len(set(self.actions)) != len(self.actions):
            raise ValueError(f"actions must be at least two distinct labels, got {self.actions}")
        if len(self.styles) < 2 or len(set(self.styles)) != len(self.styles):
            raise ValueError(f"styles must be at least two distinct labels, got {self.styles}")
        for name in ("window", "width", "layers", "kernel"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be a positive int, got {getattr(self, name)}")
        if self.kernel % 2 == 0:
            raise ValueError(f"kernel must be odd, got {self.kernel}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout}")


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


def _windows(features: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
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
        # Feature normalisation, set from the training data by train_classifier (saved with the weights).
        self.register_buffer("feature_mean", torch.zeros(FEATURE_DIM))
        self.register_buffer("feature_std", torch.ones(FEATURE_DIM))
        self.inp = nn.Linear(FEATURE_DIM, config.width)
        self.blocks = nn.ModuleList(_Block(config, 2**i) for i in range(config.layers))
        self.drop = nn.Dropout(config.dropout)
        self.action_head = nn.Linear(2 * config.width, len(config.actions))
        self.style_head = nn.Linear(2 * config.width, len(config.styles))

    def forward(self, features: torch.Tensor, mask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """features (B, T, 69), mask (B, T) bool (True = a real frame) -> logits (B, A), (B, S)."""
        x = (features - self.feature_mean) / self.feature_std
        m = mask.to(x.dtype).unsqueeze(1)  # (B, 1, T)
        x = self.inp(x).transpose(1, 2) * m  # (B, C, T)
        for block in self.blocks:
            x = block(x, m)
        count = m.sum(-1).clamp_min(1.0)  # (B, 1)
        mean = x.sum(-1) / count  # (B, C)
        peak = x.masked_fill(m == 0, float("-inf")).amax(-1)  # (B, C)
        pooled = self.drop(torch.cat([mean, peak], dim=-1))  # (B, 2C)
        return self.action_head(pooled), self.style_head(pooled)


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
        x, mask = _windows(pose_features(joints), model.config.window)
        a, s = model(torch.from_numpy(x), torch.from_numpy(mask))
        actions.append(torch.softmax(F.log_softmax(a, -1).mean(0), -1).numpy())
        styles.append(torch.softmax(F.log_softmax(s, -1).mean(0), -1).numpy())
    model.train(was_training)
    a_dim, s_dim = len(model.config.actions), len(model.config.styles)
    return (
        np.stack(actions) if actions else np.zeros((0, a_dim), np.float32),
        np.stack(styles) if styles else np.zeros((0, s_dim), np.float32),
    )


def save_classifier(path: str | Path, model: MotionClassifier, **extra: Any) -> Path:
    """Write the classifier (float16 weights; `extra`: metrics, data record) to `path`."""
    return save_checkpoint(path, kind=CHECKPOINT_KIND, config=model.config, model=model, half=True, **extra)


def load_classifier(
    path: str | Path | None = None, device: str | torch.device = "cpu"
) -> tuple[MotionClassifier, dict[str, Any]]:
    """Rebuild a classifier from its checkpoint (default: the shipped ``weights/classifier.pt``).

    Returns (model in eval mode, the whole checkpoint dict: ``metrics``, ``data``, ...).
    """
    path = DEFAULT_CLASSIFIER if path is None else Path(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"no classifier at {path}: train one with python scripts/train_classifier.py --data data/mocap"
        )
    return load_checkpoint(path, CHECKPOINT_KIND, ClassifierConfig, MotionClassifier, device)


# --------------------------------------------------------------------------------------------
# Data and training.
# --------------------------------------------------------------------------------------------


@dataclass
class LabelledClip:
    """One real clip with its labels (style None when the take has none of the known styles)."""

    name: str
    joints: np.ndarray  # (T, 22, 3)
    action: str
    style: str | None


def labelled_clips(data_dir: str | Path, split: str) -> list[LabelledClip]:
    """The whole clips (mirrors included) of one split of a built dataset, with their labels.

    Labels come from ``index.csv`` (a mirrored clip's label is already the mirrored one:
    ``Mdataset-2_wave-left-hand_...`` is a ``wave-right-hand``). CMU takes get no style.
    """
    from motion_env.data.dataset import read_split
    from motion_env.evaluation.routes import read_index

    data_dir = Path(data_dir)
    index = read_index(data_dir)
    if not index:
        raise FileNotFoundError(f"no index.csv in {data_dir} (build it with motion-env data build)")
    out = []
    for clip in read_split(data_dir, split):
        row = index.get(clip.name)
        if row is None or clip.num_frames < 2:
            continue
        style = row["style"] if row["source"] == "bandai" and row["style"] else None
        out.append(LabelledClip(clip.name, clip.joints, row["label"], style))
    return out


@dataclass
class TrainSettings:
    """How :func:`train_classifier` trains (not part of the model's config)."""

    epochs: int = 15
    batch_size: int = 64
    lr: float = 2e-3
    weight_decay: float = 1e-2
    min_takes: int = 100  # an action/style is a class when the train split has this many clips of it
    seed: int = 0


def _crop(features: np.ndarray, window: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    t = len(features)
    x = np.zeros((window, features.shape[1]), np.float32)
    mask = np.zeros(window, bool)
    if t <= window:
        x[:t], mask[:t] = features, True
    else:
        s = int(rng.integers(0, t - window + 1))
        x[:], mask[:] = features[s : s + window], True
    return x, mask


def _accuracy(model: MotionClassifier, clips: list[LabelledClip]) -> dict[str, float]:
    a_index = {a: i for i, a in enumerate(model.config.actions)}
    s_index = {s: i for i, s in enumerate(model.config.styles)}
    keep = [c for c in clips if c.action in a_index]
    pa, ps = classify(model, [c.joints for c in keep])
    act = np.array([a_index[c.action] for c in keep])
    sty = np.array([s_index.get(c.style, -1) if c.style else -1 for c in keep])
    has = sty >= 0
    out = {"clips": len(keep), "action": float((pa.argmax(1) == act).mean()) if keep else float("nan")}
    out["styled_clips"] = int(has.sum())
    out["style"] = float((ps.argmax(1)[has] == sty[has]).mean()) if has.any() else float("nan")
    if has.any():
        joint = pa[has][:, :, None] * ps[has][:, None, :]  # (N, A, S)
        flat = joint.reshape(len(joint), -1)
        top3 = np.argsort(-flat, axis=1)[:, :3]
        right = act[has] * len(s_index) + sty[has]
        out["pair_top3"] = float((top3 == right[:, None]).any(1).mean())
    return out


def train_classifier(
    data_dir: str | Path,
    config: ClassifierConfig | None = None,
    settings: TrainSettings | None = None,
    log: Any = print,
) -> tuple[MotionClassifier, dict[str, Any]]:
    """Train on the train split's real clips, keep the epoch best on val, measure on test.

    Args:
        data_dir: a dataset built by ``motion-env data build`` (``index.csv`` and the splits).
        config: the architecture; its ``actions``/``styles`` are ignored and set from the data
            (labels with at least ``settings.min_takes`` train clips; sorted).
        settings: epochs, batch size, learning rate, seed.
        log: where progress lines go.
    Returns:
        (the model in eval mode, metrics ``{"val": ..., "test": ..., "train_clips", "seconds"}``).
    """
    settings = settings or TrainSettings()
    torch.manual_seed(settings.seed)
    rng = np.random.default_rng(settings.seed)
    t0 = time.perf_counter()
    train = [c for c in labelled_clips(data_dir, "train") if c.joints.shape[0] >= 2]
    val, test = labelled_clips(data_dir, "val"), labelled_clips(data_dir, "test")
    bandai_actions = Counter(c.action for c in train if c.style is not None)
    styles = Counter(c.style for c in train if c.style is not None)
    actions = tuple(sorted(a for a, n in bandai_actions.items() if n >= settings.min_takes))
    styles_kept = tuple(sorted(s for s, n in styles.items() if n >= settings.min_takes))
    if config is None:
        cfg = ClassifierConfig(actions=actions, styles=styles_kept)
    else:
        cfg = replace(config, actions=actions, styles=styles_kept)
    train = [c for c in train if c.action in actions]
    a_index = {a: i for i, a in enumerate(actions)}
    s_index = {s: i for i, s in enumerate(styles_kept)}
    feats = [pose_features(c.joints) for c in train]
    a_lab = np.array([a_index[c.action] for c in train])
    s_lab = np.array([s_index.get(c.style, -1) if c.style else -1 for c in train])
    log(
        f"train {len(train)} clips, {len(actions)} actions {actions}, {len(styles_kept)} styles {styles_kept}"
    )

    model = MotionClassifier(cfg)
    stacked = np.concatenate(feats)
    model.feature_mean.copy_(torch.from_numpy(stacked.mean(0)))
    model.feature_std.copy_(torch.from_numpy(np.maximum(stacked.std(0), 1e-3)))
    opt = torch.optim.AdamW(model.parameters(), lr=settings.lr, weight_decay=settings.weight_decay)
    steps = settings.epochs * int(np.ceil(len(train) / settings.batch_size))
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=settings.lr, total_steps=steps)
    best, best_state, best_epoch = -1.0, None, -1
    for epoch in range(settings.epochs):
        model.train()
        order = rng.permutation(len(train))
        total = 0.0
        for i in range(0, len(order), settings.batch_size):
            idx = order[i : i + settings.batch_size]
            crops = [_crop(feats[j], cfg.window, rng) for j in idx]
            x = torch.from_numpy(np.stack([c[0] for c in crops]))  # (B, window, 69)
            mask = torch.from_numpy(np.stack([c[1] for c in crops]))  # (B, window)
            a_logits, s_logits = model(x, mask)
            loss = F.cross_entropy(a_logits, torch.from_numpy(a_lab[idx]))
            s_target = torch.from_numpy(s_lab[idx])
            if (s_target >= 0).any():
                loss = loss + F.cross_entropy(s_logits, s_target, ignore_index=-1)
            opt.zero_grad()
            loss.backward()
            opt.step()
            sched.step()
            total += loss.item() * len(idx)
        acc = _accuracy(model, val)
        score = acc["action"] + acc["style"]
        log(
            f"epoch {epoch + 1}/{settings.epochs} loss {total / len(train):.3f} "
            f"val action {acc['action']:.3f} style {acc['style']:.3f} ({time.perf_counter() - t0:.0f} s)"
        )
        if score >= best:
            best, best_epoch = score, epoch + 1
            best_state = {k: v.clone() for k, v in model.state_dict().items()}
    assert best_state is not None
    model.load_state_dict(best_state)
    model.eval()
    metrics = {
        "best_epoch": best_epoch,
        "train_clips": len(train),
        "val": _accuracy(model, val),
        "test": _accuracy(model, test),
        "seconds": round(time.perf_counter() - t0, 1),
    }
    return model, metrics
