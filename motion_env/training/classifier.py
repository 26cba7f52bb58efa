"""Training of the action/style classifier (:mod:`motion_env.models.classifier`) on real takes.

``motion-env train classifier --data data/mocap --out classifier.pt``: the classes are the Bandai
Namco actions and styles with at least ``min_takes`` clips in the train split (mirrors
included; the labels come from the dataset's ``index.csv``). Each step takes one random window
of each clip of a batch; an epoch is one pass over the train clips in a random order, with
AdamW and a one-cycle learning rate over all the epochs. After each validated epoch the model
is scored on the val split (action + style accuracy) and the best epoch is kept; the test split
is measured at the end (``metrics``).

The epoch is this trainer's unit: ``log_every``, ``save_every`` and ``eval_every`` count epochs.
The checkpoint (the project's format, kind ``"motion_classifier"``) always holds the best model
so far under ``"model"``, so :func:`~motion_env.models.classifier.load_classifier` reads it at any
time; until the last epoch it also holds what resuming needs (``"resume"``: the current weights,
optimizer, schedule and random states), so a resumed run ends with the weights an uninterrupted
one would. The finished file keeps float32 weights; ``export_checkpoint`` halves them for
shipping (``motion_env/weights/classifier.pt``).
"""

from __future__ import annotations

import copy
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import torch
from torch.nn import functional as F
from tqdm.auto import tqdm

from motion_env.data.dataset import read_index, read_split
from motion_env.models.classifier import (
    CHECKPOINT_KIND,
    ClassifierConfig,
    MotionClassifier,
    classify,
    pose_features,
    save_classifier,
)
from motion_env.motion.validation import NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt
from motion_env.training import loop
from motion_env.training.config import TrainConfig

__all__ = ["ClassifierTrainConfig", "LabelledClip", "labelled_clips", "train_classifier"]

# Settings a resumed run must share with the run it continues (they shape the batches and schedule).
_RESUME_KEYS = ("epochs", "batch_size", "lr", "weight_decay", "min_takes", "seed")


@dataclass(kw_only=True)
class ClassifierTrainConfig(TrainConfig):
    """How to train the classifier (stored in its checkpoint under ``"settings"``)."""

    epochs: PositiveInt = 15  # passes over the train clips (the best validated epoch is kept)
    batch_size: PositiveInt = 64  # clips per step (one random window of each)
    lr: PositiveFloat = 2e-3  # peak AdamW learning rate (one-cycle schedule over all the epochs)
    weight_decay: NonNegativeFloat = 1e-2  # AdamW weight decay
    min_takes: PositiveInt = 100  # an action or style is a class when the train split has this many clips
    window: PositiveInt = 80  # frames per window (4 s at 20 fps)
    width: PositiveInt = 96  # channels of the convolutions
    layers: PositiveInt = 3  # residual convolution blocks
    kernel: PositiveInt = 5  # temporal kernel size (odd)
    dropout: Annotated[float, "[0, 1)"] = 0.1  # dropout in the blocks and before the heads
    log_every: PositiveInt = 1  # epochs between loss lines
    save_every: PositiveInt = 1  # epochs between checkpoints (one is also written at the end)
    eval_every: NonNegativeInt = 1  # epochs between validations (0: only at the end); the best one is kept

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.kernel % 2 == 0:
            raise ValueError(f"{type(self).__name__}.kernel must be odd, got {self.kernel}")


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
    """Action / style accuracy on labelled clips, and the right (action, style) among the top 3."""
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


@dataclass
class _Data:
    """The train clips as features and label indices, and the val and test clips."""

    config: ClassifierConfig
    features: list[np.ndarray]  # per train clip, (T_i, 69)
    actions: np.ndarray  # (N,) action index per train clip
    styles: np.ndarray  # (N,) style index per train clip, -1: none
    val: list[LabelledClip]
    test: list[LabelledClip]


