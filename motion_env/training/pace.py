"""Fitting the pace regressor (:mod:`motion_env.models.pace`): caption embedding -> the take's speed.

Each train-split clip of at least 24 frames gives its mean root speed (path length over duration;
the takes start and end in motion, so that is the pace of the motion, 0 for gestures) and up to
``captions_per_clip`` of its captions. Each caption is embedded as the path controller reads it:
by the models' own text encoder as it is (``--caption-reader none``) and through the weights
folder's default caption adapter (``caption_adapter.pt``, when it has one), so that the one
regressor serves either reader. A ridge regression fits the speed on those embeddings (closed
form, a few seconds once the captions are encoded), or, with ``hidden`` > 0, AdamW fits a
regressor with a hidden layer (seconds too); the val split says how far off it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from motion_env.data.dataset import DatasetClip, read_index, read_split
from motion_env.models.checkpoint import read_checkpoint, save_checkpoint
from motion_env.models.pace import PaceConfig, PaceRegressor
from motion_env.motion.skeleton import FPS
from motion_env.motion.validation import NonNegativeInt
from motion_env.training.config import TrainConfig

__all__ = ["PaceTrainConfig", "clip_speed", "fit_hidden", "fit_ridge", "train_pace"]

CHECKPOINT_KIND = "pace"
MIN_FRAMES = 24  # shorter clips are skipped (as the controller's training does)


@dataclass(kw_only=True)
class PaceTrainConfig(TrainConfig):
    """How to fit the pace regressor (stored in its checkpoint under ``"settings"``)."""

    weights: str = "shipped"  # generator weights folder whose controller space and caption adapter are read
    captions_per_clip: int = 3  # captions of each train clip that are fitted (each clip has about 12)
    alpha: float = 1.0  # ridge penalty of the linear map (chosen on the val split: 0.1-100 tried)
    hidden: NonNegativeInt = 0  # width of a hidden layer (0: a linear map, fitted in closed form; else AdamW)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.captions_per_clip < 1:
            raise ValueError(f"PaceTrainConfig.captions_per_clip must be >= 1, got {self.captions_per_clip}")
        if not self.alpha >= 0:
            raise ValueError(f"PaceTrainConfig.alpha must be >= 0, got {self.alpha}")


def clip_speed(joints: np.ndarray) -> float:
    """A clip's mean root speed in m/s: the pelvis's horizontal path length over its duration."""
    xz = np.asarray(joints, np.float64)[:, 0, [0, 2]]
    return float(np.linalg.norm(np.diff(xz, axis=0), axis=1).sum() / max(len(xz) - 1, 1) * FPS)


def fit_ridge(x: np.ndarray, y: np.ndarray, alpha: float) -> tuple[np.ndarray, float]:
    """Ridge regression of `y` (N,) on `x` (N, D), intercept unpenalised: (weights (D,), bias)."""
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    mu = x.mean(0)
    xc = x - mu
    w = np.linalg.solve(xc.T @ xc + alpha * np.eye(x.shape[1]), xc.T @ (y - y.mean()))
    return w, float(y.mean() - mu @ w)


def fit_hidden(x: np.ndarray, y: np.ndarray, hidden: int, seed: int, steps: int = 1500) -> PaceRegressor:
    """A pace regressor with a hidden layer of width `hidden`, fitted to `y` (N,) on `x` (N, D) by
    AdamW on the squared error (batches of 512; a few seconds on one CPU thread)."""
    torch.manual_seed(seed)
    model = PaceRegressor(PaceConfig(text_dim=int(x.shape[1]), hidden=hidden))
    # Start the output layer from the mean speed and small random weights, not from zero (a zero
    # output layer would give the hidden layer no gradient).
    torch.nn.init.normal_(model.linear.weight, std=0.01)
    torch.nn.init.constant_(model.linear.bias, float(np.mean(y)))
    xt, yt = torch.as_tensor(x, dtype=torch.float32), torch.as_tensor(y, dtype=torch.float32)
    optimizer = torch.optim.AdamW(model.parameters(), lr=3e-3, weight_decay=1e-3)
    gen = torch.Generator().manual_seed(seed)
    for _ in range(steps):
        idx = torch.randint(0, len(xt), (min(512, len(xt)),), generator=gen)
        h = torch.nn.functional.gelu(model.hidden(xt[idx]))
        loss = (model.linear(h)[:, 0] - yt[idx]).pow(2).mean()  # unclipped, so every row has a gradient
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    return model.eval()


def _captions_and_speeds(
    clips: list[DatasetClip], per_clip: int, rng: np.random.Generator
) -> tuple[list[str], np.ndarray]:
    texts, speeds = [], []
    for c in clips:
        if len(c.joints) < MIN_FRAMES or not c.captions:
            continue
        speed = clip_speed(c.joints)
        for t in rng.choice(list(c.captions), min(per_clip, len(c.captions)), replace=False):
            texts.append(str(t))
            speeds.append(speed)
    return texts, np.asarray(speeds, np.float64)


def _readers(folder: Path, device: str) -> tuple[Any, list[Any], dict[str, Any]]:
    """The models' text encoder, the adapters whose outputs are fitted (None: the encoder as it
    is), and the controller's text encoder record."""
    from motion_env.generation.caption_readers import load_caption_reader
    from motion_env.text.encoders import load_text_encoder

    record = read_checkpoint(folder / "controller.pt", "controller").get("text_encoder") or {}
    name = record.get("name", "minilm")
    adapter, _ = load_caption_reader(folder, None, name, None, device)
    if adapter is not None and adapter.config.encoder != name:
        adapter = None  # an adapter of another encoder would need that encoder too
    return load_text_encoder(name, None, device), [None] + ([adapter] if adapter is not None else []), record


