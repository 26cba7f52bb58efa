"""The loop the trainers share: learning-rate schedule, resuming, and the bookkeeping of each step.

A trainer supplies one optimisation step as a function of the (0-based) step index;
:func:`run_loop` sets the learning rate (:func:`lr_at`), runs the steps from where a resumed run
stopped to the total, shows a tqdm progress bar, logs the loss terms, validates on the val split
every ``eval_every`` steps, writes a checkpoint every ``save_every`` steps, at the last step and
when the time limit is hit, and stops at the time limit. :func:`resume_checkpoint`,
:func:`restore` and :func:`save_training_checkpoint` (:func:`checkpoint_writer`, the loop's
`save`) read and write the training checkpoints (the project's format,
:mod:`motion_env.models.checkpoint`, plus optimizer state, step, settings and metrics);
:func:`with_text_encoder` picks the text encoder of a run.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import torch
from tqdm.auto import tqdm

from motion_env.data.dataset import load_stats, read_split
from motion_env.models.checkpoint import read_checkpoint, save_checkpoint
from motion_env.models.normalizer import Normalizer
from motion_env.text.encoders import TextEncoder, load_text_encoder
from motion_env.training.config import TrainConfig


def lr_at(step: int, total: int, peak: float, warmup: int) -> float:
    """Learning rate at (0-based) `step` of `total`: linear warm-up, then cosine decay to 10 % of `peak`."""
    if step < warmup:
        return peak * (step + 1) / warmup
    progress = min(1.0, (step - warmup) / max(1, total - warmup))
    return peak * (0.1 + 0.9 * 0.5 * (1.0 + math.cos(math.pi * progress)))


# --- data the trainers share ---------------------------------------------------------------


def load_split(data_dir: Path, split: str) -> list[Any]:
    """The clips of a split of a HumanML3D-layout dataset; an empty split is an error."""
    clips = read_split(data_dir, split)
    if not clips:
        raise ValueError(f"{data_dir}: split {split!r} has no clips")
    return clips


def load_normalizer(data_dir: Path) -> Normalizer:
    """The dataset's feature statistics (``Mean.npy`` / ``Std.npy``)."""
    return Normalizer(*load_stats(data_dir))


def with_text_encoder(
    config: Any, text_encoder: TextEncoder | None, field: str = "encoder", weights: Any = None
) -> tuple[Any, TextEncoder]:
    """The settings and a text encoder of a run: `text_encoder` when one is given (its name then
    replaces ``config.<field>``, so that the checkpoint names the encoder actually used), else
    ``config.<field>`` loaded (from `weights`, for encoders that take them) on ``config.device``."""
    if text_encoder is None:
        return config, load_text_encoder(getattr(config, field), weights, config.device)
    return replace(config, **{field: text_encoder.name}), text_encoder


# --- checkpoints ---------------------------------------------------------------------------


def resume_checkpoint(path: Path, kind: str, resume: bool, model_config: Any = None) -> dict[str, Any] | None:
    """The checkpoint to continue from, or None for a fresh start.

    Args:
        path: the run's checkpoint (None is returned when it does not exist or `resume` is False).
        kind: the checkpoint kind ("vqvae", "gpt", "controller").
        resume: whether to continue at all.
        model_config: the model config the run asks for; a checkpoint trained with another one is
            an error (None: take the checkpoint's).
    """
    if not (resume and path.is_file()):
        return None
    ckpt = read_checkpoint(path, kind)
    if model_config is not None and ckpt["config"] != asdict(model_config):
        raise ValueError(
            f"{path}: cannot resume, it was trained with config {ckpt['config']}, "
            f"not {asdict(model_config)}; pass resume=False (--no-resume) or another out_path"
        )
    return ckpt


def restore(ckpt: dict[str, Any] | None, model: torch.nn.Module, optimizer: torch.optim.Optimizer) -> int:
    """Load the model and optimizer state of a training checkpoint; returns its step (0 for None)."""
    if ckpt is None:
        return 0
    model.load_state_dict(ckpt["model"])
    optimizer.load_state_dict(ckpt["optimizer"])
    return int(ckpt["step"])


def save_training_checkpoint(
    path: Path,
    *,
    kind: str,
    model: Any,
    optimizer: torch.optim.Optimizer,
    step: int,
    settings: TrainConfig,
    metrics: dict[str, float],
    **extra: Any,
) -> Path:
    """Write a resumable checkpoint: the model (with ``model.config``), optimizer state, step, the
    training settings as a plain dict, the metrics, and `extra` (normalisation, text encoder...)."""
    return save_checkpoint(
        path, kind=kind, config=model.config, model=model, optimizer=optimizer.state_dict(), step=step,
        settings=settings.to_dict(), metrics=metrics, **extra,
    )  # fmt: skip


