"""Training of the path controller on the root paths of real clips, closed loop.

Each sample is a window of a real clip: the controller starts at the clip's root at the window's
first frame and rolls out through differentiable integration, frame by frame, with the waypoint
features recomputed from its *predicted* position (so it learns to correct its own drift). The
waypoints are the clip's own future root positions: timed at random spacing (1-3 s), untimed
(1-3 s apart, as the shipped controller was trained, so that their spacing tells the pace; or,
with ``untimed_by="distance"``, 1.5-6 m apart along the path whatever the pace), mixed, dense, a
single far one, or none at all (then it must follow the caption's natural motion).
Losses: position (weighted up at waypoint frames), local velocity, turn rate (zero-turn target on
still frames), heading, turn smoothness and acceleration.

Batches are drawn from ``numpy.random.default_rng([seed, step])``, so a resumed run sees exactly
the batches an uninterrupted one would. The loop, the learning-rate schedule and the checkpoints
are :mod:`motion_env.training.loop`'s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import torch
from tqdm.auto import tqdm

from motion_env.data.dataset import read_split
from motion_env.models.checkpoint import (
    check_text_encoder,
    config_from_dict,
    load_checkpoint,
    text_encoder_record,
)
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.waypoint_features import to_heading_frame_torch
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import root_path_from_joints, waypoint_errors
from motion_env.motion.validation import NonNegativeFloat, NonNegativeInt, PositiveFloat, PositiveInt
from motion_env.text.encoders import DEFAULT_TEXT_ENCODER, TextEncoder, jitter_embeddings
from motion_env.training import loop
from motion_env.training.config import TrainConfig

CHECKPOINT_KIND = "controller"
# A frame is "still" below this root speed (m/s): its turn target is zero (no spin on the spot).
STILL_SPEED = 0.25
# Untimed waypoints are this many metres apart along the path (uniform), whatever the pace: their
# spacing must not tell the controller how fast to go (the route planner splits longer legs).
UNTIMED_SPACING = (1.5, 6.0)
# Waypoint sampling modes and their probabilities.
MODES: dict[str, float] = {
    "timed": 0.40,
    "untimed": 0.15,
    "mixed": 0.10,
    "dense": 0.10,
    "single": 0.10,
    "none": 0.15,
}


@dataclass
class PathData:
    """Root paths of clips with their caption embeddings.

    Attributes:
        paths: per clip, (T_i, 3) float32 root paths.
        captions: per clip, int indices into `embeddings` (its captions).
        embeddings: (N, text_dim) float32 caption embeddings.
        names: clip names.
    """

    paths: list[np.ndarray]
    captions: list[np.ndarray]
    embeddings: np.ndarray
    names: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        if len(self.paths) != len(self.captions) or not self.paths:
            raise ValueError(f"PathData needs >= 1 clip and one caption list per clip, got {len(self.paths)}")
        for i, c in enumerate(self.captions):
            if len(c) == 0:
                raise ValueError(f"clip {self.names[i] if self.names else i} has no caption")


def path_data_from_clips(
    clips: Sequence[Any], encode: Callable[[list[str]], Any], min_frames: int = 24
) -> PathData:
    """Root paths and caption embeddings of dataset clips.

    Args:
        clips: objects with ``name``, ``joints`` (T, 22, 3) and ``captions`` (list[str]).
        encode: list of captions -> (N, text_dim) embeddings (a text encoder's ``encode``).
        min_frames: shorter clips are skipped.
    """
    kept = [c for c in clips if len(c.joints) >= min_frames and len(c.captions) > 0]
    if not kept:
        raise ValueError(f"no clip has >= {min_frames} frames and a caption")
    texts = sorted({t for c in kept for t in c.captions})
    index = {t: i for i, t in enumerate(texts)}
    emb = [np.asarray(encode(texts[i : i + 256]), dtype=np.float32) for i in range(0, len(texts), 256)]
    return PathData(
        paths=[root_path_from_joints(c.joints) for c in kept],
        captions=[np.array([index[t] for t in c.captions]) for c in kept],
        embeddings=np.concatenate(emb),
        names=[c.name for c in kept],
    )


@dataclass
class Batch:
    """A training batch of B windows of W frames (frame 0 = the start state)."""

    text: torch.Tensor  # (B, text_dim)
    start: torch.Tensor  # (B, 3)
    target: torch.Tensor  # (B, W, 3) real root path
    mask: torch.Tensor  # (B, W) frames that count
    waypoints: list[np.ndarray | None]  # per sample, (K, 3); times relative to the window start
    wp_weight: torch.Tensor  # (B, W) extra position weight at timed waypoint frames
    free: torch.Tensor  # (B,) True when the sample has no waypoints


def _frames_by_distance(path: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Frames of `path` (from its first frame) at random distances along it, UNTIMED_SPACING apart."""
    step = np.linalg.norm(np.diff(path[:, :2], axis=0), axis=1)
    walked = np.concatenate([[0.0], np.cumsum(step)])
    marks = [rng.uniform(*UNTIMED_SPACING)]
    while marks[-1] < walked[-1]:
        marks.append(marks[-1] + rng.uniform(*UNTIMED_SPACING))
    frames = np.unique(np.searchsorted(walked, marks[:-1]))
    frames = frames[(frames >= 1) & (frames < len(path))]
    return frames if len(frames) else np.array([len(path) - 1])


def sample_waypoints(
    path: np.ndarray,
    start: int,
    window: int,
    mode: str,
    rng: np.random.Generator,
    untimed_by: str = "time",
) -> tuple[np.ndarray | None, np.ndarray]:
    """Waypoints from a clip's own future root positions.

    `untimed_by`: untimed waypoints (mode "untimed") are spaced by "distance" along the path
    (:data:`UNTIMED_SPACING`, whatever the pace) or, as the first controllers were trained, by
    "time" (1-3 s apart, so that their spacing tells the pace).

    Returns:
        (waypoints (K, 3) with times relative to `start` (NaN where untimed) or None for mode
        "none", the frames (K,) relative to `start` the waypoints were taken from).
    """
    n = path.shape[0] - start  # frames available from the window start
    if mode == "none" or n < 2:
        return None, np.zeros(0, np.int64)
    if mode == "untimed" and untimed_by == "distance":
        frames = _frames_by_distance(path[start:], rng)
    elif mode == "dense":
        every = int(rng.choice([1, 2, 4]))
        frames = np.arange(every, n, every)
    elif mode == "single":
        frames = np.array([int(rng.integers(min(20, n - 1), n))])
    else:  # 1-3 s apart
        frames = [int(rng.integers(20, 61))]
        while frames[-1] + 20 < n:
            frames.append(frames[-1] + int(rng.integers(20, 61)))
        frames = np.array([f for f in frames if f < n] or [n - 1])
    frames = frames[: max(1, int(np.searchsorted(frames, window + 80)))]  # enough to see past the window
    wp = np.concatenate([path[start + frames, :2], frames[:, None].astype(np.float32)], axis=1)
    if mode == "untimed":
        wp[:, 2] = np.nan
    elif mode == "mixed":
        wp[rng.random(len(wp)) < 0.5, 2] = np.nan
    return wp.astype(np.float32), frames.astype(np.int64)


def sample_batch(
    data: PathData,
    rng: np.random.Generator,
    batch_size: int,
    window: int,
    text_noise: float = 0.0,
    untimed_by: str = "time",
) -> Batch:
    """Draw B windows with their waypoints (see the module docstring).

    `text_noise` jitters the caption embeddings (:func:`motion_env.text.jitter_embeddings`);
    `untimed_by` spaces untimed waypoints (:func:`sample_waypoints`).
    """
    lengths = np.array([len(p) for p in data.paths], dtype=np.float64)
    probs = lengths / lengths.sum()
    names, weights = list(MODES), np.array(list(MODES.values()))
    text, start, target, mask, wps, wpw, free = [], [], [], [], [], [], []
    for _ in range(batch_size):
        clip = int(rng.choice(len(data.paths), p=probs))
        path = data.paths[clip]
        s = int(rng.integers(0, max(1, len(path) - window) + 1))
        seg = path[s : s + window]
        m = np.zeros(window, np.float32)
        m[: len(seg)] = 1.0
        seg = np.concatenate([seg, np.repeat(seg[-1:], window - len(seg), 0)])
        mode = str(rng.choice(names, p=weights / weights.sum()))
        wp, frames = sample_waypoints(path, s, window, mode, rng, untimed_by)
        if wp is not None and frames[-1] < window - 1:
            m[frames[-1] + 1 :] = 0.0  # after the final waypoint the arrive gating holds the character
        w = np.zeros(window, np.float32)
        if wp is not None:
            timed = frames[~np.isnan(wp[:, 2])]
            w[timed[timed < window]] = 1.0 if mode != "dense" else 0.1
        text.append(data.embeddings[int(rng.choice(data.captions[clip]))])
        start.append(seg[0])
        target.append(seg)
        mask.append(m)
        wps.append(wp)
        wpw.append(w)
        free.append(wp is None)
    return Batch(
        text=jitter_embeddings(torch.from_numpy(np.stack(text)), text_noise, rng),
        start=torch.from_numpy(np.stack(start)),
        target=torch.from_numpy(np.stack(target)),
        mask=torch.from_numpy(np.stack(mask)),
        waypoints=wps,
        wp_weight=torch.from_numpy(np.stack(wpw)),
        free=torch.tensor(free),
    )


def _local_motion(roots: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, W, 3) root paths -> per-step local velocity (B, W-1, 2) in m/s and turn rate (B, W-1) rad/s."""
    theta_mid = 0.5 * (roots[:, 1:, 2] + roots[:, :-1, 2])
    vel = to_heading_frame_torch(roots[:, 1:, :2] - roots[:, :-1, :2], theta_mid) * FPS
    turn = (roots[:, 1:, 2] - roots[:, :-1, 2]) * FPS
    return vel, turn


def controller_loss(
    model: PathController, batch: Batch, generator: torch.Generator | None = None
) -> tuple[torch.Tensor, dict[str, float]]:
    """Closed-loop rollout of a batch and its loss; returns (loss, named parts)."""
    dev = model.device
    state = model.init_state(batch.text.to(dev), batch.waypoints, batch.start.to(dev), generator=generator)
    window = batch.target.shape[1]
    roots, _ = model(state, window - 1)  # (B, W, 3)
    target, mask, wpw = batch.target.to(dev), batch.mask.to(dev), batch.wp_weight.to(dev)
    free = batch.free.to(dev)[:, None].float()
    msum = mask[:, 1:].sum().clamp(min=1.0)

    dist = (roots[..., :2] - target[..., :2]).norm(dim=-1)  # (B, W)
    pos_w = mask * (1.0 - 0.7 * free)  # no route: the exact path is not determined by the caption
    loss_pos = (dist * pos_w).sum() / msum
    loss_wp = (dist * wpw * mask).sum() / (wpw * mask).sum().clamp(min=1.0)

    vel_p, turn_p = _local_motion(roots)
    vel_t, turn_t = _local_motion(target)
    step_mask = mask[:, 1:]
    still = vel_t.norm(dim=-1) < STILL_SPEED
    turn_t = torch.where(still, torch.zeros_like(turn_t), turn_t)
    loss_vel = ((vel_p - vel_t).abs().sum(-1) * step_mask).sum() / msum
    loss_turn = ((turn_p - turn_t).abs() * step_mask).sum() / msum
    head_err = torch.remainder(roots[..., 2] - target[..., 2] + math.pi, 2 * math.pi) - math.pi
    loss_head = (head_err.abs() * mask).sum() / mask.sum().clamp(min=1.0)
    loss_smooth = ((turn_p[:, 1:] - turn_p[:, :-1]).abs() * step_mask[:, 1:]).sum() / msum
    # Accelerations like the real path's: without this the controller brakes and surges around
    # timed waypoints to hit their frames (35 m/s^2 dips at 3 m/s), forces no body can make.
    acc_err = ((vel_p[:, 1:] - vel_p[:, :-1]) - (vel_t[:, 1:] - vel_t[:, :-1])).abs().sum(-1)
    loss_acc = (acc_err * step_mask[:, 1:]).sum() / msum

    loss = (
        loss_pos + 2.0 * loss_wp + 0.5 * loss_vel + 0.3 * loss_turn + 0.5 * loss_head
        + 0.1 * loss_smooth + 0.5 * loss_acc
    )  # fmt: skip
    parts = {
        "pos": loss_pos.item(),
        "wp": loss_wp.item(),
        "vel": loss_vel.item(),
        "turn": loss_turn.item(),
        "head": loss_head.item(),
        "acc": loss_acc.item(),
    }
    return loss, parts


@torch.no_grad()
def evaluate_controller(
    model: PathController,
    data: PathData,
    num_windows: int = 256,
    window: int = 160,
    seed: int = 1234,
    mode: str = "timed",
    snap: bool = True,
) -> dict[str, float]:
    """Root error of closed-loop rollouts on held-out windows (waypoints from the clips' own future).

    Root error (docs/metrics.md): XZ distance between the pelvis at a timed waypoint's frame and the
    waypoint, in cm; untimed waypoints are measured at the closest approach. Reported raw and,
    with `snap`, after :func:`motion_env.generation.recompose.snap_to_waypoints`. Only waypoints inside the
    window count.
    """
    from motion_env.generation.recompose import snap_to_waypoints

    if mode not in MODES or mode == "none":
        raise ValueError(f"mode must be one of {[m for m in MODES if m != 'none']}, got {mode!r}")
    rng = np.random.default_rng(seed)
    lengths = np.array([len(p) for p in data.paths], dtype=np.float64)
    raw, snapped, clip_max = [], [], []
    model.eval()
    for first in range(0, num_windows, 64):
        b = min(64, num_windows - first)
        text, starts, wps = [], [], []
        for _ in range(b):
            clip = int(rng.choice(len(data.paths), p=lengths / lengths.sum()))
            path = data.paths[clip]
            s = int(rng.integers(0, max(1, len(path) - window) + 1))
            n_valid = min(window, len(path) - s)
            wp, frames = sample_waypoints(path, s, window, mode, rng)
            wps.append(None if wp is None or frames[0] >= n_valid else wp[frames < n_valid])
            text.append(data.embeddings[int(rng.choice(data.captions[clip]))])
            starts.append(path[s])
        paths = model.rollout_batch(torch.from_numpy(np.stack(text)), wps, window, np.stack(starts))
        for i, wp in enumerate(wps):
            if wp is None:
                continue
            err = waypoint_errors(paths[i], wp)
            raw.extend(err.tolist())
            clip_max.append(float(err.max()))
            if snap:
                snapped.extend(waypoint_errors(snap_to_waypoints(paths[i], wp), wp).tolist())
    raw_a = np.array(raw)
    out = {
        "root_error_cm": float(raw_a.mean() * 100),
        "location_error": float((raw_a > 0.5).mean()),
        "trajectory_error": float((np.array(clip_max) > 0.5).mean()),
        "num_waypoints": float(len(raw_a)),
    }
    if snap:
        out["root_error_snapped_cm"] = float(np.mean(snapped) * 100)
    return out


@dataclass(kw_only=True)
class ControllerTrainConfig(TrainConfig):
    """How to train the path controller (stored in its checkpoint under ``"settings"``)."""

    steps: PositiveInt = 2000  # total optimisation steps (those of a resumed run included)
    batch_size: PositiveInt = 64  # windows per step
    lr: PositiveFloat = 1e-3  # peak AdamW learning rate (linear warm-up, cosine decay to a tenth)
    window: Annotated[int, ">= 2"] = 100  # frames per training window
    warmup: NonNegativeInt = 50  # warm-up steps of the learning rate
    grad_clip: PositiveFloat = 1.0  # gradient norm clip
    text_noise: NonNegativeFloat = 0.3  # expected norm of the noise added to caption embeddings (0: off)
    untimed_by: str = "time"  # untimed waypoints 1-3 s apart (time, as shipped) or 1.5-6 m (distance)
    encoder: str = DEFAULT_TEXT_ENCODER  # text encoder name (motion_env.text.load_text_encoder)
    eval_windows: PositiveInt = 256  # val windows per evaluation
    log_every: PositiveInt = 25  # steps between loss lines in the log (running averages)
    save_every: PositiveInt = 50  # steps between checkpoints (one is also written at the end)

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.untimed_by not in ("distance", "time"):
            raise ValueError(
                f"ControllerTrainConfig.untimed_by must be 'distance' or 'time', got {self.untimed_by!r}"
            )


# The name of the controller's settings before each trainer had its TrainConfig


def fit(
    model: PathController,
    data: PathData,
    settings: ControllerTrainConfig,
    optimizer: torch.optim.Optimizer | None = None,
    start_step: int = 0,
    on_step: Callable[[int, dict[str, float]], bool] | None = None,
    progress: bool = True,
    *,
    save: Callable[[int, dict[str, float]], None] | None = None,
    evaluate: Callable[[], dict[str, float]] | None = None,
) -> tuple[torch.optim.Optimizer, int]:
    """Train `model` from `start_step` to `settings.steps`.

    `on_step(step, parts)` runs after each step (step counts those done) and may return True to
    stop early; `save` and `evaluate` are :func:`motion_env.training.loop.run_loop`'s (None: no
    checkpoints, no periodic validation). Returns (optimizer, steps done).
    """
    if optimizer is None:
        optimizer = torch.optim.AdamW(model.parameters(), lr=settings.lr, weight_decay=1e-4)
    dev = model.device

    def train_step(step: int) -> dict[str, float]:
        model.train()
        rng = np.random.default_rng([settings.seed, step])
        gen = torch.Generator(device=dev).manual_seed(settings.seed * 1_000_003 + step)
        batch = sample_batch(
            data, rng, settings.batch_size, settings.window, settings.text_noise, settings.untimed_by
        )
        loss, parts = controller_loss(model, batch, gen)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), settings.grad_clip)
        optimizer.step()
        parts["loss"] = loss.item()
        return parts

    result = loop.run_loop(
        CHECKPOINT_KIND, settings, optimizer, train_step, warmup=settings.warmup, start=start_step,
        save=save, evaluate=evaluate, postfix={"loss": ".3f", "wp": ".3f"}, smoothing=0.95,
        on_step=on_step, progress=progress,
    )  # fmt: skip
    return optimizer, result.step


def load_controller(path: str | Path, device: str | torch.device = "cpu") -> tuple[PathController, dict]:
    """A trained controller from its checkpoint: (model in eval mode, the checkpoint dict)."""
    return load_checkpoint(path, CHECKPOINT_KIND, ControllerConfig, PathController, device)


def train_controller(
    data_dir: str | Path,
    out_path: str | Path,
    config: ControllerTrainConfig | None = None,
    model_config: ControllerConfig | None = None,
    text_encoder: TextEncoder | None = None,
) -> dict[str, float]:
    """Train the path controller on a HumanML3D-layout dataset and checkpoint it.

    Args:
        data_dir: dataset root (``train.txt``, ``val.txt``, ``new_joints/``, ``texts/``).
        out_path: checkpoint file; written atomically every ``config.save_every`` steps and at
            the end (resumed from when it exists and ``config.resume``: same batches).
        config: training settings (default ControllerTrainConfig()).
        model_config: model sizes (default ControllerConfig() with the text encoder's width; a
            resumed run takes the checkpoint's, and a different one given here is an error).
        text_encoder: an already loaded encoder to use instead of ``config.encoder`` (whose
            name is then stored as ``config.encoder``).

    Returns:
        The final val metrics: :func:`evaluate_controller` with timed waypoints (``root_error_cm``
        raw, ``root_error_snapped_cm`` after snapping, location/trajectory error), the same with
        untimed waypoints (``untimed_*``, closest approach), and ``step``.
    """
    config = config or ControllerTrainConfig()
    device = config.device
    torch.manual_seed(config.seed)
    out_path = Path(out_path)
    config, text_encoder = loop.with_text_encoder(config, text_encoder)
    train = path_data_from_clips(read_split(Path(data_dir), "train"), text_encoder.encode)
    val = path_data_from_clips(read_split(Path(data_dir), "val"), text_encoder.encode)
    tqdm.write(f"controller: {len(train.paths)} train clips, {len(val.paths)} val clips")

    # Built even when resuming, so that the seeded torch RNG stands where it always has afterwards.
    model = PathController(model_config or ControllerConfig(text_dim=int(text_encoder.dim))).to(device)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=1e-4)
    start = 0
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, model_config)
    if ckpt is not None:
        check_text_encoder(ckpt, text_encoder, out_path)
        model = PathController(config_from_dict(ControllerConfig, ckpt["config"])).to(device)
        optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=1e-4)
        start = loop.restore(ckpt, model, optimizer)
        tqdm.write(f"controller: resuming {out_path} at step {start}")
    tqdm.write(f"controller: {model.num_parameters() / 1e6:.2f} M parameters")

    save = loop.checkpoint_writer(
        out_path, kind=CHECKPOINT_KIND, model=model, optimizer=optimizer, settings=config,
        text_encoder=text_encoder_record(text_encoder),
    )  # fmt: skip

    _, step = fit(
        model, train, config, optimizer, start, save=save,
        evaluate=lambda: evaluate_controller(model, val, config.eval_windows, snap=False),
    )  # fmt: skip
    metrics = evaluate_controller(model, val, config.eval_windows)
    untimed = evaluate_controller(model, val, config.eval_windows, mode="untimed", snap=False)
    metrics.update({f"untimed_{k}": v for k, v in untimed.items()})
    metrics["step"] = float(step)
    save(step, metrics)
    tqdm.write("controller: final val " + " ".join(f"{k}={v:.4f}" for k, v in metrics.items()))
    return metrics
