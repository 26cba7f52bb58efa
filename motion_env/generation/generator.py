"""MotionGenerator: caption + waypoints -> motion, as whole clips or streamed frame by frame.

The whole-clip driver of :mod:`motion_env.generation.pipeline`: it checks a request once
(:mod:`motion_env.generation.request`) and runs every stage over the whole clip; :meth:`stream`
hands the same pipeline to :class:`~motion_env.generation.streaming.MotionStream`, which runs the
stages one token at a time. It also loads and saves the weights.

Weights: a directory holding ``vqvae.pt`` (with the dataset Mean/Std), ``gpt.pt`` and
``controller.pt`` (:mod:`motion_env.models.checkpoint` files) and optionally ``sampling.json``,
``caption_adapter.pt`` (:mod:`motion_env.models.caption_adapter`), ``pace.pt``
(:mod:`motion_env.models.pace`) and ``lookahead.pt`` (:mod:`motion_env.models.lookahead`); the
shipped default is ``motion_env/weights/`` inside the package.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from motion_env.generation.caption_readers import ADAPTER_FILE, load_caption_reader
from motion_env.generation.pipeline import Pipeline
from motion_env.generation.refine import RefineConfig
from motion_env.generation.request import (
    BatchRequest,
    check_batch_request,
    check_request,
    check_text,
    check_texts,
)
from motion_env.models.caption_adapter import CaptionAdapter
from motion_env.models.checkpoint import check_text_encoder, load_checkpoint, save_checkpoint, training_record
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.gpt import GPTConfig, TokenGPT
from motion_env.models.lookahead import LOOKAHEAD_FILE, controller_fingerprint, load_lookahead
from motion_env.models.normalizer import Normalizer
from motion_env.models.pace import PACE_FILE, load_pace
from motion_env.models.sampling import SAMPLING_FILE, SamplingConfig, load_sampling
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.motion.features import rest_pose_features
from motion_env.motion.skeleton import FEATURE_DIM, FPS
from motion_env.motion.types import Motion
from motion_env.text.vocabulary import load_vocabulary

if TYPE_CHECKING:
    from motion_env.generation.streaming import MotionStream

__all__ = ["DEFAULT_WEIGHTS", "RANDOM_MODEL", "MotionGenerator", "SamplingConfig"]

# The shipped model, found relative to the package.
DEFAULT_WEIGHTS = Path(__file__).resolve().parents[1] / "weights"
WEIGHT_FILES = {"vqvae": "vqvae.pt", "gpt": "gpt.pt", "controller": "controller.pt"}
# What `gen.<name>` reads from the pipeline (see MotionGenerator.__getattr__).
PIPELINE_PARTS = frozenset(
    {"vqvae", "gpt", "controller", "device", "rate", "path_horizon", "text_encoder", "text_encoder_name"}
)
# `from_pretrained(RANDOM_MODEL)` gives the untrained test model (:meth:`MotionGenerator.random`).
RANDOM_MODEL = "random"


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
        name: where the weights came from (recorded in every motion's meta).

    Attributes:
        pipeline: the :class:`~motion_env.generation.pipeline.Pipeline` that does the work; its parts
            read through the generator too (``gen.vqvae``, ``gen.gpt``, ``gen.controller``,
            ``gen.device``, ``gen.rate``, ``gen.path_horizon``, ``gen.text_encoder``).
        sampling: token sampling settings (assignable); mean, std: the feature statistics.
        refine_config: :class:`~motion_env.generation.refine.RefineConfig`, the test-time
            refinement of clips with joint targets or objectives (assignable).
        untrained, name, training_info: what the weights are and how they were trained.
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
        caption_adapter: CaptionAdapter | None = None,
    ) -> None:
        self.pipeline = Pipeline(
            vqvae, gpt, controller, Normalizer(mean, std), sampling or SamplingConfig(),
            text_encoder=text_encoder, text_encoder_name=text_encoder_name, device=device,
            caption_adapter=caption_adapter,
        )  # fmt: skip
        self.untrained = bool(untrained)
        self.name = name
        # Per model, how it was trained (step, metrics, settings), carried from checkpoint to checkpoint.
        self.training_info: dict[str, dict[str, Any]] = {}
        # The test-time refinement of clips with joint targets or objectives (assignable).
        self.refine_config = RefineConfig()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_pretrained(
        cls,
        path: str | Path | None = None,
        device: str | torch.device = "cpu",
        text_encoder: Any = None,
        sampling: SamplingConfig | None = None,
        caption_reader: str | None = None,
    ) -> MotionGenerator:
        """Load a generator from a weights directory.

        Args:
            path: directory with ``vqvae.pt``, ``gpt.pt``, ``controller.pt`` (and optionally
                ``sampling.json``, caption adapters and ``pace.pt``, the pace regressor of
                :mod:`motion_env.models.pace`); None = the shipped default model
                (``motion_env/weights``); ``"random"`` = the untrained test model of
                :meth:`random` (seed 0).
            device: "cpu", "cuda", ...
            text_encoder: an already loaded text encoder (default: loaded by the name the
                checkpoints (or the caption adapter) record, lazily, on the first caption).
            sampling: overrides ``sampling.json``.
            caption_reader: which caption reader (a text encoder and the caption adapter trained
                for it) reads the captions (:func:`motion_env.generation.caption_readers.caption_readers`):
                None = ``caption_adapter.pt`` when the folder has one; ``"none"`` = no adapter
                (the models read the encoder's embedding as they were trained); another name =
                ``caption_adapter.<name>.pt`` (``"mpnet"``: the optional all-mpnet-base-v2 reader).
        """
        if path is not None and str(path) == RANDOM_MODEL:
            return cls.random(device=device, text_encoder=text_encoder)
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
        normalizer = Normalizer.from_checkpoint(vq_ckpt, folder / WEIGHT_FILES["vqvae"])
        records = [(c.get("text_encoder") or {}).get("name", "minilm") for c in (gpt_ckpt, ctrl_ckpt)]
        if records[0] != records[1]:
            raise ValueError(
                f"{folder}: the GPT was trained with text encoder {records[0]!r}, "
                f"the controller with {records[1]!r}"
            )
        adapter, adapter_ckpt = load_caption_reader(folder, caption_reader, records[0], text_encoder, device)
        if text_encoder is not None and adapter is None:
            check_text_encoder(gpt_ckpt, text_encoder, folder / WEIGHT_FILES["gpt"])
            check_text_encoder(ctrl_ckpt, text_encoder, folder / WEIGHT_FILES["controller"])
        sampling = load_sampling(folder) if sampling is None else sampling
        untrained = any(bool(c.get("untrained", False)) for c in (vq_ckpt, gpt_ckpt, ctrl_ckpt))
        gen = cls(
            vq, gpt, ctrl, mean=normalizer.mean, std=normalizer.std,
            text_encoder=text_encoder, text_encoder_name=records[0], sampling=sampling,
            untrained=untrained, device=device, name=str(folder), caption_adapter=adapter,
        )  # fmt: skip
        gen.pipeline.vocabulary = load_vocabulary(folder)
        # Optional: untimed routes at the caption's pace, the stream's look-ahead in one pass.
        gen.pipeline.pace, pace_ckpt = load_pace(folder, records[0], ctrl.config.text_dim, device)
        gen.pipeline.lookahead, head_ckpt = load_lookahead(folder, ctrl, device)
        checkpoints = {
            "vqvae": vq_ckpt, "gpt": gpt_ckpt, "controller": ctrl_ckpt,
            "caption_adapter": adapter_ckpt, "pace": pace_ckpt, "lookahead": head_ckpt,
        }  # fmt: skip
        gen.training_info.update({k: training_record(c) for k, c in checkpoints.items() if c is not None})
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
        ctrl = PathController.drifting(ControllerConfig(text_proj=16, hidden=32, mlp=32), std=0.1)
        mean = rest_pose_features()
        std = np.full(FEATURE_DIM, 0.02, np.float32)
        return cls(
            vq, gpt, ctrl, mean, std, text_encoder=text_encoder, untrained=True, device=device, name="random"
        )

    def save(self, path: str | Path, half: bool = False) -> Path:
        """Write the generator as a weights directory that :meth:`from_pretrained` reads back.

        The caption adapter in use (if any) is written as ``caption_adapter.pt``, the folder's
        default reader; other readers of the folder it came from are not copied.

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
            half=half, **self.pipeline.normalizer.checkpoint_entries(),
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
        # The optional models; a stale file of one not in use would read these models wrongly.
        # The pace regressor is 6 kB: it stays float32.
        optional = (
            (ADAPTER_FILE, "caption_adapter", self.pipeline.caption_adapter, half, {}),
            (PACE_FILE, "pace", self.pipeline.pace, False, {}),
            (LOOKAHEAD_FILE, "lookahead", self.pipeline.lookahead, half,
             {"controller_fingerprint": controller_fingerprint(self.controller)}),
        )  # fmt: skip
        for file, kind, model, halved, entries in optional:
            if model is None:
                (folder / file).unlink(missing_ok=True)
                continue
            save_checkpoint(
                folder / file, kind=kind, config=model.config, model=model, half=halved,
                text_encoder=record, **entries, **self._training_extra(kind),
            )  # fmt: skip
        (folder / SAMPLING_FILE).write_text(json.dumps(asdict(self.sampling), indent=2) + "\n")
        if self.pipeline.vocabulary is not None:  # what the model knows travels with it
            self.pipeline.vocabulary.save(folder)
        return folder

    def _training_extra(self, kind: str) -> dict[str, Any]:
        info = self.training_info.get(kind)
        return {"training": info} if info else {}

    # ------------------------------------------------------------------ the pipeline's parts
    def __getattr__(self, name: str) -> Any:
        # Read-only views of the pipeline's parts: gen.vqvae, gen.gpt, gen.controller, gen.device,
        # gen.rate (frames per token), gen.path_horizon, gen.text_encoder, gen.text_encoder_name.
        if name in PIPELINE_PARTS:
            return getattr(self.pipeline, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def mean(self) -> np.ndarray:
        """(263,) the training set's feature mean."""
        return self.pipeline.normalizer.mean

    @property
    def std(self) -> np.ndarray:
        """(263,) the training set's feature std."""
        return self.pipeline.normalizer.std

    @property
    def caption_adapter(self) -> CaptionAdapter | None:
        """The caption adapter between the text encoder and the models (assignable; None: the
        encoder's embeddings go to the models as they are)."""
        return self.pipeline.caption_adapter

    @caption_adapter.setter
    def caption_adapter(self, adapter: CaptionAdapter | None) -> None:
        self.pipeline.caption_adapter = adapter

    @property
    def physics(self) -> bool:
        """Whether stage 6 makes flight and contact consistent (:mod:`motion_env.generation.physics`;
        assignable, on by default). Streams take the setting of the moment they start."""
        return self.pipeline.physics

    @physics.setter
    def physics(self, value: bool) -> None:
        if not isinstance(value, bool):
            raise TypeError(f"physics must be True or False, got {value!r}")
        self.pipeline.physics = value

    @property
    def sampling(self) -> SamplingConfig:
        """Token sampling settings (assignable)."""
        return self.pipeline.sampling

    @sampling.setter
    def sampling(self, value: SamplingConfig) -> None:
        if not isinstance(value, SamplingConfig):
            raise TypeError(f"sampling must be a SamplingConfig, got {type(value).__name__}")
        self.pipeline.sampling = value

    def encode_text(self, texts: Sequence[str]) -> torch.Tensor:
        """Captions -> (N, text_dim) float32 embeddings on the generator's device."""
        return self.pipeline.encode_text(check_texts(texts))

    def caption_warning(self, text: str) -> str:
        """The warning `text` gets ('' for none): not English, too long, or far from every caption
        the model was trained on (:mod:`motion_env.text.vocabulary`). A caption not generated from
        yet is embedded first, which warns as generating from it would; then the answer is cached."""
        return self.pipeline.caption_warning(check_text(text))

    def num_parameters(self) -> dict[str, int]:
        """Parameter count of each model."""
        return {
            name: sum(p.numel() for p in model.parameters())
            for name, model in (("vqvae", self.vqvae), ("gpt", self.gpt), ("controller", self.controller))
        }

    # ------------------------------------------------------------------ whole clips
    @torch.no_grad()
    def generate(
        self,
        text: str,
        waypoints: np.ndarray | Sequence | None = None,
        num_frames: int = 200,
        seed: int | None = None,
        start: np.ndarray | Sequence[float] | None = None,
        infeasible: str = "raise",
        joint_targets: np.ndarray | None = None,
        objectives: Sequence[Any] | None = None,
    ) -> Motion:
        """One motion clip.

        Args:
            text: the caption ("a person jogs", "an elderly person walks slowly").
            waypoints: None (follow the caption) or (K, 2)/(K, 3) world x, z and optionally the
                frame index (20 fps) at which to pass; untimed ones are followed in order.
            num_frames: T, frames to generate (20 fps), 1 to ``MAX_FRAMES``.
            seed: makes the clip reproducible (None: a fresh random seed, stored in meta).
            start: (x, z, heading) of the first frame; default origin facing +Z.
            infeasible: timed waypoints that ask for more than ``MAX_SPEED`` raise a ValueError
                ("raise"), or are retimed to the fastest feasible frame with a warning ("warn").
            joint_targets: None, or (T, 22, 3) world positions (metres) that joints must reach,
                NaN where a joint is free: any joints, any frames (one keyframe to every frame).
                Without `waypoints` the path controller walks to where the targets are.
            objectives: None, or a list of :mod:`motion_env.objectives` (``KeepOut``,
                ``HeightLimit``, ``StayInside``) and callables ``f(joints) -> scalar`` (joints: a
                differentiable ``torch.Tensor`` (T, 22, 3)) that the refinement lowers.

        With targets or objectives the clip goes through the test-time refinement
        (:mod:`motion_env.generation.refine`, settings in ``gen.refine_config``); targets it
        cannot meet within 2 cm (out of the body's reach) and objectives that still fail are
        named in a UserWarning, with the distance, and ``meta["control"]`` sums up the errors.

        Returns:
            Motion with joints (T, 22, 3) float32 world metres, fps 20, the caption, the waypoints
            and meta (seed, model).
        """
        req = check_request(text, waypoints, num_frames, seed, start, infeasible, joint_targets, objectives)
        return self._clips(req)[0]

    @torch.no_grad()
    def generate_batch(
        self,
        texts: Sequence[str],
        waypoints: Any = None,
        num_frames: int = 200,
        seed: int | None = None,
        starts: np.ndarray | None = None,
        infeasible: str = "raise",
        joint_targets: Any = None,
        objectives: Any = None,
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
            infeasible: as in :meth:`generate`.
            joint_targets: None, one (T, 22, 3) array for every character, or B entries (each None
                or an array); as in :meth:`generate`.
            objectives: None, one list for every character, or B lists (each None or a list).

        Returns:
            B :class:`Motion` clips of `num_frames` frames.
        """
        req = check_batch_request(
            texts, waypoints, num_frames, seed, starts, infeasible, joint_targets, objectives
        )
        return self._clips(req)

    def _clips(self, req: BatchRequest) -> list[Motion]:
        """The pipeline's stages over whole clips (:meth:`Pipeline.clips`), as Motions."""
        motions = []
        for i, clip in enumerate(self.pipeline.clips(req, self.refine_config)):
            meta = self._meta(req.seed, i)
            if clip.report is not None:
                meta["control"] = clip.report.summary()
                if clip.report.message:
                    who = "" if len(req.texts) == 1 else f"character {i}: "
                    warnings.warn(f"{who}{clip.report.message}", UserWarning, stacklevel=3)
            motions.append(
                Motion(joints=clip.joints, fps=FPS, text=req.texts[i], waypoints=req.routes[i], meta=meta)
            )
        return motions

    @torch.no_grad()
    def root_paths(
        self,
        texts: Sequence[str],
        waypoints: Any = None,
        num_frames: int = 200,
        seed: int | None = None,
        starts: np.ndarray | None = None,
        snap: bool = True,
        infeasible: str = "raise",
    ) -> np.ndarray:
        """The root paths that :meth:`generate_batch` puts the bodies on (same arguments, same seed).

        Args:
            snap: bend them through the waypoints (as the clips are); False gives the path
                controller's own rollout, which tells how well the controller alone follows a route.

        Returns:
            (B, num_frames, 3) float32 x, z, heading (before the heading is turned to the
            direction of travel).
        """
        req = check_batch_request(texts, waypoints, num_frames, seed, starts, infeasible)
        emb = self.pipeline.encode_text(req.texts)
        if snap:
            _, paths = self.pipeline.plan_paths(emb, req)
        else:
            paths = self.pipeline.clip_paths(emb, req, snap=False)
        return paths[:, : req.num_frames]

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
        infeasible: str = "raise",
    ) -> MotionStream:
        """A batch of characters generated frame by frame (see :class:`MotionStream`).

        Args:
            texts: B captions.
            waypoints: None, one route for everyone, or B entries (each None or a route); times are
                frame indices of each character's episode.
            starts: (B, 3) x, z, heading.
            seed: as in :meth:`generate_batch`.
            infeasible: as in :meth:`generate`, for these routes and those given later.
        """
        from motion_env.generation.streaming import MotionStream

        return MotionStream(self.pipeline, texts, waypoints, starts, seed, infeasible)
