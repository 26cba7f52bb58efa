"""MotionGenerator: caption + waypoints -> motion, as whole clips or streamed frame by frame.

The one place that wires the parts together (C-T2M's decoupled pipeline):

1. the path controller (:mod:`motion_env.controller`) rolls out the root path (x, z, heading)
   from the caption and the waypoints, closed loop, frame by frame;
2. :func:`motion_env.recompose.snap_to_waypoints` bends it exactly through the timed waypoints
   and the untimed ones it passes within ``SNAP_RADIUS``;
3. per-token path features (:func:`motion_env.paths.token_path_features`) tell the body GPT how
   the root moves over each token and the second after it;
4. the body GPT (:mod:`motion_env.gpt`) samples motion tokens one by one (multinomial, seeded
   per character), conditioned on the caption, the path features and the past tokens;
5. the VQ-VAE (:mod:`motion_env.vqvae`) decodes the tokens into normalised 263-d features, which
   are denormalised with the training set's Mean/Std;
6. the decoded body, relative to its root, is recomposed onto the root path
   (:mod:`motion_env.recompose`), rebuilt on the skeleton's fixed bone lengths
   (:func:`motion_env.motion.with_bone_lengths`: decoded legs come out up to 9 cm short), and the feet
   are pinned where the decoder says they are in contact (:class:`FootPinner`).

Streaming (:class:`motion_env.streaming.MotionStream`, from :meth:`MotionGenerator.stream`) runs
the same steps causally, one token at a time; see :mod:`motion_env.streaming`.

Weights: a directory holding ``vqvae.pt`` (with the dataset Mean/Std), ``gpt.pt`` and
``controller.pt`` (:mod:`motion_env.checkpoint` files) and optionally ``sampling.json``; the
shipped default is ``motion_env/weights/`` inside the package.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from motion_env.checkpoint import check_text_encoder, load_checkpoint, save_checkpoint
from motion_env.clip import Motion
from motion_env.controller import ControllerConfig, ControllerState, PathController
from motion_env.gpt import GPTConfig, TokenGPT
from motion_env.motion import with_bone_lengths
from motion_env.paths import LOOKAHEAD_FRAMES, token_path_features, validate_waypoints
from motion_env.recompose import (
    LEGS,
    align_heading_to_travel,
    local_pose_from_features,
    recompose,
    snap_to_waypoints,
    two_bone_ik,
)
from motion_env.skeleton import FEATURE_DIM, FOOT_CONTACT, FPS, NUM_JOINTS
from motion_env.vqvae import VQVAE, VQVAEConfig

if TYPE_CHECKING:
    from motion_env.streaming import MotionStream

__all__ = ["DEFAULT_WEIGHTS", "FootPinner", "MotionGenerator", "SamplingConfig"]

# The shipped model, found relative to the package.
DEFAULT_WEIGHTS = Path(__file__).resolve().parent / "weights"
WEIGHT_FILES = {"vqvae": "vqvae.pt", "gpt": "gpt.pt", "controller": "controller.pt"}
SAMPLING_FILE = "sampling.json"

# An untimed waypoint is snapped to only where the controller's path passes it this close (m): one
# the path has not reached (yet) is left to the controller rather than dragging the path to it.
SNAP_RADIUS = 0.5


@dataclass
class SamplingConfig:
    """How tokens are sampled.

    Attributes:
        temperature: softmax temperature (> 0); 1 samples the model's distribution.
        top_p: nucleus mass in (0, 1], or None for the full distribution.
        guidance: classifier-free guidance scale (1 = off; > 1 follows the caption more at the
            cost of a second GPT row per character).
    """

    temperature: float = 1.0
    top_p: float | None = None
    guidance: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.temperature) and self.temperature > 0):
            raise ValueError(f"SamplingConfig.temperature must be > 0, got {self.temperature!r}")
        if self.top_p is not None and not 0.0 < self.top_p <= 1.0:
            raise ValueError(f"SamplingConfig.top_p must be in (0, 1] or None, got {self.top_p!r}")
        if not (math.isfinite(self.guidance) and self.guidance >= 1.0):
            raise ValueError(f"SamplingConfig.guidance must be >= 1, got {self.guidance!r}")


# --------------------------------------------------------------------------------------------
# Input checks shared by generate, generate_batch and the stream
# --------------------------------------------------------------------------------------------


def _check_text(text: Any, what: str = "text") -> str:
    if not isinstance(text, str):
        raise TypeError(f"{what} must be a string caption, got {type(text).__name__}")
    if not text.strip():
        raise ValueError(f"{what} is empty: give a caption such as 'a person walks forward'")
    return text.strip()


def _check_texts(texts: Sequence[str]) -> list[str]:
    if isinstance(texts, str):
        raise TypeError("texts must be a list of captions, not a single string")
    out = [_check_text(t, f"texts[{i}]") for i, t in enumerate(texts)]
    if not out:
        raise ValueError("texts is empty: give at least one caption")
    return out


def _check_num_frames(num_frames: Any) -> int:
    if isinstance(num_frames, bool) or not float(num_frames).is_integer():
        raise ValueError(f"num_frames must be a whole number of frames, got {num_frames!r}")
    if int(num_frames) < 1:
        raise ValueError(f"num_frames must be >= 1, got {num_frames}")
    return int(num_frames)


def _check_start(start: Any, what: str = "start") -> np.ndarray:
    arr = np.asarray(start, dtype=np.float64)
    if arr.shape != (3,):
        raise ValueError(f"{what} must be (x, z, heading), shape (3,), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{what} must be finite, got {arr.tolist()}")
    return arr.astype(np.float32)


def _check_starts(starts: Any, batch: int) -> np.ndarray:
    if starts is None:
        return np.zeros((batch, 3), np.float32)
    arr = np.asarray(starts, dtype=np.float64)
    if arr.shape != (batch, 3):
        raise ValueError(
            f"starts must have shape ({batch}, 3) (x, z, heading per character), got {arr.shape}"
        )
    if not np.isfinite(arr).all():
        rows = np.unique(np.nonzero(~np.isfinite(arr))[0])
        raise ValueError(f"starts has NaN or infinite values in rows {rows.tolist()}")
    return arr.astype(np.float32)


def _is_route(waypoints: Any) -> bool:
    """True when `waypoints` is one (K, 2)/(K, 3) numeric array (rather than one entry per character)."""
    try:
        arr = np.asarray(waypoints, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return arr.ndim == 2


def _per_row_waypoints(waypoints: Any, batch: int) -> list[np.ndarray | None]:
    """None, one route for every character, or B entries (each None or a route) -> B checked routes."""
    if waypoints is None:
        return [None] * batch
    if _is_route(waypoints):
        route = validate_waypoints(waypoints)
        return [route.copy() for _ in range(batch)]
    if isinstance(waypoints, np.ndarray) and waypoints.ndim != 3:
        raise ValueError(
            f"waypoints must have shape (K, 2) or (K, 3) (or one per character), got {waypoints.shape}"
        )
    if not isinstance(waypoints, Sequence | np.ndarray) or len(waypoints) != batch:
        n = len(waypoints) if isinstance(waypoints, Sequence) else type(waypoints).__name__
        raise ValueError(
            f"waypoints must be None, one (K, 2)/(K, 3) array, or a list of {batch} entries "
            f"(one per character, each None or an array); got {n}"
        )
    out = []
    for i, w in enumerate(waypoints):
        try:
            out.append(None if w is None else validate_waypoints(w))
        except ValueError as exc:
            raise ValueError(f"waypoints of character {i}: {exc}") from exc
    return out


def _resolve_seed(seed: int | None) -> int:
    if seed is None:
        return int(np.random.SeedSequence().generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))
    if isinstance(seed, bool) or int(seed) != seed:
        raise ValueError(f"seed must be an integer or None, got {seed!r}")
    return int(seed)


def _row_generator(seed: int, row: int, stream: int) -> torch.Generator:
    """An independent CPU generator for one character and one purpose (0: controller, 1: tokens)."""
    state = np.random.SeedSequence([seed & 0xFFFFFFFFFFFFFFFF, row, stream]).generate_state(
        2, dtype=np.uint32
    )
    g = torch.Generator(device="cpu")
    g.manual_seed(int(state[0]) << 32 | int(state[1]))
    return g


def _sample_rows(
    logits: torch.Tensor, generators: list[torch.Generator], sampling: SamplingConfig
) -> torch.Tensor:
    """(N, V) logits -> (N,) token ids, row n drawn with generators[n] (multinomial, optional nucleus).

    One uniform number per row and an inverse-CDF lookup: a row's draw depends only on its own
    generator, so a character samples the same tokens alone or in a batch.
    """
    probs = torch.softmax(logits.detach().float().cpu() / sampling.temperature, dim=-1)  # (N, V)
    if sampling.top_p is not None and sampling.top_p < 1.0:
        sorted_p, order = probs.sort(dim=-1, descending=True)
        drop = sorted_p.cumsum(-1) - sorted_p >= sampling.top_p  # always keeps the top token
        probs = torch.zeros_like(probs).scatter_(-1, order, sorted_p.masked_fill(drop, 0.0))
    u = torch.stack([torch.rand((), generator=g) for g in generators])  # (N,)
    cdf = probs.cumsum(-1)
    idx = torch.searchsorted(cdf, (u * cdf[:, -1])[:, None], right=True)[:, 0]
    return idx.clamp(max=probs.shape[1] - 1)


def _rest_pose_features() -> np.ndarray:
    """(263,) features of the canonical skeleton standing in its rest pose (the random model's mean)."""
    from motion_env.motion import bone_offsets, forward_kinematics, joints_to_features

    rots = np.zeros((2, NUM_JOINTS, 4))
    rots[..., 0] = 1.0  # identity quaternions (w, x, y, z)
    height = -float(bone_offsets()[[2, 5, 8], 1].sum())  # hip + knee + ankle drop of the right leg
    joints = forward_kinematics(np.array([[0.0, height, 0.0]] * 2), rots)
    return joints_to_features(joints)[0].astype(np.float32)


def _route_anchors(path: np.ndarray, route: np.ndarray, first: int = 0, open_end: bool = False) -> np.ndarray:
    """The waypoints a root path is snapped to, each timed at the frame where the path should pass it.

    Args:
        path: (T, 3) root path whose frame 0 is episode frame `first`.
        route: (K, 3) waypoints ahead (episode frame times, NaN = untimed), in order.
        first: episode frame of the path's frame 0 (which stays where it is).
        open_end: the path goes on after its last frame (streaming look-ahead): an untimed
            waypoint closest at the last frame is still being approached and is not snapped.

    Returns:
        (M, 3) float32 x, z and the frame (of `path`) of each anchor, frames increasing: timed
        waypoints inside the path; untimed ones at their closest approach (searched after the
        previous anchor) when it is within SNAP_RADIUS. The first untimed waypoint the path
        does not reach ends the list (the ones after it are not reached in order either).
    """
    last = len(path) - 1
    anchors: list[tuple[float, float, float]] = []
    after = 0
    for x, z, t in route:
        if np.isnan(t):
            dist = np.linalg.norm(path[after:, :2] - (x, z), axis=1)
            k = after + int(np.argmin(dist))
            if dist[k - after] > SNAP_RADIUS or (open_end and k == last):
                break
        else:
            k = int(np.rint(t)) - first
            if k > last:
                break
        if k <= 0 or (anchors and k <= anchors[-1][2]):
            continue  # at or before a frame that is already fixed
        anchors.append((float(x), float(z), float(k)))
        after = k
    return np.array(anchors, np.float32).reshape(-1, 3)


def _snap(path: np.ndarray, route: np.ndarray | None) -> np.ndarray:
    """A whole clip's root path bent through the route's anchors (:func:`snap_to_waypoints`)."""
    if route is None:
        return path
    anchors = _route_anchors(path, route)
    return path if len(anchors) == 0 else snap_to_waypoints(path, anchors, keep_start=True)


def _training_record(ckpt: dict[str, Any]) -> dict[str, Any]:
    """What a checkpoint says about its training (a training checkpoint's own keys, or the record
    a packaged one carries), as plain numbers and strings."""
    if isinstance(ckpt.get("training"), dict):
        return ckpt["training"]
    record: dict[str, Any] = {}
    for key in ("step", "metrics", "settings", "vqvae"):
        value = ckpt.get(key)
        if isinstance(value, int | float | str):
            record[key] = value
        elif isinstance(value, dict):
            record[key] = {str(k): v for k, v in value.items() if isinstance(v, int | float | str)}
    return record


# --------------------------------------------------------------------------------------------
# Foot contacts
# --------------------------------------------------------------------------------------------

# Frames over which a released foot's correction fades out.
FOOT_BLEND = 3
# The largest correction (m) a pinned foot gets; a foot the body drags farther (its stride does
# not match the path's speed) slides along with it, so the leg never snaps back from afar.
FOOT_MAX_OFFSET = 0.25


class FootPinner:
    """Causal foot cleanup for B characters, frame by frame (whole clips and streaming alike).

    A foot flagged in contact by the decoder is pinned where it is shown when the contact starts
    (its ankle, or its toe while only the toe touches, as the heel lifts) and the leg is re-solved
    with two-bone IK (:mod:`motion_env.recompose`'s). The pin follows the foot when the body drags
    it more than FOOT_MAX_OFFSET away, and after the contact the correction fades out over
    FOOT_BLEND frames. Unlike :func:`motion_env.recompose.clean_foot_contacts`, which pins a foot to
    the mean of its whole contact run, it never needs future frames, and it keeps every joint
    within FOOT_MAX_OFFSET of the decoded pose: pins the leg cannot reach make no pops.

    Args:
        batch: B characters; the state of each carries over from one :meth:`apply` to the next.
    """

    def __init__(self, batch: int) -> None:
        self.pins = np.full((batch, len(LEGS), 2, 2), np.nan)  # pinned ankle / toe XZ, NaN: free
        self.offset = np.zeros((batch, len(LEGS), 2))  # correction of the last frame
        self.released = np.zeros((batch, len(LEGS), 2))  # correction when the contact ended
        self.since = np.full((batch, len(LEGS)), FOOT_BLEND + 1)  # frames since then

    def reset(self, i: int) -> None:
        """Forget character i's feet (a new episode)."""
        self.pins[i] = np.nan
        self.offset[i] = self.released[i] = 0.0
        self.since[i] = FOOT_BLEND + 1

    def apply(self, i: int, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """Character i's next frames: (n, 22, 3) joints and (n, 4) contact channels -> (n, 22, 3).

        contacts: the decoded features' foot contacts (left ankle, left toe, right ankle, right
        toe; > 0.5 = in contact).
        """
        out = joints.astype(np.float64)
        flags = np.asarray(contacts) > 0.5
        for leg, (hip, knee, ankle, toe) in enumerate(LEGS):
            offsets = np.zeros((len(out), 2))
            for t in range(len(out)):
                # The ankle's flag wins; the toe alone is pinned while the heel lifts.
                kind = 0 if flags[t, 2 * leg] else 1 if flags[t, 2 * leg + 1] else None
                for other in {0, 1} - {kind}:
                    self.pins[i, leg, other] = np.nan
                if kind is None:
                    self.since[i, leg] += 1
                    offset = self.released[i, leg] * max(0.0, 1.0 - self.since[i, leg] / (FOOT_BLEND + 1))
                else:
                    xz = out[t, (ankle, toe)[kind], [0, 2]]
                    if np.isnan(self.pins[i, leg, kind, 0]):
                        self.pins[i, leg, kind] = xz + self.offset[i, leg]  # where it is shown now
                    offset = self.pins[i, leg, kind] - xz
                    norm = np.linalg.norm(offset)
                    if norm > FOOT_MAX_OFFSET:
                        offset *= FOOT_MAX_OFFSET / norm
                        self.pins[i, leg, kind] = xz + offset  # the pin slides with the foot
                    self.released[i, leg], self.since[i, leg] = offset, 0
                self.offset[i, leg] = offsets[t] = offset
            moved = np.nonzero(offsets.any(axis=1))[0]  # frames left alone keep their exact pose
            if not len(moved):
                continue
            goal = out[moved, ankle].copy()
            goal[:, [0, 2]] += offsets[moved]
            toes = out[moved, toe] - out[moved, ankle]
            toes[:, 1] = 0.0  # a knee points the way the foot does
            leg = out[moved, hip], out[moved, knee], out[moved, ankle]
            new_knee, new_ankle = two_bone_ik(*leg, goal, toes)
            out[moved, toe] += new_ankle - out[moved, ankle]
            out[moved, knee], out[moved, ankle] = new_knee, new_ankle
        return out.astype(np.float32)


# --------------------------------------------------------------------------------------------
# The generator
# --------------------------------------------------------------------------------------------


class MotionGenerator:
    """Text- and path-controlled motion: path controller + body GPT + VQ-VAE + recompose.

    Build it with :meth:`from_pretrained` (trained weights) or :meth:`random` (tiny untrained
    models for tests). All randomness comes from ``seed``: the same seed and inputs give the same
    motion, and each character of a batch draws from its own generators.

    Args:
        vqvae, gpt, controller: the three models (moved to `device`, eval mode).
        mean, std: (263,) the training set's feature statistics (features = x * std + mean).
        text_encoder: object with ``encode(list[str]) -> (N, dim)``, ``name`` and ``dim``; default
            (None): loaded lazily by name (``text_encoder_name``) on the first caption.
        text_encoder_name: the encoder the models were trained with ("minilm", ...).
        sampling: token sampling settings.
        untrained: True for random weights: every motion's meta says so.
        device: torch device.
    """

    def __init__(
        self,
        vqvae: VQVAE,
        gpt: TokenGPT,
        controller: PathController,
        mean: np.ndarray,
        std: np.ndarray,
        text_encoder: Any = None,
        text_encoder_name: str = "minilm",
        sampling: SamplingConfig | None = None,
        untrained: bool = False,
        device: str | torch.device = "cpu",
        name: str = "",
    ) -> None:
        mean = np.asarray(mean, dtype=np.float32).reshape(-1)
        std = np.asarray(std, dtype=np.float32).reshape(-1)
        if mean.shape != (FEATURE_DIM,) or std.shape != (FEATURE_DIM,):
            raise ValueError(
                f"mean and std must have shape ({FEATURE_DIM},), got {mean.shape} and {std.shape}"
            )
        if not (np.isfinite(mean).all() and np.isfinite(std).all() and (std > 0).all()):
            raise ValueError("mean must be finite and std finite and > 0")
        if gpt.config.vocab_size != vqvae.config.codebook_size:
            raise ValueError(
                f"the GPT predicts {gpt.config.vocab_size} tokens but the VQ-VAE has "
                f"{vqvae.config.codebook_size} codes: the checkpoints do not belong together"
            )
        if gpt.config.text_dim != controller.config.text_dim:
            raise ValueError(
                f"the GPT takes {gpt.config.text_dim}-d text, the controller {controller.config.text_dim}-d"
            )
        if text_encoder is not None and int(text_encoder.dim) != gpt.config.text_dim:
            raise ValueError(
                f"text encoder {text_encoder.name} is {text_encoder.dim}-d, "
                f"the models need {gpt.config.text_dim}"
            )
        self.device = torch.device(device)
        self.vqvae = vqvae.to(self.device).eval()
        self.gpt = gpt.to(self.device).eval()
        self.controller = controller.to(self.device).eval()
        self.mean, self.std = mean, std
        self.sampling = sampling or SamplingConfig()
        self.untrained = bool(untrained)
        self.name = name
        self.text_encoder_name = text_encoder_name if text_encoder is None else str(text_encoder.name)
        self._text_encoder = text_encoder
        # Per model, how it was trained (step, metrics, settings), carried from checkpoint to checkpoint.
        self.training_info: dict[str, dict[str, Any]] = {}

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_pretrained(
        cls,
        path: str | Path | None = None,
        device: str | torch.device = "cpu",
        text_encoder: Any = None,
        sampling: SamplingConfig | None = None,
    ) -> MotionGenerator:
        """Load a generator from a weights directory.

        Args:
            path: directory with ``vqvae.pt``, ``gpt.pt``, ``controller.pt`` (and optionally
                ``sampling.json``); None = the shipped default model (``motion_env/weights``).
            device: "cpu", "cuda", ...
            text_encoder: an already loaded text encoder (default: loaded by the name the
                checkpoints record, lazily, on the first caption).
            sampling: overrides ``sampling.json``.
        """
        folder = DEFAULT_WEIGHTS if path is None else Path(path)
        if not folder.is_dir():
            raise FileNotFoundError(f"no generator weights directory at {folder}")
        missing = [f for f in WEIGHT_FILES.values() if not (folder / f).is_file()]
        if missing:
            hint = " (the shipped model has not been packaged into this install)" if path is None else ""
            raise FileNotFoundError(f"{folder}: missing {', '.join(missing)}{hint}")
        vq, vq_ckpt = load_checkpoint(folder / WEIGHT_FILES["vqvae"], "vqvae", VQVAEConfig, VQVAE, device)
        gpt, gpt_ckpt = load_checkpoint(folder / WEIGHT_FILES["gpt"], "gpt", GPTConfig, TokenGPT, device)
        ctrl, ctrl_ckpt = load_checkpoint(
            folder / WEIGHT_FILES["controller"], "controller", ControllerConfig, PathController, device
        )
        if "mean" not in vq_ckpt or "std" not in vq_ckpt:
            raise ValueError(
                f"{folder / WEIGHT_FILES['vqvae']}: no dataset 'mean'/'std' stored with the VQ-VAE"
            )
        records = [(c.get("text_encoder") or {}).get("name", "minilm") for c in (gpt_ckpt, ctrl_ckpt)]
        if records[0] != records[1]:
            raise ValueError(
                f"{folder}: the GPT was trained with text encoder {records[0]!r}, "
                f"the controller with {records[1]!r}"
            )
        if text_encoder is not None:
            check_text_encoder(gpt_ckpt, text_encoder, folder / WEIGHT_FILES["gpt"])
            check_text_encoder(ctrl_ckpt, text_encoder, folder / WEIGHT_FILES["controller"])
        if sampling is None and (folder / SAMPLING_FILE).is_file():
            try:
                sampling = SamplingConfig(**json.loads((folder / SAMPLING_FILE).read_text()))
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{folder / SAMPLING_FILE}: {exc}") from exc
        untrained = any(bool(c.get("untrained", False)) for c in (vq_ckpt, gpt_ckpt, ctrl_ckpt))
        gen = cls(
            vq, gpt, ctrl,
            mean=vq_ckpt["mean"].float().numpy(), std=vq_ckpt["std"].float().numpy(),
            text_encoder=text_encoder, text_encoder_name=records[0], sampling=sampling,
            untrained=untrained, device=device, name=str(folder),
        )  # fmt: skip
        for kind, ckpt in (("vqvae", vq_ckpt), ("gpt", gpt_ckpt), ("controller", ctrl_ckpt)):
            gen.training_info[kind] = _training_record(ckpt)
        return gen

    @classmethod
    def random(
        cls,
        seed: int = 0,
        device: str | torch.device = "cpu",
        text_encoder: Any = None,
        rate: int = 4,
    ) -> MotionGenerator:
        """An UNTRAINED generator: tiny models with random weights, for tests only.

        Its motions have the right shapes, frame rate and determinism but no meaning (the body
        is a rest pose plus noise, the path a random drift); ``meta["untrained"]`` says so.
        The text encoder is the real one (loaded lazily), so captions must still be non-empty.
        """
        torch.manual_seed(seed)
        vq = VQVAE(VQVAEConfig(width=32, code_dim=16, codebook_size=32, rate=rate, depth=1))
        # A quantizer that was never trained has an all-zero codebook; give it distinct codes.
        vq.quantizer.codebook.normal_()
        gpt = TokenGPT(GPTConfig(vocab_size=32, block_size=16, n_layer=1, n_head=2, n_embd=32, dropout=0.0))
        ctrl = PathController(ControllerConfig(text_proj=16, hidden=32, mlp=32))
        # The controller starts at "stand still" (zero output layer); let the random one drift.
        torch.nn.init.normal_(ctrl.out[-1].weight, std=0.1)
        torch.nn.init.normal_(ctrl.out[-1].bias, std=0.1)
        mean = _rest_pose_features()
        std = np.full(FEATURE_DIM, 0.02, np.float32)
        return cls(
            vq, gpt, ctrl, mean, std, text_encoder=text_encoder, untrained=True, device=device, name="random"
        )

    def save(self, path: str | Path, half: bool = False) -> Path:
        """Write the generator as a weights directory that :meth:`from_pretrained` reads back.

        Args:
            path: directory (created; existing checkpoint files in it are replaced).
            half: store float weights as float16 (shipping size; loaded back as float32).
        """
        folder = Path(path)
        folder.mkdir(parents=True, exist_ok=True)
        record = {"name": self.text_encoder_name, "dim": int(self.gpt.config.text_dim)}
        extra: dict[str, Any] = {"untrained": True} if self.untrained else {}
        save_checkpoint(
            folder / WEIGHT_FILES["vqvae"], kind="vqvae", config=self.vqvae.config, model=self.vqvae,
            half=half, mean=torch.from_numpy(self.mean.copy()), std=torch.from_numpy(self.std.copy()),
            **extra, **self._training_extra("vqvae"),
        )  # fmt: skip
        save_checkpoint(
            folder / WEIGHT_FILES["gpt"], kind="gpt", config=self.gpt.config, model=self.gpt, half=half,
            text_encoder=record, **extra, **self._training_extra("gpt"),
        )  # fmt: skip
        save_checkpoint(
            folder / WEIGHT_FILES["controller"], kind="controller", config=self.controller.config,
            model=self.controller, half=half, text_encoder=record,
            **extra, **self._training_extra("controller"),
        )  # fmt: skip
        (folder / SAMPLING_FILE).write_text(json.dumps(asdict(self.sampling), indent=2) + "\n")
        return folder

    def _training_extra(self, kind: str) -> dict[str, Any]:
        info = self.training_info.get(kind)
        return {"training": info} if info else {}

    # ------------------------------------------------------------------ properties
    @property
    def rate(self) -> int:
        """Frames per motion token."""
        return int(self.vqvae.rate)

    @property
    def path_horizon(self) -> int:
        """Frames of root path a token needs beyond its first frame (its own span and one second)."""
        return max(self.rate, LOOKAHEAD_FRAMES)

    @property
    def text_encoder(self) -> Any:
        """The text encoder (loaded on first use)."""
        if self._text_encoder is None:
            from motion_env.text import load_text_encoder

            encoder = load_text_encoder(self.text_encoder_name)
            if int(encoder.dim) != self.gpt.config.text_dim:
                raise ValueError(
                    f"text encoder {encoder.name} is {encoder.dim}-d, "
                    f"the models need {self.gpt.config.text_dim}"
                )
            self._text_encoder = encoder
        return self._text_encoder

    def encode_text(self, texts: Sequence[str]) -> torch.Tensor:
        """Captions -> (N, text_dim) float32 embeddings on the generator's device."""
        return torch.as_tensor(self.text_encoder.encode(_check_texts(texts)), dtype=torch.float32).to(
            self.device
        )

    def num_parameters(self) -> dict[str, int]:
        """Parameter count of each model."""
        return {
            name: sum(p.numel() for p in model.parameters())
            for name, model in (("vqvae", self.vqvae), ("gpt", self.gpt), ("controller", self.controller))
        }

    # ------------------------------------------------------------------ building blocks
    def _init_controller(
        self,
        text_emb: torch.Tensor,
        routes: list[np.ndarray | None],
        starts: np.ndarray,
        gens: list[torch.Generator],
    ) -> ControllerState:
        """Controller state at frame 0; the initial GRU state is drawn per character from its generator."""
        state = self.controller.init_state(text_emb, routes, torch.from_numpy(starts))
        noise_std = self.controller.config.h0_noise
        if noise_std > 0:
            hidden = self.controller.config.hidden
            noise = torch.stack([torch.randn(hidden, generator=g) for g in gens]).to(self.device)
            state = replace(state, hidden=state.hidden + noise_std * noise)
        return state

    def _denormalise(self, x: torch.Tensor) -> np.ndarray:
        """(..., 263) normalised decoder output -> float32 features."""
        return x.detach().float().cpu().numpy() * self.std + self.mean

    def _compose(
        self, features: np.ndarray, root_path: np.ndarray, num_frames: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Decoded features (n, 263) on a root path (>= n, 3) -> world joints and the root path used.

        The root path may run past the features (look-ahead frames): they shape the direction of
        travel at the last frames; the local pose is held over them and they are cut off.

        Returns:
            (num_frames, 22, 3) joints before foot cleanup, (num_frames, 3) root path whose heading
            is turned to the direction of travel.
        """
        n = features.shape[0]
        local = local_pose_from_features(features)
        if root_path.shape[0] > n:
            local = np.concatenate([local, np.repeat(local[-1:], root_path.shape[0] - n, axis=0)])
        path = align_heading_to_travel(root_path)
        joints = with_bone_lengths(recompose(local, path, face_travel=False)[:num_frames])
        return joints, path[:num_frames]

    # ------------------------------------------------------------------ whole clips
    @torch.no_grad()
    def generate(
        self,
        text: str,
        waypoints: np.ndarray | Sequence | None = None,
        num_frames: int = 200,
        seed: int | None = None,
        start: np.ndarray | Sequence[float] | None = None,
    ) -> Motion:
        """One motion clip.

        Args:
            text: the caption ("a person jogs", "an elderly person walks slowly").
            waypoints: None (follow the caption) or (K, 2)/(K, 3) world x, z and optionally the
                frame index (20 fps) at which to pass; untimed ones are followed in order.
            num_frames: T, frames to generate (20 fps).
            seed: makes the clip reproducible (None: a fresh random seed, stored in meta).
            start: (x, z, heading) of the first frame; default origin facing +Z.

        Returns:
            Motion with joints (T, 22, 3) float32 world metres, fps 20, the caption, the waypoints
            and meta (seed, model).
        """
        _check_text(text)
        starts = None if start is None else _check_start(start)[None]
        route = None if waypoints is None else [validate_waypoints(waypoints)]
        return self.generate_batch([text], route, num_frames, seed, starts)[0]

    @torch.no_grad()
    def generate_batch(
        self,
        texts: Sequence[str],
        waypoints: Any = None,
        num_frames: int = 200,
        seed: int | None = None,
        starts: np.ndarray | None = None,
    ) -> list[Motion]:
        """B clips at once (one batched pass through each model).

        Args:
            texts: B captions.
            waypoints: None, one (K, 2)/(K, 3) route for every character, or B entries (each None
                or a route).
            num_frames: frames per clip.
            seed: as in :meth:`generate`; character b draws from generators seeded by (seed, b),
                so row 0 equals ``generate(texts[0], ..., seed=seed)``.
            starts: (B, 3) x, z, heading per character.

        Returns:
            B :class:`Motion` clips of `num_frames` frames.
        """
        texts, routes, start_arr, num_frames, seed = self._check_request(
            texts, waypoints, num_frames, seed, starts
        )
        b = len(texts)
        rate = self.rate
        n_tok = math.ceil(num_frames / rate)
        emb = self.encode_text(texts)
        paths = self._paths(emb, routes, start_arr, num_frames, seed)

        feats = torch.from_numpy(np.stack([token_path_features(p, rate)[:n_tok] for p in paths])).to(
            self.device
        )
        token_gens = [_row_generator(seed, i, 1) for i in range(b)]
        cache = self.gpt.new_cache(emb, self.sampling.guidance)
        tokens = torch.zeros(b, n_tok, dtype=torch.long)
        prev = None
        for k in range(n_tok):
            logits, cache = self.gpt.step(cache, prev, feats[:, k])
            tokens[:, k] = _sample_rows(logits, token_gens, self.sampling)
            prev = tokens[:, k].to(self.device)
        body = self._denormalise(self.vqvae.decode(tokens.to(self.device)))  # (B, n_tok * rate, 263)

        motions = []
        for i in range(b):
            joints, _ = self._compose(body[i], paths[i], n_tok * rate)
            joints = FootPinner(1).apply(0, joints, body[i][:, FOOT_CONTACT])[:num_frames]
            motions.append(
                Motion(
                    joints=joints,
                    fps=FPS,
                    text=texts[i],
                    waypoints=None if routes[i] is None else routes[i],
                    meta=self._meta(seed, i),
                )  # fmt: skip
            )
        return motions

    def _check_request(
        self, texts: Sequence[str], waypoints: Any, num_frames: Any, seed: int | None, starts: Any
    ) -> tuple[list[str], list[np.ndarray | None], np.ndarray, int, int]:
        """Validated (texts, per-row routes, (B, 3) starts, num_frames, seed) of a batch request."""
        texts = _check_texts(texts)
        routes = _per_row_waypoints(waypoints, len(texts))
        starts_arr = _check_starts(starts, len(texts))
        return texts, routes, starts_arr, _check_num_frames(num_frames), _resolve_seed(seed)

    def _paths(
        self,
        emb: torch.Tensor,
        routes: list[np.ndarray | None],
        starts: np.ndarray,
        num_frames: int,
        seed: int,
        snap: bool = True,
    ) -> np.ndarray:
        """Root paths (B, n_path, 3) for clips of `num_frames`, bent through the routes if `snap`.

        The path reaches one horizon past the last token's first frame, as in streaming, so the
        last tokens' path features are never cut short.
        """
        n_path = (math.ceil(num_frames / self.rate) - 1) * self.rate + self.path_horizon + 1
        roots = self._rollout(emb, routes, starts, n_path, seed)
        if snap:
            roots = np.stack([_snap(r, w) for r, w in zip(roots, routes, strict=True)])
        return roots

    def _rollout(
        self,
        emb: torch.Tensor,
        routes: list[np.ndarray | None],
        starts: np.ndarray,
        num_frames: int,
        seed: int,
    ) -> np.ndarray:
        """The controller's closed-loop root paths: (B, num_frames, 3) float32, frame 0 = start."""
        gens = [_row_generator(seed, i, 0) for i in range(len(routes))]
        state = self._init_controller(emb, routes, starts, gens)
        roots, _ = self.controller(state, num_frames - 1)
        return roots.cpu().numpy().astype(np.float32)

    @torch.no_grad()
    def root_paths(
        self,
        texts: Sequence[str],
        waypoints: Any = None,
        num_frames: int = 200,
        seed: int | None = None,
        starts: np.ndarray | None = None,
        snap: bool = True,
    ) -> np.ndarray:
        """The root paths that :meth:`generate_batch` puts the bodies on (same arguments, same seed).

        Args:
            snap: bend them through the waypoints (as the clips are); False gives the path
                controller's own rollout, which tells how well the controller alone follows a route.

        Returns:
            (B, num_frames, 3) float32 x, z, heading (before the heading is turned to the
            direction of travel).
        """
        texts, routes, start_arr, num_frames, seed = self._check_request(
            texts, waypoints, num_frames, seed, starts
        )
        return self._paths(self.encode_text(texts), routes, start_arr, num_frames, seed, snap)[:, :num_frames]

    def _meta(self, seed: int, row: int) -> dict[str, str]:
        meta = {
            "generator": "motion_env.MotionGenerator",
            "model": self.name,
            "seed": str(seed),
            "row": str(row),
        }
        if self.untrained:
            meta["untrained"] = "true (random weights, for tests only)"
        return meta

    # ------------------------------------------------------------------ streaming
    def stream(
        self,
        texts: Sequence[str],
        waypoints: Any = None,
        starts: np.ndarray | None = None,
        seed: int | None = None,
    ) -> MotionStream:
        """A batch of characters generated frame by frame (see :class:`MotionStream`).

        Args:
            texts: B captions.
            waypoints: None, one route for everyone, or B entries (each None or a route); times are
                frame indices of each character's episode.
            starts: (B, 3) x, z, heading.
            seed: as in :meth:`generate_batch`.
        """
        from motion_env.streaming import MotionStream

        return MotionStream(self, texts, waypoints, starts, seed)