def _training_data(data_dir: str | Path, config: ClassifierTrainConfig) -> _Data:
    """The classes (labels with at least ``min_takes`` train clips, sorted) and the splits."""
    train = [c for c in labelled_clips(data_dir, "train") if c.joints.shape[0] >= 2]
    val, test = labelled_clips(data_dir, "val"), labelled_clips(data_dir, "test")
    bandai_actions = Counter(c.action for c in train if c.style is not None)
    styles = Counter(c.style for c in train if c.style is not None)
    actions = tuple(sorted(a for a, n in bandai_actions.items() if n >= config.min_takes))
    kept = tuple(sorted(s for s, n in styles.items() if n >= config.min_takes))
    if len(actions) < 2 or len(kept) < 2:
        raise ValueError(
            f"{data_dir}: fewer than two actions ({actions}) or styles ({kept}) with at least "
            f"min_takes={config.min_takes} train clips"
        )
    cfg = ClassifierConfig(
        actions=actions, styles=kept, window=config.window, width=config.width, layers=config.layers,
        kernel=config.kernel, dropout=config.dropout,
    )  # fmt: skip
    train = [c for c in train if c.action in actions]
    s_index = {s: i for i, s in enumerate(kept)}
    tqdm.write(f"classifier: train {len(train)} clips, actions {actions}, styles {kept}")
    return _Data(
        cfg,
        [pose_features(c.joints) for c in train],
        np.array([actions.index(c.action) for c in train]),
        np.array([s_index.get(c.style, -1) if c.style else -1 for c in train]),
        val,
        test,
    )


def _check_resumable(ckpt: dict[str, Any], config: ClassifierTrainConfig, out_path: Path) -> None:
    """A run continues only the run with the same schedule and batches."""
    stored = ckpt.get("settings", {})
    changed = [k for k in _RESUME_KEYS if stored.get(k) != getattr(config, k)]
    if changed:
        raise ValueError(
            f"{out_path}: cannot resume, it was trained with other {', '.join(changed)} "
            f"({', '.join(f'{k}={stored.get(k)!r}' for k in changed)}); pass --no-resume or another --out"
        )


