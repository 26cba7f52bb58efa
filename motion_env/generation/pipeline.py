"""The generation pipeline: one object holds the models and runs the stages (C-T2M's decoupled design).

The stages, in order (:meth:`Pipeline.clips` runs them over whole clips, and is the one place
that writes the order out; :class:`~motion_env.generation.streaming.MotionStream` runs the same
stage methods causally, one token at a time, in the same order):

1. **text** (:meth:`Pipeline.encode_text`): the caption becomes an embedding (encoder loaded
   lazily); a caption that is not English, too long or far from what the models know gets a
   warning, once (:func:`motion_env.text.vocabulary.caption_warning`); the caption reader's
   adapter (:mod:`motion_env.models.caption_adapter`) moves a wording the models never saw to
   where they answer with the action and style it names;
2. **path** (:meth:`Pipeline.plan_paths`): the route is planned
   (:mod:`motion_env.generation.route_planning`; untimed waypoints are timed at the caption's
   pace, :mod:`motion_env.models.pace`, for the controller only), the path controller
   (:mod:`motion_env.models.controller`) rolls out x, z, heading frame by frame, closed loop, from
   the caption and the waypoints (towards the joint targets when there is no route), and the path
   is bent exactly through the waypoints (:mod:`motion_env.generation.recompose`);
3. **tokens** (:meth:`Pipeline.sample_tokens`): per-token path features
   (:mod:`motion_env.models.path_features`) and the caption condition the body GPT, which samples
   motion tokens one by one (:mod:`motion_env.models.sampling`);
4. **decode** (:meth:`Pipeline.decode`, :meth:`Pipeline.decode_next` for the stream): the VQ-VAE
   decodes tokens to features (its :class:`~motion_env.models.normalizer.Normalizer` undoes the
   normalisation);
5. **compose** (:meth:`Pipeline.compose`): the decoded body, relative to its root, is placed on
   the root path and rebuilt on the skeleton's bone lengths (decoded legs come out up to 9 cm
   short), its wrists where the decoder put them (:func:`~motion_env.generation.recompose.on_bone_lengths`),
   and with one pelvis shape for the whole clip (:func:`~motion_env.motion.kinematics.hold_pelvis_shape`);
   the pelvis keeps its decoded height, and the feet go where the legs put them (6 puts them on
   the floor);
6. **feet and physics** (:meth:`Pipeline.balance`, :class:`~motion_env.generation.feet.FootPinner`,
   :mod:`motion_env.generation.physics`): whole clips' root paths are shifted a few centimetres so
   that the floor's push passes through the centre of mass (:mod:`motion_env.generation.balance`;
   the start and the waypoints stay put; the stream's token by token, from the frames it has);
   feet the decoder marks as planted, and a run's toes on the floor
   (:mod:`motion_env.generation.contacts`), are pinned; then, with
   ``Pipeline.physics`` (on by default), the body's height is planned so that its centre of mass
   falls with gravity in flight and takes off and lands within what legs can push, planted feet
   stand on the floor and no joint goes below it (:meth:`Pipeline.place_clip` runs 5 and 6);
7. **refine** (:func:`motion_env.generation.refine.refine_clip`, only for clips with joint targets
   or objectives): test-time optimisation of the body, then the closed-form finish
   (:mod:`motion_env.generation.closed_form`); it re-runs 5 and 6 around its corrections.
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch

from motion_env.generation.balance import balance_shift
from motion_env.generation.contacts import with_run_toes
from motion_env.generation.feet import FootPinner
from motion_env.generation.physics import apply_physics
from motion_env.generation.recompose import (
    align_heading_to_travel,
    local_pose_from_features,
    on_bone_lengths,
    recompose,
    smooth_path,
    snap_route,
    waypoint_frames,
)
from motion_env.generation.refine import RefineConfig, Refined, refine_clip
from motion_env.generation.request import BatchRequest
from motion_env.generation.root_bending import implied_route
from motion_env.generation.route_planning import needs_pace, pace_route, plan_route, turn_round, walks_forward
from motion_env.models.caption_adapter import UNLABELLED, CaptionAdapter
from motion_env.models.controller import ControllerState, PathController
from motion_env.models.gpt import TokenGPT
from motion_env.models.lookahead import LookaheadHead
from motion_env.models.normalizer import Normalizer
from motion_env.models.pace import PaceRegressor
from motion_env.models.path_features import LOOKAHEAD_FRAMES, token_path_features
from motion_env.models.sampling import SamplingConfig
from motion_env.models.vqvae import VQVAE, DecoderStream
from motion_env.motion.kinematics import hold_pelvis_shape, pelvis_shape
from motion_env.motion.skeleton import FOOT_CONTACT
from motion_env.text.vocabulary import Vocabulary, caption_warning, reading_text

__all__ = ["CONTROLLER_STREAM", "TOKEN_STREAM", "Clip", "Pipeline", "row_generator"]

# Frames (Gaussian sigma) the controller's root path of a whole clip is smoothed over before it
# is bent through the waypoints: the controller brakes and surges for a few frames where it
# passes a timed waypoint (up to 2 m/s in 3 frames on runs), a horizontal acceleration the
# MuJoCo replay's root force rejects; 2 frames take the stutter out and keep the pace.
PATH_SMOOTHING = 2.0
# The random streams of one character (see row_generator).
CONTROLLER_STREAM, TOKEN_STREAM = 0, 1


def row_generator(seed: int, row: int, stream: int) -> torch.Generator:
    """An independent CPU generator for one character (`row`) and one purpose (`stream`).

    Every character of a batch draws from its own generators, so a character generates the same
    motion alone or in a batch, and the controller's draws never shift the token draws.
    """
    state = np.random.SeedSequence([seed & 0xFFFFFFFFFFFFFFFF, row, stream]).generate_state(
        2, dtype=np.uint32
    )
    g = torch.Generator(device="cpu")
    g.manual_seed(int(state[0]) << 32 | int(state[1]))
    return g


@dataclass
class Clip:
    """One whole clip out of :meth:`Pipeline.clips`.

    Attributes:
        joints: (T, 22, 3) float32 world joints.
        report: how the refinement met the clip's joint targets and objectives (None: it had none).
    """

    joints: np.ndarray
    report: Refined | None = None


class Pipeline:
    """The models and the stages that turn a checked request into motion.

    Args:
        vqvae, gpt, controller: the three models (moved to `device`, eval mode).
        normalizer: the training set's feature statistics (the VQ-VAE's).
        sampling: token sampling settings.
        text_encoder: object with ``encode(list[str]) -> (N, dim)``, ``name`` and ``dim``; default
            (None): loaded lazily by name (``text_encoder_name``) on the first caption.
        text_encoder_name: the encoder the models were trained with ("minilm+sides", ...).
        device: torch device.
        caption_adapter: the caption adapter between the encoder and the models, or None (the
            encoder's embedding goes to the models as it is); it may read another encoder, which
            is then the one loaded.

    Attributes:
        pace: the pace regressor (:class:`~motion_env.models.pace.PaceRegressor`, ``pace.pt``)
            that times untimed routes at the caption's pace for the controller, or None (the
            controller's own pace; assignable).
        vocabulary: what the models know about captions (the weights folder's
            :class:`~motion_env.text.vocabulary.Vocabulary`), or None: then captions are only
            checked for language and length, not for their distance to known wordings.
    """

    def __init__(
        self,
        vqvae: VQVAE,
        gpt: TokenGPT,
        controller: PathController,
        normalizer: Normalizer,
        sampling: SamplingConfig,
        text_encoder: Any = None,
        text_encoder_name: str = "minilm",
        device: str | torch.device = "cpu",
        caption_adapter: CaptionAdapter | None = None,
    ) -> None:
        if gpt.config.vocab_size != vqvae.config.codebook_size:
            raise ValueError(
                f"the GPT predicts {gpt.config.vocab_size} tokens but the VQ-VAE has "
                f"{vqvae.config.codebook_size} codes: the checkpoints do not belong together"
            )
        if gpt.config.text_dim != controller.config.text_dim:
            raise ValueError(
                f"the GPT takes {gpt.config.text_dim}-d text, the controller {controller.config.text_dim}-d"
            )
        self.device = torch.device(device)
        self.vqvae = vqvae.to(self.device).eval()
        self.gpt = gpt.to(self.device).eval()
        self.controller = controller.to(self.device).eval()
        self._caption_adapter = None if caption_adapter is None else self._checked_adapter(caption_adapter)
        if text_encoder is not None:
            self._check_encoder(text_encoder)
        self.normalizer = normalizer
        self.sampling = sampling
        self.text_encoder_name = text_encoder_name
        if text_encoder is not None and caption_adapter is None:
            self.text_encoder_name = str(text_encoder.name)
        self._text_encoder = text_encoder
        self.vocabulary: Vocabulary | None = None
        # Stage 6's physics (generation.physics): on by default; False skips it (faster, as the
        # models decode, for comparisons or learners that want every frame they can get).
        self.physics = True
        self._caption_warnings: dict[str, str] = {}  # caption -> its warning ('' none), made once
        self._walks: dict[str, bool] = {}  # caption -> whether it reads as a forward walk (turn_round)
        # Stage 2's pace regressor (models.pace): untimed routes are followed at the caption's pace
        # (generation.route_planning.pace_route); None: at the controller's own.
        self.pace: PaceRegressor | None = None
        # The stream's look-ahead head (models.lookahead): after a change it predicts the second
        # ahead instead of rolling the controller out again; None: the stream rolls it out.
        self.lookahead: LookaheadHead | None = None

    # ------------------------------------------------------------------ sizes
    @property
    def rate(self) -> int:
        """Frames per motion token."""
        return int(self.vqvae.rate)

    @property
    def path_horizon(self) -> int:
        """Frames of root path a token needs beyond its first frame (its own span and one second)."""
        return max(self.rate, LOOKAHEAD_FRAMES)

    # ------------------------------------------------------------------ the stages, in order
    def clips(self, req: BatchRequest, refine: RefineConfig) -> list[Clip]:
        """Whole clips of a checked request: every stage, in order, once over the whole clip."""
        n_tok = math.ceil(req.num_frames / self.rate)
        controlled = [False] * len(req.texts)
        if req.joint_targets is not None:
            controlled = [t is not None or bool(o) for t, o in zip(req.joint_targets, req.objectives)]
        emb = self.encode_text(req.texts)  # 1. text
        routes, paths = self.plan_paths(emb, req)  # 2. path
        logits: list[torch.Tensor] | None = [] if refine.space == "logits" and any(controlled) else None
        tokens = self.sample_tokens(emb, paths, n_tok, req.seed, logits)  # 3. tokens
        body = self.decode(tokens)  # 4. decode
        out = []
        for i in range(len(req.texts)):
            if not controlled[i]:
                path = self.balance(body[i], paths[i], routes[i], n_tok * self.rate)  # 6. balance
                _, joints = self.place_clip(body[i], path, n_tok * self.rate)  # 5. compose, 6. feet
                out.append(Clip(joints[: req.num_frames]))
                continue
            targets = req.joint_targets[i]
            refined = refine_clip(  # 7. refine (5 and 6 run again around its corrections)
                self, refine, body[i], tokens[i],
                None if logits is None else torch.stack([step[i] for step in logits]),
                paths[i], routes[i],
                np.full((req.num_frames, 22, 3), np.nan, np.float32) if targets is None
                else targets.dense(req.num_frames),
                list(req.objectives[i]),
            )  # fmt: skip
            out.append(Clip(refined.joints, refined))
        return out

    # ------------------------------------------------------------------ 1. text
    @property
    def caption_adapter(self) -> CaptionAdapter | None:
        """The caption adapter between the text encoder and the models (assignable; None: none)."""
        return self._caption_adapter

    @caption_adapter.setter
    def caption_adapter(self, adapter: CaptionAdapter | None) -> None:
        before = self.reader_name
        self._caption_adapter = None if adapter is None else self._checked_adapter(adapter)
        self._caption_warnings.clear()  # they name what the adapter reads
        self._walks.clear()
        if self.reader_name != before:
            self._text_encoder = None  # the other encoder loads on the next caption

    def _checked_adapter(self, adapter: CaptionAdapter) -> CaptionAdapter:
        if not isinstance(adapter, CaptionAdapter):
            raise TypeError(f"caption_adapter must be a CaptionAdapter or None, got {type(adapter).__name__}")
        if adapter.config.out_dim != self.gpt.config.text_dim:
            raise ValueError(
                f"the caption adapter puts out {adapter.config.out_dim}-d embeddings, "
                f"the models read {self.gpt.config.text_dim}-d"
            )
        return adapter.to(self.device).eval()

    @property
    def reader_name(self) -> str:
        """The text encoder the pipeline reads captions with: the adapter's, else the models'."""
        return self.text_encoder_name if self.caption_adapter is None else self.caption_adapter.config.encoder

    def _check_encoder(self, encoder: Any) -> None:
        need = (
            self.gpt.config.text_dim if self.caption_adapter is None else self.caption_adapter.config.in_dim
        )
        if int(encoder.dim) != need:
            raise ValueError(f"text encoder {encoder.name} is {encoder.dim}-d, the pipeline needs {need}")

    @property
    def text_encoder(self) -> Any:
        """The text encoder (loaded on first use)."""
        if self._text_encoder is None:
            from motion_env.text.encoders import load_text_encoder

            encoder = load_text_encoder(self.reader_name)
            self._check_encoder(encoder)
            self._text_encoder = encoder
        return self._text_encoder

    def encode_text(self, texts: Sequence[str]) -> torch.Tensor:
        """Checked captions -> (N, text_dim) float32 embeddings on the pipeline's device.

        A caption seen for the first time is checked (:meth:`caption_warning`); a problem is a
        ``UserWarning``, once per caption, however often the stream or the environments ask again.
        The caption adapter, when there is one, then moves the encoder's embeddings.
        """
        emb = torch.as_tensor(self.text_encoder.encode(list(texts)), dtype=torch.float32)
        for text, row in zip(texts, emb, strict=True):
            if text not in self._caption_warnings:
                self._caption_warnings[text] = message = self._check_caption(text, row.numpy())
                if message:
                    warnings.warn(message, UserWarning, stacklevel=3)
            if text not in self._walks:
                self._walks[text] = self._walking(row)
        emb = emb.to(self.device)
        if self.caption_adapter is not None:
            with torch.no_grad():
                emb = self.caption_adapter(emb)
        return emb

    def _check_caption(self, text: str, embedding: np.ndarray) -> str:
        vocab = self.vocabulary
        # The stored wordings are embedded by the base of the encoder read ("minilm" of
        # "minilm+sides", whose first half is that embedding); any other encoder: text checks only.
        # What the adapter reads is worked out only for a caption that warns.
        reading = None if self.caption_adapter is None else functools.partial(self._reading, embedding)
        if vocab is None or str(self.text_encoder.name).split("+")[0] != vocab.encoder:
            return caption_warning(text, reading=reading)
        return caption_warning(text, embedding, vocab, reading=reading)

    def _walking(self, embedding: torch.Tensor) -> bool:
        """Whether the caption adapter reads a caption's encoder `embedding` as a forward walk
        (:func:`~motion_env.generation.route_planning.walks_forward`); False without an adapter."""
        adapter = self.caption_adapter
        if adapter is None:
            return False
        with torch.no_grad():
            logits, _ = adapter.labels(embedding[None].to(self.device))
        return walks_forward(logits[0].softmax(-1).cpu().numpy(), adapter.config.action_classes, UNLABELLED)

    def walks_forward(self, texts: Sequence[str]) -> np.ndarray:
        """(N,) bool: which captions read as a forward walk, whose untimed waypoints behind are
        turned to on an arc (:func:`~motion_env.generation.route_planning.turn_round`); a caption
        not encoded yet is encoded first."""
        missing = [t for t in dict.fromkeys(texts) if t not in self._walks]
        if missing:
            self.encode_text(missing)
        return np.array([self._walks[t] for t in texts], bool)

    def _reading(self, embedding: np.ndarray) -> str:
        row = torch.from_numpy(embedding)[None].to(self.device)
        return reading_text(self.caption_adapter.read_labels(row, top=2)[0])

    def caption_warning(self, text: str) -> str:
        """The warning a checked caption gets ('' for none); a caption not encoded yet is encoded
        first (and warns, as generating from it would), later calls read the cached verdict."""
        if text not in self._caption_warnings:
            self.encode_text([text])
        return self._caption_warnings[text]

    # ------------------------------------------------------------------ 2. root path
    def init_controller(
        self,
        text_emb: torch.Tensor,
        routes: list[np.ndarray | None],
        starts: np.ndarray,
        gens: list[torch.Generator],
        paced: bool = True,
    ) -> ControllerState:
        """Controller state at frame 0; the initial GRU state is drawn per character from its generator.
        With `paced`, the planned `routes` are timed at each caption's pace first (:meth:`paced_routes`):
        whole clips only. A timed waypoint is passed when its frame comes, reached or not; a whole
        clip's path is then bent through every waypoint, but the stream's causal bend only snaps
        the waypoints its path comes near, so the stream follows untimed routes at the
        controller's own pace (paced, a late character cut a corner and never reached it)."""
        if paced:
            routes = self.paced_routes(text_emb, routes, starts)
        state = self.controller.init_state(text_emb, routes, torch.from_numpy(starts))
        noise_std = self.controller.config.h0_noise
        if noise_std > 0:
            hidden = self.controller.config.hidden
            noise = torch.stack([torch.randn(hidden, generator=g) for g in gens]).to(self.device)
            state = replace(state, hidden=state.hidden + noise_std * noise)
        return state

    def paced_routes(
        self,
        text_emb: torch.Tensor,
        routes: Sequence[np.ndarray | None],
        starts: np.ndarray,
    ) -> list[np.ndarray | None]:
        """Planned routes with their untimed waypoints timed at each caption's pace (:attr:`pace`,
        :func:`~motion_env.generation.route_planning.pace_route`): what the controller follows."""
        if self.pace is None or not any(needs_pace(r) for r in routes):
            return list(routes)
        paces = self.pace.pace(text_emb)
        return [
            pace_route(r, s[:2], 0, float(p))
            for r, s, p in zip(routes, np.asarray(starts), paces, strict=True)
        ]

    def rollout(self, text_emb: torch.Tensor, req: BatchRequest, num_frames: int) -> np.ndarray:
        """The controller's closed-loop root paths: (B, num_frames, 3) float32, frame 0 = start."""
        gens = [row_generator(req.seed, i, CONTROLLER_STREAM) for i in range(len(req.routes))]
        state = self.init_controller(text_emb, req.routes, req.starts, gens)
        roots, _ = self.controller(state, num_frames - 1)
        return roots.cpu().numpy().astype(np.float32)

    def clip_paths(self, text_emb: torch.Tensor, req: BatchRequest, snap: bool = True) -> np.ndarray:
        """Root paths (B, n_path, 3) for clips of ``req.num_frames``, bent through the routes if `snap`.

        The routes are planned first (:func:`~motion_env.generation.route_planning.plan_route`; a
        forward walk's controller also turns round on an arc to a waypoint behind it,
        :func:`~motion_env.generation.route_planning.turn_round`, which the bending does not see). The path
        reaches one horizon past the last token's first frame, as in streaming, so the last
        tokens' path features are never cut short.
        """
        n_path = (math.ceil(req.num_frames / self.rate) - 1) * self.rate + self.path_horizon + 1
        routes = [plan_route(r, start[:2]) for r, start in zip(req.routes, req.starts, strict=True)]
        walking = self.walks_forward(req.texts)
        steered = [turn_round(r, s) if w else r for r, s, w in zip(routes, req.starts, walking, strict=True)]
        roots = self.rollout(text_emb, replace(req, routes=steered), n_path)
        if snap:
            roots = np.stack([snap_route(r, w) for r, w in zip(roots, routes, strict=True)])
        return roots

    def plan_paths(self, text_emb: torch.Tensor, req: BatchRequest) -> tuple[list, np.ndarray]:
        """The planned routes (B entries, None or (K, 3)) and the root paths (B, n_path, 3) of whole
        clips, smoothed (PATH_SMOOTHING) and bent through the routes. Without a route, a character
        with joint targets is steered to where they are
        (:func:`~motion_env.generation.root_bending.implied_route`) unless the path it takes
        without them already brings them within reach (then its motion is the one without targets,
        refined); the path is bent through the request's own route only, the targets bend it
        later (refine)."""
        steer = req.routes
        raw = None
        if req.joint_targets is not None and any(
            r is None and t is not None for r, t in zip(req.routes, req.joint_targets, strict=True)
        ):
            free = self.clip_paths(text_emb, req, snap=False)  # the paths without targets
            steer = [
                implied_route(t.dense(req.num_frames), path=p) if r is None and t is not None else r
                for r, t, p in zip(req.routes, req.joint_targets, free, strict=True)
            ]
            if all(s is r for s, r in zip(steer, req.routes, strict=True)):
                raw = free
        if raw is None:
            raw = self.clip_paths(text_emb, replace(req, routes=steer), snap=False)
        # Only a path that passes waypoints stutters; without one the clip's path stays the
        # controller's own, as the stream's is.
        smooth = [p if r is None else smooth_path(p, PATH_SMOOTHING) for p, r in zip(raw, steer, strict=True)]
        routes = [plan_route(r, s[:2]) for r, s in zip(req.routes, req.starts, strict=True)]
        return routes, np.stack([snap_route(p, r, q) for p, r, q in zip(smooth, routes, raw, strict=True)])

    # ------------------------------------------------------------------ 3. tokens
    def sample_tokens(
        self,
        text_emb: torch.Tensor,
        paths: np.ndarray,
        num_tokens: int,
        seed: int,
        logits_out: list[torch.Tensor] | None = None,
    ) -> torch.Tensor:
        """Whole clips' tokens: (B, num_tokens) long, conditioned on the caption and the root paths
        (`logits_out` receives the logits of each token, see :meth:`TokenGPT.generate`)."""
        feats = np.stack([token_path_features(p, self.rate)[:num_tokens] for p in paths])
        gens = [row_generator(seed, i, TOKEN_STREAM) for i in range(len(paths))]
        return self.gpt.generate(
            text_emb, torch.from_numpy(feats).to(self.device), num_tokens, gens, self.sampling, logits_out
        )

    # ------------------------------------------------------------------ 4. decode
    def decode(self, tokens: torch.Tensor) -> np.ndarray:
        """(B, N) tokens -> (B, N * rate, 263) float32 features."""
        return self.normalizer.denormalize(self.vqvae.decode(tokens.to(self.device)))

    def decode_next(self, decoder: DecoderStream, codes: torch.Tensor, rows: np.ndarray) -> np.ndarray:
        """The stream's decode: each of `rows`' newest token (`codes`, (N,)) -> (N, rate, 263)
        float32 features, through the decoder's per-row history (:class:`DecoderStream`)."""
        return self.normalizer.denormalize(decoder.step(codes.to(self.device), rows))

    # ------------------------------------------------------------------ 5. body on the path
    def compose(
        self,
        features: np.ndarray,
        root_path: np.ndarray,
        num_frames: int,
        first: int = 0,
        pelvis: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Decoded features (n, 263) on a root path (>= n, 3) -> world joints and the root path used
        (or B of each, (B, n, 263) and (B, m, 3), in one call: the stream's characters).

        The root path may run past the features (look-ahead frames): they shape the direction of
        travel at the last frames; the local pose is held over them and they are cut off.
        `first` > 0 puts frames first..num_frames-1 only on the path (the stream's new frames of
        its window; the earlier ones still shape the direction of travel): placing the body and
        its bone lengths are per frame, so they are the same numbers as those frames of a call
        with `first` 0. Every frame gets one pelvis shape
        (:func:`~motion_env.motion.kinematics.hold_pelvis_shape`): `pelvis` (m, one per
        character, or a number), the median of the frames placed where it is None or NaN (a whole
        clip's own; the stream holds its first token's).

        Returns:
            (num_frames - first, 22, 3) joints before foot cleanup, (num_frames - first, 3) root
            path whose heading is turned to the direction of travel.
        """
        n, m = features.shape[-2], root_path.shape[-2]
        start = min(first, n - 1)  # the local pose of frames start.. only: the others are not placed
        local = local_pose_from_features(features, first=start)
        if m > n:
            local = np.concatenate([local, np.repeat(local[..., -1:, :, :], m - n, axis=-3)], axis=-3)
        path = align_heading_to_travel(root_path)[..., first:num_frames, :]
        placed = local[..., first - start : num_frames - start, :, :]
        joints = on_bone_lengths(recompose(placed, path, face_travel=False))
        held = np.full(joints.shape[:-3], np.nan) if pelvis is None else np.asarray(pelvis, np.float64)
        if np.isnan(held).any():  # the frames' own median
            held = np.where(np.isnan(held), np.median(pelvis_shape(joints), axis=-1), held)
        return hold_pelvis_shape(joints, held[..., None]), path

    # ------------------------------------------------------------------ 6. feet and physics
    def balance(
        self, features: np.ndarray, root_path: np.ndarray, route: np.ndarray | None, num_frames: int
    ) -> np.ndarray:
        """A whole clip's root path shifted horizontally so that, with :attr:`physics`, the floor's
        push passes through its centre of mass (:func:`~motion_env.generation.balance.balance_shift`,
        measured on the composed body); the start and the route's waypoints stay where they are.
        The stream's, which cannot see a stance's end, is causal
        (:class:`~motion_env.generation.balance.StreamBalance`)."""
        if not self.physics:
            return root_path
        joints, _ = self.compose(features, root_path, num_frames)
        anchors = [0]
        if route is not None and len(route):
            anchors += [int(f) for f in waypoint_frames(root_path[:num_frames], route) if f >= 0]
        contacts = with_run_toes(joints, features[:num_frames, FOOT_CONTACT])
        shift = balance_shift(joints, contacts, np.asarray(anchors))
        out = np.array(root_path, dtype=np.float64)
        out[:num_frames, :2] += shift
        out[num_frames:, :2] += shift[-1]
        return out.astype(np.float32)

    def place_clip(
        self, features: np.ndarray, root_path: np.ndarray, num_frames: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """A whole clip's body on its path (:meth:`compose`), then its feet pinned where the decoder
        marks them planted (and a run's toes on the floor,
        :func:`~motion_env.generation.contacts.with_run_toes`) and, with :attr:`physics`, its
        height made to obey gravity and the floor
        (:func:`~motion_env.generation.physics.apply_physics`): (num_frames, 22, 3) joints before
        and after."""
        joints, _ = self.compose(features, root_path, num_frames)
        contacts = with_run_toes(joints, features[: len(joints), FOOT_CONTACT])
        pinned = FootPinner(1).apply(0, joints, contacts)
        if self.physics:
            pinned = apply_physics(pinned, contacts)
        return joints, pinned
