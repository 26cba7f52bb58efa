"""Streaming generation: B characters, one frame per step, steerable between frames.

A :class:`MotionStream` (from :meth:`motion_env.MotionGenerator.stream`) is the second driver of
:class:`~motion_env.generation.pipeline.Pipeline`: it runs the stages causally, one token (``rate``
frames) at a time:

- Look-ahead: a token covering frames ``f .. f + rate - 1`` needs the root path up to frame
  ``f + path_horizon`` (20 frames, one second: the long window of the path features), so the
  path controller runs up to 20 frames (1 s) ahead of the emitted frame. The first
  :meth:`MotionStream.step` pays for rolling it out; every later step that starts a token pays
  for ``rate`` more controller frames. The look-ahead's code is
  :mod:`motion_env.generation.stream_paths`.
- Work ahead (a single character, while nothing changed): the steps between tokens each do a share
  of the next token, the controller's frames, then its path and token, then its decoding and
  composing (:meth:`MotionStream._work_ahead`): the same numbers, a lighter token step. A change
  before the token undoes them.
- Control delay: a new caption or new waypoints act from the next token on, i.e. on the frames
  after those already decoded (at most ``rate`` frames, 0.2 s, after the call). The controller's
  look-ahead is rolled out again from the last decoded frame, so no emitted pose moves and the
  path does not jump.
- After a change, :attr:`MotionStream.lookahead` ``"exact"`` rolls the whole second out again;
  ``"head"`` (the default with a look-ahead head, :mod:`motion_env.models.lookahead`) rolls out
  the token's ``rate`` frames only (decoded frames are always the controller's) and predicts the
  rest in one pass; the roll-out then catches up (:data:`CATCH_UP_TOKENS`). Without changes both
  are the controller's alone.
- Tokens are sampled one at a time with the GPT's KV cache; the VQ-VAE decodes the newest token
  with its convolutions' history cached (:class:`motion_env.models.vqvae.DecoderStream`); the
  recompose runs on a short window of recent frames, of which only the new ones are emitted; the foot cleanup
  (:class:`~motion_env.generation.feet.FootPinner`) is causal, frame by frame, as for whole clips.
- Snapping is causal too: the residual to each waypoint inside the look-ahead is spread linearly
  from the last decoded frame to the waypoint's frame.
- So is the balance (:class:`~motion_env.generation.balance.StreamBalance`): each token's frames
  are shifted so that the floor's push passes through the centre of mass, from the frames
  already emitted (a whole clip's balance also sees each stance's end).
- Joint targets and height limits (:meth:`MotionStream.set_joint_targets`,
  :meth:`MotionStream.set_objectives`) are met by the causal, closed-form stages of
  :mod:`motion_env.generation.stream_control` as each token is decoded.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch

from motion_env.generation.balance import StreamBalance
from motion_env.generation.contacts import with_run_toes
from motion_env.generation.feet import FootPinner
from motion_env.generation.physics import PhysicsFilter
from motion_env.generation.pipeline import CONTROLLER_STREAM, TOKEN_STREAM, Pipeline, row_generator
from motion_env.generation.request import (
    check_feasible,
    check_route,
    check_start,
    check_starts,
    check_text,
    check_texts,
    per_row_waypoints,
    resolve_seed,
)
from motion_env.generation.request_controls import check_joint_targets, check_objectives
from motion_env.generation.stream_control import StreamControl
from motion_env.generation.stream_paths import CATCH_UP_TOKENS, StreamPaths
from motion_env.joint_targets import JointTargets
from motion_env.models.controller_state import StateRing
from motion_env.models.path_features import D_PATH, first_token_path_features
from motion_env.models.sampling import sample_tokens
from motion_env.motion.kinematics import pelvis_shape
from motion_env.motion.skeleton import FEATURE_DIM, FOOT_CONTACT, NUM_JOINTS
from motion_env.objectives import HeightLimit

__all__ = ["CATCH_UP_TOKENS", "MotionStream"]

# Frames of decoded body kept as left context of the recompose.
STREAM_CONTEXT_FRAMES = 40


@dataclass
class _EarlyToken:
    """A single character's next token worked out before it is due (:meth:`MotionStream._work_ahead`);
    `undo` puts back what that changed (:meth:`MotionStream._discard_early`)."""

    ahead: list[np.ndarray]
    tokens: torch.Tensor
    undo: tuple[Any, ...]
    body: np.ndarray | None = None
    joints: np.ndarray | None = None
    paths: np.ndarray | None = None


class MotionStream(StreamPaths):
    """B characters generated one frame per :meth:`step`, steerable between frames.

    Each character's episode starts at its ``start`` (frame 0) and advances one frame per
    :meth:`step`. Per character, the stream keeps the controller up to ``path_horizon`` frames
    ahead of the emitted frame, the GPT's KV cache, the VQ decoder's context and a short history
    of decoded frames (see the module docstring for the look-ahead and the control delay).

    Attributes:
        batch_size: B.
        lookahead_frames: how far (frames) the controller runs ahead of the emitted frame at most.
        lookahead: ``"head"`` or ``"exact"``: how the look-ahead is made again after a change (see
            the module docstring; settable; "head" needs a pipeline with a ``lookahead`` head).
        control_delay_frames: the most frames between :meth:`set_text` / :meth:`set_waypoints`
            and the first frame that follows the change (the rest of the decoded token).
    """

    def __init__(
        self,
        pipeline: Pipeline,
        texts: Sequence[str],
        waypoints: Any = None,
        starts: np.ndarray | None = None,
        seed: int | None = None,
        infeasible: str = "raise",
    ) -> None:
        g = self._pipe = pipeline
        if isinstance(texts, str):
            texts = [texts]  # one character
        texts = check_texts(texts)
        b = self.batch_size = len(texts)
        self._texts = list(texts)
        start_arr = check_starts(starts, b)
        self.infeasible = infeasible
        checked = [
            check_feasible(route, start_arr[i, :2], infeasible, what=f"waypoints of character {i}")
            for i, route in enumerate(per_row_waypoints(waypoints, b))
        ]
        self.seed = resolve_seed(seed)
        self._ctrl_gens = [row_generator(self.seed, i, CONTROLLER_STREAM) for i in range(b)]
        self._tok_gens = [row_generator(self.seed, i, TOKEN_STREAM) for i in range(b)]
        self._rate = rate = g.rate
        self._horizon = g.path_horizon
        self.lookahead_frames = self._horizon
        self.control_delay_frames = rate
        # One ring of per-frame history, indexed by frame % R: the body context, the anchor one
        # frame before the next token and the look-ahead all fit.
        self._window = STREAM_CONTEXT_FRAMES
        r = self._ring = self._window + self._horizon + 2 * rate
        dev = g.device
        hid = g.controller.config.hidden
        self._states = StateRing(b, r, hid, dev)  # the controller's state and root per frame
        self._snapped = np.zeros((b, r, 3), np.float32)  # committed (snapped) root per frame
        self._features = np.zeros((b, r, FEATURE_DIM), np.float32)  # decoded features per frame
        self._pelvis = np.full(b, np.nan)  # each character's pelvis shape, its first token's (compose)
        self._composed = np.full((b, NUM_JOINTS, 3), np.nan)  # the last frame composed (with_run_toes)
        self._feet = FootPinner(b)
        self._physics = PhysicsFilter(b) if g.physics else None
        self._balance = StreamBalance(b) if g.physics else None
        self._anchor_frames = [np.zeros(0, np.int64)] * b  # waypoint frames ahead (_snap_ahead)
        self._emitted = np.zeros(b, np.int64)
        self._decoded = np.zeros(b, np.int64)
        # A change waits for the next token; `_predicted`: the look-ahead beyond the roll-out is the head's.
        self._dirty, self._predicted = np.zeros(b, bool), np.zeros(b, bool)
        # Checked routes, planned when the next token needs them (the last one counts): _planned's
        # route, where (x, z, heading) and frame.
        self._pending: dict[int, tuple[np.ndarray | None, np.ndarray, int]] = {}
        self._decoder = g.vqvae.decoder_stream(b)
        self._prev = torch.zeros(b, dtype=torch.long)
        self._buffer = np.zeros((b, rate, NUM_JOINTS, 3), np.float32)
        self._buffer_root = np.zeros((b, rate, 3), np.float32)
        self._buffer_pos = np.full(b, rate, np.int64)  # rate = empty
        self._root = start_arr.copy()
        self._control = StreamControl(b)  # joint targets and height limits (set_joint_targets, ...)
        self._head = g.lookahead
        if self._head is not None and self._head.config.horizon < self._horizon:
            raise ValueError(f"look-ahead head horizon {self._head.config.horizon} < {self._horizon} frames")
        self._lookahead = "exact" if self._head is None else "head"
        self._early: _EarlyToken | None = None  # one character's next token, worked out ahead

        emb = g.encode_text(self._texts)
        # planned routes (generation.route_planning): what the controller and snapping see
        self._routes = [self._planned(i, route, start_arr[i]) for i, route in enumerate(checked)]
        self._cache = g.gpt.new_cache(emb, g.sampling.guidance)
        self._front = g.init_controller(emb, self._routes, start_arr, self._ctrl_gens, paced=False)
        rows = torch.arange(b, device=dev)
        self._states.record(rows, self._front)
        self._snapped[:, 0] = start_arr

    # ------------------------------------------------------------------ public state
    @property
    def frame_index(self) -> np.ndarray:
        """(B,) int: frames emitted so far in each character's episode."""
        return self._emitted.copy()

    @property
    def root_state(self) -> np.ndarray:
        """(B, 3) x, z, heading of the last emitted frame (the start before the first step)."""
        return self._root.copy()

    @property
    def texts(self) -> list[str]:
        """The current caption of each character."""
        return list(self._texts)

    @torch.no_grad()
    def caption_features(self, index: int | None = None) -> np.ndarray:
        """(B, D) float32: each character's current caption as the path controller reads it (its
        projection of the sentence embedding; D = 64 for the shipped model), or (D,) of character
        `index`. Compact enough for an observation, and it is what sets the pace of walking
        versus jogging."""
        text = self._front.text if index is None else self._front.text[int(self._rows(index)[0])]
        return self._pipe.controller.text_proj(text).cpu().numpy().astype(np.float32)

    @property
    def lookahead(self) -> str:
        """How the look-ahead is made again after a change: "head" or "exact" (module docstring)."""
        return self._lookahead

    @lookahead.setter
    def lookahead(self, mode: str) -> None:
        if mode not in ("exact", "head") or (mode == "head" and self._head is None):
            raise ValueError(f"lookahead must be 'exact' or 'head' (needs a lookahead.pt), got {mode!r}")
        self._discard_early()
        self._lookahead = mode

    # ------------------------------------------------------------------ steering
    def _rows(self, index: int | None) -> np.ndarray:
        if index is None:
            return np.arange(self.batch_size)
        if isinstance(index, bool) or int(index) != index or not 0 <= int(index) < self.batch_size:
            raise IndexError(f"character index {index!r} out of range for a batch of {self.batch_size}")
        return np.array([int(index)])

    def set_text(self, text: str, index: int | None = None) -> None:
        """Change the caption of one character (`index`) or of all (None) from the next token on."""
        text = check_text(text)
        rows = self._rows(index)
        self._discard_early()
        g = self._pipe
        emb = g.encode_text([text])  # (1, D)
        self._front = g.controller.set_text(
            self._front, emb.expand(len(rows), -1) if index is None else emb[0], index
        )
        g.gpt.set_cache_text(self._cache, emb.expand(len(rows), -1), None if index is None else int(index))
        for i in rows:
            self._texts[i] = text
        self._dirty[rows] = True

    def set_waypoints(self, waypoints: np.ndarray | Sequence | None, index: int | None = None) -> None:
        """Replace the route ahead of one character (`index`) or of all (None).

        Args:
            waypoints: (K, 2)/(K, 3) world x, z and optionally the frame index in that character's
                episode; None removes the route (the character follows the caption).
        """
        route = check_route(waypoints)
        rows = self._rows(index)
        self._discard_early()
        for i in rows:
            # Feasible from where the character is now (times are frames of its episode).
            where, frame = self._root[i].copy(), int(self._emitted[i])
            self._pending[int(i)] = (check_feasible(route, where[:2], self.infeasible, frame), where, frame)
            self._dirty[i] = True

    def set_goals(self, points: np.ndarray, rows: Sequence[int] | np.ndarray) -> None:
        """Send each character of `rows` to one point: ``set_waypoints([points[n]], index=rows[n])``
        for every n (one untimed waypoint each, which asks for no speed), checked in one go.

        Args:
            points: (N, 2) world x, z.
            rows: (N,) distinct character indices.
        """
        rows = np.asarray(rows, np.int64).reshape(-1)
        pts = np.asarray(points, np.float64)
        if pts.shape != (len(rows), 2):
            raise ValueError(f"points must have shape ({len(rows)}, 2) (one x, z per row), got {pts.shape}")
        if len(np.unique(rows)) != len(rows) or ((rows < 0) | (rows >= self.batch_size)).any():
            raise IndexError(f"rows must be distinct indices in [0, {self.batch_size}), got {rows.tolist()}")
        if not len(rows):
            return
        routes = check_route(pts)  # the points as N untimed one-point routes: checked together
        self._discard_early()
        for n, i in enumerate(rows.tolist()):
            self._pending[i] = (routes[n : n + 1], self._root[i].copy(), int(self._emitted[i]))
        self._dirty[rows] = True

    def set_joint_targets(
        self,
        targets: JointTargets | np.ndarray | None,
        index: int | None = None,
        first_frame: int | None = None,
    ) -> None:
        """Give one character (`index`) or all (None) joint targets from now on (replacing earlier ones).

        Args:
            targets: a :class:`~motion_env.joint_targets.JointTargets` whose frames are episode
                frames, or a dense (F, 22, 3) array of world positions (metres), NaN where a joint
                is free, row k being episode frame ``first_frame + k``. None removes the targets.
            first_frame: a dense array's row 0 (default: the next frame to be emitted).

        Look-ahead: a target is met exactly at its frame if it is set at least FADE (10) frames
        before it (the joint blends into it over those frames); a pelvis target also bends the path
        once it is within ``lookahead_frames`` (20). Targets for frames already decoded (up to
        ``control_delay_frames`` after the last emitted one) are not used, with a warning (not for
        targets the character already had); emitted frames never change. See
        :mod:`motion_env.generation.stream_control`.
        """
        rows = self._rows(index)
        if first_frame is not None and (
            isinstance(first_frame, bool) or int(first_frame) != first_frame or first_frame < 0
        ):
            raise ValueError(f"first_frame must be a frame index >= 0, got {first_frame!r}")
        # A dense array without first_frame starts at each character's next frame; anything else
        # means the same frames for every character and is checked once.
        per_row = first_frame is None and targets is not None and not isinstance(targets, JointTargets)
        checked = None if per_row else check_joint_targets(targets, None, "joint_targets", first_frame or 0)
        self._discard_early()
        for i in rows:
            if per_row:
                checked = check_joint_targets(targets, None, "joint_targets", int(self._emitted[i]))
            self._control.set_targets(int(i), checked, int(self._decoded[i]))

    def set_objectives(self, objectives: Sequence[Any] | None, index: int | None = None) -> None:
        """Height limits for one character (`index`) or all (None) from now on (replacing earlier ones).

        The stream takes :class:`~motion_env.objectives.HeightLimit` (frames are episode frames);
        KeepOut, StayInside and callables need the whole clip (``generate``) and raise here.
        """
        objs = check_objectives(objectives)
        bad = [k for k, o in enumerate(objs) if not isinstance(o, HeightLimit)]
        if bad:
            raise ValueError(
                f"objectives[{bad[0]}] ({type(objs[bad[0]]).__name__}): the stream takes HeightLimit "
                "objectives only; KeepOut, StayInside and callables need a whole clip "
                "(MotionGenerator.generate), "
                "or plan the route around obstacles (policies.AStarPolicy)"
            )
        rows = self._rows(index)
        self._discard_early()
        for i in rows:
            self._control.limits[int(i)] = list(objs)

    def control_summary(self, index: int = 0) -> str:
        """How well character `index` has met its joint targets so far (errors of the emitted ones)."""
        (i,) = self._rows(index)
        return self._control.describe(int(i))

    def reset(
        self,
        index: int,
        text: str,
        waypoints: np.ndarray | Sequence | None = None,
        start: np.ndarray | Sequence[float] | None = None,
    ) -> None:
        """Start a new episode for one character (frame 0 at `start`); the others go on."""
        (i,) = self._rows(index)
        text = check_text(text)
        start_arr = np.zeros(3, np.float32) if start is None else check_start(start)
        checked = check_feasible(check_route(waypoints), start_arr[:2], self.infeasible)
        self._discard_early()
        g = self._pipe
        emb = g.encode_text([text])
        self._texts[i] = text  # the caption the route is planned for (_planned)
        route = self._planned(i, checked, start_arr)
        sub = g.init_controller(emb, [route], start_arr[None], [self._ctrl_gens[i]], paced=False)
        rows = torch.tensor([i], device=g.device)
        self._front = self._front.put(rows, sub)
        self._states.record(rows, sub)
        g.gpt.reset_cache_rows(self._cache, [int(i)], emb)
        self._routes[i] = route
        self._snapped[i, 0] = start_arr
        self._emitted[i] = self._decoded[i] = 0
        self._dirty[i] = self._predicted[i] = False
        self._pending.pop(int(i), None)
        self._decoder.reset([i])
        self._pelvis[i] = np.nan
        self._composed[i] = np.nan
        self._feet.reset(i)
        if self._physics is not None:
            self._physics.reset(i)
            self._balance.reset(i)
        self._control.reset(i)
        self._prev[i] = 0
        self._buffer_pos[i] = self._rate
        self._root[i] = start_arr

    # ------------------------------------------------------------------ emission
    @torch.no_grad()
    def step(self, rows: Sequence[int] | np.ndarray | None = None) -> np.ndarray:
        """Emit the next frame of every character, or only of `rows` (the others wait).

        Returns:
            (B, 22, 3) float32 world joints, or (len(rows), 22, 3) in the order of `rows`.
        """
        if rows is None:
            rows = np.arange(self.batch_size)
        else:
            rows = np.asarray(rows, dtype=np.int64).reshape(-1)
            if len(np.unique(rows)) != len(rows) or ((rows < 0) | (rows >= self.batch_size)).any():
                raise IndexError(
                    f"rows must be distinct indices in [0, {self.batch_size}), got {rows.tolist()}"
                )
        need = rows[self._buffer_pos[rows] >= self._rate]
        if len(need):
            self._produce(np.sort(need))
        pos = self._buffer_pos[rows]
        out = self._buffer[rows, pos].copy()
        self._root[rows] = self._buffer_root[rows, pos]
        self._buffer_pos[rows] += 1
        self._emitted[rows] += 1
        if not len(need) and len(rows) == self.batch_size:
            self._work_ahead()  # a share of the next token's work, spread over the steps before it
        return out

    # ------------------------------------------------------------------ internals
    def _produce(self, rows: np.ndarray) -> None:
        """Decode the next token of each character in `rows` and fill their frame buffers: the
        pipeline's stages in their order (:mod:`motion_env.generation.pipeline`), for one token
        (of a single character, the stages :meth:`_work_ahead` did are not done again)."""
        first = self._decoded[rows]  # (N,) first frame of the new token
        early, self._early = self._early, None
        if early is None:
            ahead = self._plan_paths(rows, first)  # 2. path (1. text ran in set_text / reset)
            early = _EarlyToken(ahead, self._sample_tokens(rows, ahead), ())  # 3. tokens
        if early.body is None:
            self._decode_compose(rows, early)  # 4. decode, 5. compose
        ahead, body, joints, paths = early.ahead, early.body, early.joints, early.paths
        before = np.where(np.isnan(self._composed[rows]), joints[:, 0], self._composed[rows])
        contacts = with_run_toes(joints, body[:, :, FOOT_CONTACT], before)  # 6. balance, feet and physics
        self._composed[rows] = joints[:, -1]
        if self._balance is not None:
            joints, paths = self._balanced(rows, first, joints, paths, contacts)
        pinned = self._feet.apply_rows(rows, joints, contacts)
        if self._physics is not None:
            pinned = self._physics.apply_rows(rows, pinned, contacts)
        slots = (first[:, None] + np.arange(self._rate)) % self._ring  # (N, rate) the token's frames
        self._snapped[rows[:, None], slots] = np.stack([a[: self._rate] for a in ahead])
        self._buffer[rows], self._buffer_root[rows] = pinned, paths
        for n, i in enumerate(rows):
            if self._control.active(int(i)):  # 7. refine (causal, closed form)
                f = int(first[n])
                self._buffer[i] = self._control.apply(int(i), f, self._buffer[i], body[n][:, FOOT_CONTACT])
        self._decoded[rows] += self._rate
        self._buffer_pos[rows] = 0

    def _balanced(
        self, rows: np.ndarray, first: np.ndarray, joints: np.ndarray, paths: np.ndarray, contacts: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The new frames and their root path shifted for balance (:class:`StreamBalance`); the
        committed path the next tokens continue stays the controller's, as a whole clip's."""
        anchors = [self._anchor_frames[i] - first[n] for n, i in enumerate(rows)]
        held = np.array([self._control.active(int(i)) for i in rows], bool)
        shift = self._balance.shift_rows(rows, joints, contacts, anchors, held).astype(np.float32)
        joints = joints.copy()
        joints[..., 0] += shift[:, :, None, 0]
        joints[..., 2] += shift[:, :, None, 1]
        return joints, paths + np.pad(shift, ((0, 0), (0, 0), (0, 1)))

    def _decode_compose(self, rows: np.ndarray, early: _EarlyToken) -> None:
        """Stages 4 and 5 of the token whose path and tokens `early` holds (into `early`)."""
        early.body = self._pipe.decode_next(self._decoder, early.tokens, rows)
        early.joints, early.paths = self._compose(rows, self._decoded[rows], early.body, early.ahead)

    def _work_ahead(self) -> None:
        """One share of a single character's next token, in each step between tokens, so that the
        token's step does not carry it all (the p99 of ``env.step``): the controller's roll-out,
        then the path ahead and the token (stages 2-3), then its decoding and composing (4-5);
        the feet, physics and joint targets (6-7) stay in the token's step.

        The same numbers as at the token: while nothing waits to be re-rolled (no change since the
        last token, no predicted look-ahead) the inputs of these stages are final; a change before
        the token undoes them (:meth:`_discard_early`). (Not in a batch: a row worked out early
        would run in a smaller group, whose matrix products differ in the last bits.)"""
        if self.batch_size != 1 or self._dirty[0] or self._predicted[0]:
            return
        rows, first = np.zeros(1, np.int64), self._decoded.copy()
        last = first + self._horizon  # the next token's last frame
        if (self._front.frame.cpu().numpy() < last).any():
            self._advance(rows, last)  # the controller's roll-out
        elif self._early is None:
            # A GPT step writes only past the cached columns (or re-primes into new buffers), and
            # at B = 1 changes no cached column: a shallow copy keeps the cache as it was.
            undo = (replace(self._cache), self._tok_gens[0].get_state(), self._prev.clone())
            undo += (self._decoder.state(),)
            ahead = self._plan_paths(rows, first)
            self._early = _EarlyToken(ahead, self._sample_tokens(rows, ahead), undo)
        elif self._early.body is None:
            self._decode_compose(rows, self._early)

    def _discard_early(self) -> None:
        """Undo the work done ahead for the next token (:meth:`_work_ahead`): a change arrived
        before the token was due, which the token must see. (The frames it wrote into the history
        of decoded features are written again before they are read.)"""
        early, self._early = self._early, None
        if early is None:
            return
        self._cache, gen_state, self._prev, decoder = early.undo
        self._tok_gens[0].set_state(gen_state)
        self._decoder.restore(decoder)

    def _sample_tokens(self, rows: np.ndarray, ahead: list[np.ndarray]) -> torch.Tensor:
        """One GPT step for the whole batch, in which only `rows` advance: (N,) sampled tokens."""
        g = self._pipe
        path_feat = torch.zeros(self.batch_size, D_PATH)
        feats = first_token_path_features(np.stack(ahead), self._rate)  # each row's next token
        path_feat[torch.as_tensor(rows)] = torch.from_numpy(feats)
        logits, self._cache = g.gpt.step(self._cache, self._prev.to(g.device), path_feat.to(g.device), rows)
        rows_t = torch.as_tensor(rows, device=logits.device)
        tokens = sample_tokens(logits[rows_t], [self._tok_gens[i] for i in rows], g.sampling)
        self._prev[torch.as_tensor(rows)] = tokens.to(self._prev.device)
        return tokens

    def _compose(
        self, rows: np.ndarray, first: np.ndarray, body: np.ndarray, ahead: list[np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray]:
        """The new frames' body on each path: (N, rate, 22, 3) joints and (N, rate, 3) root path.

        The recompose runs over a window of recent frames (its smoothing needs the past), one
        batched call per window length (every character once past its first two seconds)."""
        rate, ring = self._rate, self._ring
        window = np.minimum(first + rate, self._window)  # frames begin..f+rate-1, begin >= 0
        joints = np.zeros((len(rows), rate, NUM_JOINTS, 3), np.float32)
        paths = np.zeros((len(rows), rate, 3), np.float32)
        self._features[rows[:, None], (first[:, None] + np.arange(rate)) % ring] = body
        for length in np.unique(window):
            sel = np.nonzero(window == length)[0]
            at = rows[sel, None]
            span = (first[sel, None] + rate - length + np.arange(length)) % ring  # (S, length)
            roots = np.concatenate(
                [self._snapped[at, span[:, :-rate]], np.stack([ahead[n] for n in sel])], axis=1
            )
            held = self._pelvis[rows[sel]]
            j, path = self._pipe.compose(
                self._features[at, span], roots, int(length), int(length) - rate, held
            )
            joints[sel], paths[sel] = j, path
            first_token = np.isnan(held)
            if first_token.any():  # from now on these characters hold the shape their first token got
                self._pelvis[rows[sel][first_token]] = np.median(pelvis_shape(j[first_token]), axis=-1)
        return joints, paths