def _embed(encoder: Any, adapters: list[Any], texts: list[str]) -> list[np.ndarray]:
    """Per reader (None: the encoder alone), (N, D) float32 embeddings as the controller reads them."""
    raw = np.concatenate(
        [np.asarray(encoder.encode(texts[i : i + 512]), np.float32) for i in range(0, len(texts), 512)]
    )
    out = []
    for adapter in adapters:
        if adapter is None:
            out.append(raw)
        else:
            with torch.no_grad():
                out.append(adapter(torch.from_numpy(raw).to(adapter.prototypes.device)).cpu().numpy())
    return out


def train_pace(
    data_dir: str | Path,
    out_path: str | Path,
    config: PaceTrainConfig | None = None,
    text_encoder: Any = None,
) -> dict[str, float]:
    """Fit the pace regressor on a built dataset's train split and write its checkpoint.

    Args:
        data_dir: dataset root (``train.txt``, ``val.txt``, ``new_joints/``, ``texts/``).
        out_path: the checkpoint (``pace.pt`` in a weights folder is what the generator loads).
        config: the settings (default PaceTrainConfig()).
        text_encoder: an encoder whose embeddings the regressor reads as they are, instead of the
            weights folder's (its controller's encoder and caption adapter); for tests.

    Returns:
        Val metrics: mean absolute error (m/s) per reader (``mae_none``, ``mae_adapter``) and the
        mean predicted and real pace of the val runs and walks (``run_pred``, ``run_real``, ...).
    """
    from motion_env.generation.generator import DEFAULT_WEIGHTS

    config = config or PaceTrainConfig()
    folder = DEFAULT_WEIGHTS if config.weights == "shipped" else Path(config.weights)
    if not Path(data_dir).is_dir():
        raise FileNotFoundError(f"no dataset directory at {data_dir}")
    if text_encoder is None:
        encoder, adapters, record = _readers(folder, config.device)
    else:
        encoder, adapters = text_encoder, [None]
        record = {"name": str(text_encoder.name), "dim": int(text_encoder.dim)}
    rng = np.random.default_rng(config.seed)
    texts, speeds = _captions_and_speeds(read_split(Path(data_dir), "train"), config.captions_per_clip, rng)
    tqdm.write(f"pace: {len(texts)} train captions, {len(adapters)} reader(s)")
    train_x = _embed(encoder, adapters, texts)
    x, y = np.concatenate(train_x), np.tile(speeds, len(train_x))
    if config.hidden:
        model = fit_hidden(x, y, config.hidden, config.seed)
    else:
        weight, bias = fit_ridge(x, y, config.alpha)
        model = PaceRegressor(PaceConfig(text_dim=int(train_x[0].shape[1])))
        model.set_weights(weight, bias)

    val_clips = read_split(Path(data_dir), "val")
    index = read_index(Path(data_dir))
    labels = []
    for c in val_clips:
        if len(c.joints) >= MIN_FRAMES and c.captions:
            labels += [(index.get(c.name) or {}).get("label", "")] * min(
                config.captions_per_clip, len(c.captions)
            )
    val_texts, val_speeds = _captions_and_speeds(
        val_clips, config.captions_per_clip, np.random.default_rng(1)
    )
    metrics: dict[str, float] = {"train_captions": float(len(texts)), "val_captions": float(len(val_texts))}
    labels_arr = np.asarray(labels)
    for adapter, x in zip(adapters, _embed(encoder, adapters, val_texts), strict=True):
        pred = model.pace(x)
        reader = "none" if adapter is None else "adapter"
        metrics[f"mae_{reader}"] = float(np.abs(pred - val_speeds).mean())
        for label in ("run", "walk"):
            rows = labels_arr == label
            if rows.any():
                metrics[f"{label}_pred_{reader}"] = float(pred[rows].mean())
                metrics[f"{label}_real"] = float(val_speeds[rows].mean())
    save_checkpoint(
        out_path, kind=CHECKPOINT_KIND, config=model.config, model=model, text_encoder=record,
        step=0, settings=config.to_dict(), metrics=metrics,
    )  # fmt: skip
    tqdm.write("pace: val " + " ".join(f"{k}={v:.3f}" for k, v in metrics.items()))
    return metrics
