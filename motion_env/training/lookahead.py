"""Distilling the look-ahead head (:mod:`motion_env.models.lookahead`) from the path controller.

The head learns where a trained controller goes in the ``horizon`` frames after a state, so the
data are the controller's own closed-loop roll-outs over routes of real takes (the train split's
root paths, waypoints drawn as the controller's training draws them,
:func:`motion_env.training.controller.sample_batch`), in the situations the stream meets:

- a roll-out runs a random number of frames on its route (the GRU state carries its history);
- then each character, as in the environments, gets a new command: a single untimed point within
  ``reach`` metres (what a learner sends), one farther away, a new caption, or nothing new (the
  route goes on); the route is planned as the stream plans it
  (:func:`motion_env.generation.route_planning.plan_route`);
- the states of the frames after the change (every ``stride`` frames) are the inputs, the next
  ``horizon`` frames of the roll-out the targets.

The pool of pairs is drawn once from ``numpy.random.default_rng([seed, n])`` (the same pool
when a run resumes); the loop, the schedule and the checkpoints are
:mod:`motion_env.training.loop`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from motion_env.data.dataset import read_split
from motion_env.generation.route_planning import plan_route
from motion_env.models.checkpoint import check_text_encoder, load_checkpoint
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.controller_state import ControllerState, Trace
from motion_env.models.lookahead import (
    CHECKPOINT_KIND,
    LookaheadConfig,
    LookaheadHead,
    controller_fingerprint,
)
from motion_env.models.waypoint_features import to_heading_frame_torch
from motion_env.motion.kinematics import from_heading_frame
from motion_env.motion.validation import NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt
from motion_env.training import loop
from motion_env.training.config import TrainConfig
from motion_env.training.controller import PathData, path_data_from_clips, sample_batch

__all__ = ["LookaheadTrainConfig", "distill_pairs", "evaluate_lookahead", "train_lookahead"]

# What a character gets after its burn-in: probabilities of a near point, a far point, a new
# caption and nothing new.
COMMANDS = {"near": 0.45, "far": 0.15, "caption": 0.1, "none": 0.3}


@dataclass(kw_only=True)
class LookaheadTrainConfig(TrainConfig):
    """How to distil the look-ahead head (stored in its checkpoint under ``"settings"``)."""

    weights: str = "shipped"  # generator weights folder whose controller is distilled
    steps: PositiveInt = 3000  # total optimisation steps
    batch_size: PositiveInt = 512  # pairs per step
    lr: PositiveFloat = 1e-3  # peak AdamW learning rate (linear warm-up, cosine decay to a tenth)
    warmup: NonNegativeInt = 100  # warm-up steps of the learning rate
    rollouts: PositiveInt = 240  # roll-out batches of the train pool (each gives rows x offsets pairs)
    val_rollouts: PositiveInt = 24  # roll-out batches of the val pool
    rows: PositiveInt = 64  # characters per roll-out batch
    burn_in: PositiveInt = 80  # frames on the first route before the change: uniform in [0, burn_in)
    stride: PositiveInt = 2  # frames between the states taken after the change
    after: PositiveInt = 24  # states are taken up to this many frames after the change
    reach: PositiveFloat = 3.0  # metres: the near commands (a learner's normalised reach)
    text_noise: NonNegativeFloat = 0.3  # caption embedding jitter (as the controller's training)
    captions_per_clip: PositiveInt = 1  # captions embedded per clip (of about 12; encoding is slow)
    log_every: PositiveInt = 100  # steps between loss lines in the log
    save_every: PositiveInt = 500  # steps between checkpoints (one is also written at the end)


def _command_routes(
    state: ControllerState, rng: np.random.Generator, reach: float
) -> tuple[list[int], list[np.ndarray | None], list[int], list[str]]:
    """Per character a new command: (rows with a new route, their planned routes, rows with a new
    caption, every row's command name)."""
    names = list(COMMANDS)
    probs = np.array(list(COMMANDS.values()))
    pos = state.pos.cpu().numpy().astype(np.float64)
    theta = state.theta.cpu().numpy().astype(np.float64)
    frame = state.frame.cpu().numpy()
    route_rows, routes, caption_rows, kinds = [], [], [], []
    for i in range(len(pos)):
        kind = str(rng.choice(names, p=probs / probs.sum()))
        kinds.append(kind)
        if kind in ("near", "far"):
            local = rng.uniform(-1.0, 1.0, 2) * reach if kind == "near" else rng.uniform(-8.0, 8.0, 2)
            world = pos[i] + from_heading_frame(local, theta[i])
            route = np.array([[world[0], world[1], np.nan]], np.float32)
            route_rows.append(i)
            routes.append(plan_route(route, pos[i].astype(np.float32), int(frame[i])))
        elif kind == "caption":
            caption_rows.append(i)
    return route_rows, routes, caption_rows, kinds


def _state_at(state: ControllerState, trace: Trace, n: int) -> ControllerState:
    """The roll-out's state at trace frame n (1-based: frame n after `state`)."""
    roots = trace.roots[:, n - 1]
    return replace(
        state,
        pos=roots[:, :2],
        theta=roots[:, 2],
        vel=trace.vel[:, n - 1],
        hidden=trace.hidden[:, n - 1],
        queue=trace.queue[:, n - 1],
        frame=state.frame + n,
    )


def offsets_from_roots(roots: torch.Tensor, start: ControllerState) -> torch.Tensor:
    """(B, H, 3) world roots -> offsets in the start's heading frame (the head's output)."""
    xz = to_heading_frame_torch(roots[..., :2] - start.pos[:, None], start.theta[:, None])
    return torch.cat([xz, (roots[..., 2] - start.theta[:, None])[..., None]], dim=-1)


@torch.no_grad()
def distill_pairs(
    controller: PathController,
    data: PathData,
    rng: np.random.Generator,
    settings: LookaheadTrainConfig,
    horizon: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One roll-out batch (see the module docstring): (inputs (N, input_dim), offsets (N, horizon, 3))."""
    dev = controller.device
    batch = sample_batch(data, rng, settings.rows, settings.burn_in + 1, settings.text_noise)
    gen = torch.Generator(device=dev).manual_seed(int(rng.integers(2**31 - 1)))
    state = controller.init_state(batch.text.to(dev), batch.waypoints, batch.start.to(dev), generator=gen)
    state, _ = controller.run(state, int(rng.integers(0, settings.burn_in)))
    route_rows, routes, caption_rows, _ = _command_routes(state, rng, settings.reach)
    if route_rows:
        state = controller.set_routes(state, route_rows, routes)
    if caption_rows:
        text = state.text.clone()
        other = rng.choice(len(data.embeddings), len(caption_rows))
        text[caption_rows] = torch.from_numpy(data.embeddings[other]).to(dev)
        state = replace(state, text=text)
    _, trace = controller.run(state, settings.after + horizon, trace=True)
    inputs, targets = [], []
    for n in range(0, settings.after + 1, settings.stride):
        at = state if n == 0 else _state_at(state, trace, n)
        inputs.append(LookaheadHead.inputs(controller, at))
        targets.append(offsets_from_roots(trace.roots[:, n : n + horizon], at))
    return torch.cat(inputs), torch.cat(targets)


def _pool(
    controller: PathController,
    data: PathData,
    settings: LookaheadTrainConfig,
    count: int,
    stream: int,
    horizon: int,
    what: str,
) -> tuple[torch.Tensor, torch.Tensor]:
    xs, ys = [], []
    for n in tqdm(range(count), desc=f"lookahead: {what} roll-outs", disable=not settings.progress):
        x, y = distill_pairs(
            controller, data, np.random.default_rng([settings.seed, stream, n]), settings, horizon
        )
        xs.append(x.cpu())
        ys.append(y.cpu())
    return torch.cat(xs), torch.cat(ys)


def _pools(
    controller: PathController, data_dir: str | Path, encoder: Any, config: LookaheadTrainConfig, horizon: int
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The train and val pools of pairs: (inputs, offsets) of each."""
    train, val = (_path_data(data_dir, split, encoder, config) for split in ("train", "val"))
    x_train, y_train = _pool(controller, train, config, config.rollouts, 0, horizon, "train")
    x_val, y_val = _pool(controller, val, config, config.val_rollouts, 1, horizon, "val")
    tqdm.write(
        f"lookahead: {len(x_train)} train pairs from {len(train.paths)} clips, {len(x_val)} val pairs "
        f"from {len(val.paths)}"
    )
    return x_train, y_train, x_val, y_val


@torch.no_grad()
def evaluate_lookahead(head: LookaheadHead, inputs: torch.Tensor, offsets: torch.Tensor) -> dict[str, float]:
    """Errors of the head's window against the controller's: mean and 99th percentile of the
    position error over the window (cm), at its last frame (cm), and of the heading (degrees)."""
    head.eval()
    dev = head.in_mean.device
    pred = torch.cat([head(inputs[i : i + 4096].to(dev)).cpu() for i in range(0, len(inputs), 4096)])
    err = (pred[..., :2] - offsets[..., :2]).norm(dim=-1) * 100.0  # (N, H) cm
    head_err = (pred[..., 2] - offsets[..., 2]).abs().rad2deg()
    return {
        "pos_cm": float(err.mean()),
        "pos_p99_cm": float(err.quantile(0.99)),
        "last_cm": float(err[:, -1].mean()),
        "last_p99_cm": float(err[:, -1].quantile(0.99)),
        "heading_deg": float(head_err.mean()),
    }


def _path_data(data_dir: str | Path, split: str, encoder: Any, settings: LookaheadTrainConfig) -> PathData:
    """The root paths of a split with `captions_per_clip` of each clip's captions (seeded)."""
    rng = np.random.default_rng([settings.seed, 7])
    clips = []
    for clip in read_split(Path(data_dir), split):
        keep = min(settings.captions_per_clip, len(clip.captions))
        picked = [clip.captions[int(i)] for i in rng.choice(len(clip.captions), keep, replace=False)]
        clips.append(replace(clip, captions=picked))
    return path_data_from_clips(clips, encoder.encode)


def _controller(settings: LookaheadTrainConfig) -> tuple[PathController, dict, Path]:
    from motion_env.generation.generator import DEFAULT_WEIGHTS, WEIGHT_FILES

    folder = DEFAULT_WEIGHTS if settings.weights == "shipped" else Path(settings.weights)
    path = folder / WEIGHT_FILES["controller"]
    if not path.is_file():
        raise FileNotFoundError(f"no controller at {path} (--weights names a generator weights folder)")
    controller, ckpt = load_checkpoint(path, "controller", ControllerConfig, PathController, settings.device)
    return controller, ckpt, path


def train_lookahead(
    data_dir: str | Path,
    out_path: str | Path,
    config: LookaheadTrainConfig | None = None,
    model_config: LookaheadConfig | None = None,
    text_encoder: Any = None,
) -> dict[str, float]:
    """Distil the look-ahead head of a weights folder's controller and checkpoint it.

    Args:
        data_dir: dataset root (``train.txt``, ``val.txt``, ``new_joints/``, ``texts/``): the routes.
        out_path: the checkpoint (resumed from when it exists and ``config.resume``);
            ``lookahead.pt`` in the weights folder is what the generator loads (written with
            :func:`motion_env.models.checkpoint.export_checkpoint`, float16).
        config: training settings (default LookaheadTrainConfig()).
        model_config: head sizes (default: ``LookaheadConfig.for_controller`` of the controller).
        text_encoder: an already loaded encoder (it must be the controller's) instead of loading
            the one the controller's checkpoint names.

    Returns:
        :func:`evaluate_lookahead` on the val pool, and ``step``.
    """
    from motion_env.text.encoders import load_text_encoder

    config = config or LookaheadTrainConfig()
    if not Path(data_dir).is_dir():
        raise FileNotFoundError(f"no dataset directory at {data_dir}")
    torch.manual_seed(config.seed)
    out_path = Path(out_path)
    controller, ctrl_ckpt, ctrl_path = _controller(config)
    record = ctrl_ckpt.get("text_encoder") or {"name": "minilm"}
    if text_encoder is None:
        text_encoder = load_text_encoder(record["name"], None, config.device)
    check_text_encoder(ctrl_ckpt, text_encoder, ctrl_path)
    c = controller.config
    model_config = model_config or LookaheadConfig.for_controller(c)
    head = LookaheadHead(model_config).to(config.device)
    head.check_controller(controller)
    tqdm.write(f"lookahead: distilling {ctrl_path}")
    x_train, y_train, x_val, y_val = _pools(controller, data_dir, text_encoder, config, model_config.horizon)
    head.set_normalization(x_train.mean(0), x_train.std(0), y_train.std(0))

    optimizer = torch.optim.AdamW(head.parameters(), lr=config.lr, weight_decay=1e-4)
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, model_config)
    start = loop.restore(ckpt, head, optimizer)
    if start:
        tqdm.write(f"lookahead: resuming {out_path} at step {start}")
    tqdm.write(f"lookahead: {head.num_parameters() / 1e6:.2f} M parameters")
    save = loop.checkpoint_writer(
        out_path, kind=CHECKPOINT_KIND, model=head, optimizer=optimizer, settings=config,
        text_encoder=record, controller_fingerprint=controller_fingerprint(controller),
    )  # fmt: skip
    dev = head.in_mean.device
    x_dev, y_dev = x_train.to(dev), (y_train / head.out_scale.cpu()).to(dev)

    def train_step(step: int) -> dict[str, float]:
        head.train()
        gen = torch.Generator().manual_seed(config.seed * 1_000_003 + step)
        pick = torch.randint(len(x_dev), (config.batch_size,), generator=gen).to(dev)
        pred = head(x_dev[pick]) / head.out_scale
        loss = torch.nn.functional.mse_loss(pred, y_dev[pick])
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        return {"loss": loss.item()}

    result = loop.run_loop(
        CHECKPOINT_KIND, config, optimizer, train_step, warmup=config.warmup, start=start, save=save,
        evaluate=lambda: evaluate_lookahead(head, x_val, y_val), postfix={"loss": ".4f"}, smoothing=0.95,
        progress=config.progress,
    )  # fmt: skip
    metrics = evaluate_lookahead(head, x_val, y_val)
    metrics["step"] = float(result.step)
    save(result.step, metrics)
    tqdm.write("lookahead: final val " + " ".join(f"{k}={v:.4f}" for k, v in metrics.items()))
    return metrics