class _Run:
    """The model, optimizer, schedule, random states and the best epoch so far of one training run."""

    def __init__(self, data: _Data, config: ClassifierTrainConfig, steps_per_epoch: int) -> None:
        torch.manual_seed(config.seed)
        self.rng = np.random.default_rng(config.seed)
        self.model = MotionClassifier(data.config)
        stacked = np.concatenate(data.features)
        self.model.feature_mean.copy_(torch.from_numpy(stacked.mean(0)))
        self.model.feature_std.copy_(torch.from_numpy(np.maximum(stacked.std(0), 1e-3)))
        self.model.to(config.device)
        self.opt = torch.optim.AdamW(self.model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
        self.sched = torch.optim.lr_scheduler.OneCycleLR(
            self.opt, max_lr=config.lr, total_steps=config.epochs * steps_per_epoch
        )
        self.epoch, self.best_epoch, self.best_score = 0, 0, -1.0
        self.best: MotionClassifier | None = None

    def restore(self, ckpt: dict[str, Any]) -> None:
        """Continue from a checkpoint of this trainer (finished or not)."""
        self.epoch, self.best_epoch = int(ckpt["epoch"]), int(ckpt["best_epoch"])
        self.best_score = float(ckpt["best_score"])
        state = ckpt.get("resume")
        self.best = copy.deepcopy(self.model)
        self.best.load_state_dict(ckpt["model"])
        if state is None:  # finished: nothing left to train
            self.model = self.best
            return
        self.model.load_state_dict(state["model"])
        self.opt.load_state_dict(state["optimizer"])
        self.sched.load_state_dict(state["scheduler"])
        self.rng.bit_generator.state = state["rng"]
        torch.set_rng_state(state["torch_rng"])

    def save(self, path: Path, config: ClassifierTrainConfig, metrics: dict[str, Any], final: bool) -> None:
        """The best model so far (and, unless `final`, what resuming needs) to `path`."""
        extra: dict[str, Any] = {}
        if not final:
            extra["resume"] = {
                "model": {k: v.detach().cpu() for k, v in self.model.state_dict().items()},
                "optimizer": self.opt.state_dict(),
                "scheduler": self.sched.state_dict(),
                "rng": self.rng.bit_generator.state,
                "torch_rng": torch.get_rng_state(),
            }
        save_classifier(
            path, self.best if self.best is not None else self.model, half=False, epoch=self.epoch,
            best_epoch=self.best_epoch, best_score=self.best_score, settings=config.to_dict(),
            metrics=metrics, **extra,
        )  # fmt: skip


def _train_epoch(run: _Run, data: _Data, config: ClassifierTrainConfig, bar: Any) -> float:
    """One pass over the train clips in a random order; the mean loss per clip."""
    model, window, device = run.model, data.config.window, config.device
    model.train()
    order = run.rng.permutation(len(data.features))
    total = 0.0
    for i in range(0, len(order), config.batch_size):
        idx = order[i : i + config.batch_size]
        crops = [_crop(data.features[j], window, run.rng) for j in idx]
        x = torch.from_numpy(np.stack([c[0] for c in crops])).to(device)  # (B, window, 69)
        mask = torch.from_numpy(np.stack([c[1] for c in crops])).to(device)  # (B, window)
        a_logits, s_logits = model(x, mask)
        loss = F.cross_entropy(a_logits, torch.from_numpy(data.actions[idx]).to(device))
        s_target = torch.from_numpy(data.styles[idx]).to(device)
        if (s_target >= 0).any():
            loss = loss + F.cross_entropy(s_logits, s_target, ignore_index=-1)
        run.opt.zero_grad()
        loss.backward()
        run.opt.step()
        run.sched.step()
        total += loss.item() * len(idx)
        bar.update(1)
        bar.set_postfix({"loss": f"{loss.item():.3f}"}, refresh=False)
    return total / len(order)


def train_classifier(
    data_dir: str | Path, out_path: str | Path, config: ClassifierTrainConfig | None = None
) -> dict[str, Any]:
    """Train the classifier on the train split's real clips, keep the best validated epoch,
    measure it on the test split, and checkpoint it (resumes from `out_path` when it exists).

    Args:
        data_dir: a dataset built by ``motion-env data build`` (``index.csv`` and the splits).
        out_path: checkpoint file (written every ``save_every`` epochs and at the end).
        config: training settings and architecture (default ClassifierTrainConfig()).
    Returns:
        metrics: ``best_epoch``, ``epoch`` (epochs done), ``train_clips``, ``val`` and ``test``
        (``action``, ``style``, ``pair_top3`` accuracy, clip counts), ``seconds``.
    """
    config = config or ClassifierTrainConfig()
    out_path = Path(out_path)
    t0 = time.perf_counter()
    data = _training_data(data_dir, config)
    steps_per_epoch = int(np.ceil(len(data.features) / config.batch_size))
    run = _Run(data, config, steps_per_epoch)
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, data.config)
    if ckpt is not None:
        _check_resumable(ckpt, config, out_path)
        run.restore(ckpt)
    metrics: dict[str, Any] = dict(ckpt.get("metrics", {})) if ckpt is not None else {}
    bar = tqdm(
        total=config.epochs * steps_per_epoch, initial=run.epoch * steps_per_epoch, desc="classifier",
        mininterval=5.0, disable=not config.progress,
    )  # fmt: skip
    while run.epoch < config.epochs:
        loss = _train_epoch(run, data, config, bar)
        run.epoch += 1
        line = f"classifier epoch {run.epoch}/{config.epochs} loss {loss:.3f}"
        if (config.eval_every and run.epoch % config.eval_every == 0) or run.epoch == config.epochs:
            acc = _accuracy(run.model, data.val)
            score = float(np.nansum([acc["action"], acc["style"]]))
            line += f" val action {acc['action']:.3f} style {acc['style']:.3f}"
            if score >= run.best_score:
                run.best_score, run.best_epoch, run.best = score, run.epoch, copy.deepcopy(run.model)
        timed_out = time.perf_counter() - t0 > config.max_minutes * 60
        if run.epoch % config.log_every == 0:
            bar.write(f"{line} ({time.perf_counter() - t0:.0f} s)")
        if run.epoch < config.epochs and (run.epoch % config.save_every == 0 or timed_out):
            run.save(out_path, config, {"train_loss": loss}, final=False)
        if timed_out and run.epoch < config.epochs:
            bar.write(f"classifier: stopping after epoch {run.epoch} ({config.max_minutes} minutes)")
            break
    bar.close()
    if run.epoch < config.epochs:  # stopped by max_minutes: resumable from the checkpoint
        return {"epoch": run.epoch, "best_epoch": run.best_epoch, "train_loss": loss}
    if "test" not in metrics:
        best = (run.best if run.best is not None else run.model).eval()
        metrics = {
            "best_epoch": run.best_epoch, "epoch": run.epoch, "train_clips": len(data.features),
            "val": _accuracy(best, data.val), "test": _accuracy(best, data.test),
            "seconds": round(time.perf_counter() - t0, 1),
        }  # fmt: skip
        run.save(out_path, config, metrics, final=True)
    return metrics