def checkpoint_writer(
    path: Path,
    *,
    kind: str,
    model: Any,
    optimizer: torch.optim.Optimizer,
    settings: TrainConfig,
    **extra: Any,
) -> Callable[[int, dict[str, float]], None]:
    """The `save` of :func:`run_loop`: ``save(step, metrics)`` writes
    :func:`save_training_checkpoint` of `model` and `optimizer` at that step."""

    def save(step: int, metrics: dict[str, float]) -> None:
        save_training_checkpoint(
            path, kind=kind, model=model, optimizer=optimizer, step=step, settings=settings,
            metrics=metrics, **extra,
        )  # fmt: skip

    return save


# --- the loop ------------------------------------------------------------------------------


@dataclass
class LoopResult:
    """What :func:`run_loop` did.

    Attributes:
        step: steps done in all (those of a resumed run included).
        done: steps done by this call.
        last: the loss terms of the last step ({} when no step ran).
        seconds_per_step: wall time per step of this call.
    """

    step: int
    done: int
    last: dict[str, float]
    seconds_per_step: float


def _terms(values: dict[str, float]) -> str:
    return " ".join(f"{name} {value:.4f}" for name, value in values.items())


def run_loop(
    kind: str,
    config: Any,
    optimizer: torch.optim.Optimizer,
    train_step: Callable[[int], dict[str, float]],
    *,
    warmup: int,
    start: int = 0,
    save: Callable[[int, dict[str, float]], None] | None = None,
    evaluate: Callable[[], dict[str, float]] | None = None,
    postfix: dict[str, str] | None = None,
    smoothing: float = 0.0,
    on_step: Callable[[int, dict[str, float]], bool] | None = None,
    progress: bool = True,
) -> LoopResult:
    """Run `train_step` for steps ``start .. config.steps - 1`` with the shared bookkeeping.

    Args:
        kind: the model's name in the progress bar and the log.
        config: the trainer's settings: ``steps``, ``lr`` (the peak), ``log_every``,
            ``save_every``, ``eval_every``, ``max_minutes`` (inf: no limit), ``progress``.
        optimizer: its learning rate is set before each step (:func:`lr_at`).
        train_step: (0-based) step -> that step's loss terms (after the optimizer step).
        warmup: warm-up steps of the learning-rate schedule.
        start: the first step (a resumed run's step).
        save: ``save(steps_done, metrics)`` writes a checkpoint; metrics are the last step's loss
            terms and the latest validation (``val_``-prefixed). None: no checkpoints.
        evaluate: validation on the val split, run every ``config.eval_every`` steps and logged.
        postfix: loss terms shown on the progress bar, with their formats ({"loss": ".4f"}).
        smoothing: the logged terms are an exponential moving average with this weight on the
            past (0: the last step's values).
        on_step: ``on_step(steps_done, terms)`` after the bookkeeping; True stops the loop.
        progress: False hides the progress bar (so does ``config.progress``).
    """
    steps = config.steps
    t0 = time.perf_counter()
    done, last, shown, val = 0, {}, {}, {}
    bar = tqdm(
        total=steps, initial=start, desc=kind, mininterval=5.0, disable=not (progress and config.progress)
    )
    for step in range(start, steps):
        for group in optimizer.param_groups:
            group["lr"] = lr_at(step, steps, config.lr, warmup)
        last = train_step(step)
        done, n = done + 1, step + 1
        shown = (
            {k: smoothing * shown.get(k, v) + (1 - smoothing) * v for k, v in last.items()}
            if smoothing
            else last
        )
        bar.update(1)
        if postfix:
            bar.set_postfix({k: f"{last[k]:{fmt}}" for k, fmt in postfix.items()}, refresh=False)
        if n % config.log_every == 0:
            bar.write(
                f"{kind} step {n}/{steps} {_terms(shown)} {(time.perf_counter() - t0) / done:.3f} s/step"
            )
        if evaluate is not None and config.eval_every and n % config.eval_every == 0:
            val = evaluate()
            bar.write(f"{kind} step {n} val {_terms(val)}")
        timed_out = time.perf_counter() - t0 > config.max_minutes * 60
        if save is not None and (n % config.save_every == 0 or n == steps or timed_out):
            save(n, {**last, **{f"val_{k}": v for k, v in val.items()}})
        if timed_out:
            bar.write(f"{kind}: stopping at step {n} after {config.max_minutes} minutes")
        if timed_out or (on_step is not None and on_step(n, last)):
            break
    bar.close()
    return LoopResult(start + done, done, last, (time.perf_counter() - t0) / max(1, done))


def final_metrics(
    result: LoopResult, ckpt: dict[str, Any] | None, evaluations: dict[str, dict[str, float]]
) -> dict[str, float]:
    """The metrics a trainer returns and stores at the end: the last logged loss terms (those of the
    checkpoint when a resumed run had nothing left to do), the speed, and each evaluation's numbers
    under its prefix (``{"val": {...}}`` -> ``val_<name>``)."""
    last = dict(ckpt.get("metrics", {})) if result.done == 0 and ckpt is not None else result.last
    metrics = {"step": float(result.step), **last, "seconds_per_step": result.seconds_per_step}
    for prefix, values in evaluations.items():
        metrics.update({f"{prefix}_{k}": v for k, v in values.items()})
    return metrics
