"""The path controller: a small closed-loop GRU that drives the root (x, z, heading) frame by frame.

C-T2M's path half. Every frame the controller sees, in the character's own heading frame, the
next four waypoints of its route (direction, distance, time to go, flags), the caption embedding
and its own previous velocity, and predicts the local step ``(d_lateral, d_forward, d_theta)``,
which is integrated into the world root path. Because the waypoint features are recomputed from
the *predicted* position every frame (also in training), the controller learns to correct its own
drift.

Two closed-form rules sit on top of the network:

- waypoint queue: the route advances past a timed waypoint once its frame is reached and past an
  untimed one once the character is within ``arrive_radius``; the last waypoint is never
  dropped (it is where the character stays);
- arrive gating: within ``arrive_radius`` of the last waypoint the network's step is blended into
  a direct approach whose turn is zero, so the character settles on the point instead of
  orbiting or spinning around it.

Waypoints follow :mod:`motion_env.motion.trajectory`: world ``x, z`` and a frame index (NaN = untimed).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Annotated

import numpy as np
import torch
from torch import nn

from motion_env.models.controller_state import ControllerState, Trace, pad_waypoints
from motion_env.models.frame_ops import (
    TORCH,
    Array,
    Constants,
    NumpyOps,
    TorchOps,
    gradients_state,
    numpy_chosen,
)
from motion_env.models.jit_cache import jit_enabled
from motion_env.models.waypoint_features import (
    RouteView,
    from_heading_frame_torch,
    next_queue,
    pack_waypoints,
    route_view,
    slot_features,
    step_input_dim,
)
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_waypoints
from motion_env.motion.validation import CheckedConfig, NonNegativeFloat, PositiveFloat, PositiveInt

# The most characters a roll-out without gradients runs on numpy (PathController.frame_ops).
NUMPY_MAX_BATCH = 8


@dataclass
class ControllerConfig(CheckedConfig):
    """Sizes and the closed-form constants of :class:`PathController`.

    Attributes:
        text_dim: width of the caption embedding (384 for the MiniLM encoder).
        text_proj: width the caption is projected to.
        num_slots: how many upcoming waypoints the controller sees (padded by repeating the last).
        hidden: GRU width.
        mlp: width of the input and output MLPs.
        arrive_radius: metres; an untimed waypoint within it counts as reached, and within it of the
            last waypoint the arrive gating takes over.
        seek_rate: fraction of the remaining offset closed per frame inside the arrive radius.
        step_scale: metres per frame of a unit network output (bounds the learning problem).
        turn_scale: radians per frame of a unit network output.
        max_time_to_go: seconds; longer times to a timed waypoint are clamped.
        h0_noise: std of the random initial GRU state drawn when a generator is given (sampled the
            same way in training, so rollouts vary a little with the seed).
    """

    text_dim: PositiveInt = 384
    text_proj: PositiveInt = 64
    num_slots: PositiveInt = 4
    hidden: PositiveInt = 192  # the shipped size since session 23: its weights stay in a core's L2 cache
    mlp: PositiveInt = 192
    arrive_radius: PositiveFloat = 0.3
    seek_rate: Annotated[float, "(0, 1]"] = 0.25
    step_scale: PositiveFloat = 0.1
    turn_scale: PositiveFloat = 0.1
    max_time_to_go: PositiveFloat = 10.0
    h0_noise: NonNegativeFloat = 0.3

    @property
    def input_dim(self) -> int:
        return step_input_dim(self.text_proj, self.num_slots)


class PathController(nn.Module):
    """Closed-loop GRU root controller (see the module docstring)."""

    def __init__(self, config: ControllerConfig) -> None:
        super().__init__()
        self.config = config
        c = config
        self.text_proj = nn.Linear(c.text_dim, c.text_proj)
        self.inp = nn.Sequential(nn.Linear(c.input_dim, c.mlp), nn.GELU(), nn.Linear(c.mlp, c.mlp), nn.GELU())
        self.gru = nn.GRUCell(c.mlp, c.hidden)
        self.out = nn.Sequential(nn.Linear(c.hidden + c.mlp, c.mlp), nn.GELU(), nn.Linear(c.mlp, 3))
        # Start near "stand still": the rollout is stable from the first training step.
        nn.init.zeros_(self.out[-1].weight)
        nn.init.zeros_(self.out[-1].bias)
        self._text_cache: tuple[torch.Tensor, tuple[int, int], torch.Tensor] | None = None
        self._numpy = NumpyOps()  # the frame's backend for roll-outs without gradients on the CPU
        # Where a roll-out's frames run (frame_ops.BACKENDS): "auto" (numpy for a few characters on the
        # CPU without gradients, else torch), "torch" (the same numbers on any device, to the bit),
        # or "numpy" (CPU, no gradients); the two agree to float32 rounding.
        self.frame_backend = "auto"
        # Whether a roll-out on numpy runs as one compiled loop (controller_jit, numba) or frame by
        # frame on numpy's operations (the reference it is tested against); the same numbers to
        # float32 rounding.
        self.compiled = True

    @classmethod
    def drifting(cls, config: ControllerConfig, std: float) -> PathController:
        """An untrained controller whose output layer is random (normal, `std`) from torch's
        global generator: a new one stands still, this one drifts (for tests and the random
        generator)."""
        model = cls(config)
        for p in model.out[-1].parameters():
            nn.init.normal_(p, std=std)
        return model

    @property
    def device(self) -> torch.device:
        return self.text_proj.weight.device

    # ------------------------------------------------------------------ state handling
    def init_state(
        self,
        text_emb: torch.Tensor,
        waypoints: list[np.ndarray | list | None] | None = None,
        start: np.ndarray | torch.Tensor | None = None,
        frame: int | np.ndarray | torch.Tensor = 0,
        generator: torch.Generator | None = None,
    ) -> ControllerState:
        """The state at the first frame of B characters.

        Args:
            text_emb: (B, text_dim) caption embeddings.
            waypoints: None or B entries of (K, 2)/(K, 3) waypoints (or None each).
            start: (B, 3) x, z, heading of the first frame; default: origin facing +Z.
            frame: the episode frame index of the first frame (scalar or (B,)).
            generator: draws the initial GRU state (None: zeros, fully deterministic).
        """
        dev = self.device
        text_emb = torch.as_tensor(text_emb, dtype=torch.float32, device=dev)
        if text_emb.ndim != 2 or text_emb.shape[1] != self.config.text_dim:
            raise ValueError(f"text_emb must be (B, {self.config.text_dim}), got {tuple(text_emb.shape)}")
        b = text_emb.shape[0]
        if start is None:
            start = torch.zeros(b, 3, device=dev)
        start = torch.as_tensor(start, dtype=torch.float32, device=dev)
        if start.shape != (b, 3) or not torch.isfinite(start).all():
            raise ValueError(f"start must be a finite (B, 3) = ({b}, 3) array of x, z, heading")
        wp, count = pack_waypoints(waypoints, b, dev)
        hidden = torch.zeros(b, self.config.hidden, device=dev)
        if generator is not None and self.config.h0_noise > 0:
            noise = torch.randn(b, self.config.hidden, generator=generator, device=generator.device)
            hidden = hidden + self.config.h0_noise * noise.to(dev)
        frames = torch.as_tensor(frame, dtype=torch.long, device=dev).expand(b).clone()
        state = ControllerState(
            pos=start[:, :2].clone(),
            theta=start[:, 2].clone(),
            vel=torch.zeros(b, 3, device=dev),
            hidden=hidden,
            frame=frames,
            text=text_emb,
            waypoints=wp,
            count=count,
            queue=torch.zeros(b, dtype=torch.long, device=dev),
        )
        return self._advance_queue(state)

    def set_waypoints(
        self, state: ControllerState, waypoints: np.ndarray | list | None, index: int | None = None
    ) -> ControllerState:
        """Replace the route ahead of one character (`index`) or of all (None); times are episode frames."""
        b = state.pos.shape[0]
        targets = list(range(b)) if index is None else [int(index)]
        return self.set_routes(state, targets, [waypoints] * len(targets))

    def set_routes(
        self,
        state: ControllerState,
        rows: Sequence[int],
        routes: Sequence[np.ndarray | list | None],
        checked: bool = False,
    ) -> ControllerState:
        """Replace the routes of several characters at once: ``routes[n]`` for character ``rows[n]``
        (None: no route). The others keep theirs; the tensor of waypoints only ever grows, its
        padding repeats each route's last waypoint as :func:`pack_waypoints` does. `checked`: the
        routes are checked (K, 3) float32 already (the stream's planned routes), not again."""
        b = state.pos.shape[0]
        rows = [int(i) for i in rows]
        for i in rows:
            if not 0 <= i < b:
                raise IndexError(f"character index {i} out of range for a batch of {b}")
        new = list(routes) if checked else [None if r is None else validate_waypoints(r) for r in routes]
        width = max([state.waypoints.shape[1]] + [len(r) for r in new if r is not None])
        # The new rows padded in numpy and written in one go (the last of a row given twice wins).
        last = dict(zip(rows, new))
        block = np.zeros((len(last), width, 3), np.float32)
        counts = np.zeros(len(last), np.int64)
        for n, r in enumerate(last.values()):
            if r is not None:
                block[n, : len(r)], block[n, len(r) :], counts[n] = r, r[-1], len(r)
        at = list(last)
        if _on_numpy(state):
            # Copied and written on numpy: a stream sets a new route at most tokens, and torch's
            # per-operation cost was most of it (125 -> 80 us a call on the development CPU).
            wp = pad_waypoints(state.waypoints.numpy(), width, copy=True)
            count, queue = state.count.numpy().copy(), state.queue.numpy().copy()
            wp[at], count[at], queue[rows] = block, counts, 0
            wp, count, queue = (torch.from_numpy(x) for x in (wp, count, queue))
        else:
            wp = pad_waypoints(state.waypoints, width).clone()
            count, queue = state.count.clone(), state.queue.clone()
            if at:
                index = torch.as_tensor(at, dtype=torch.long, device=wp.device)
                wp[index] = torch.from_numpy(block).to(device=wp.device, dtype=wp.dtype)
                count[index] = torch.from_numpy(counts).to(count.device)
            queue[rows] = 0
        return self._advance_queue(replace(state, waypoints=wp, count=count, queue=queue))

    def reset_character(
        self,
        state: ControllerState,
        index: int,
        text_emb: torch.Tensor,
        waypoints: np.ndarray | list | None = None,
        start: np.ndarray | tuple[float, float, float] | None = None,
        generator: torch.Generator | None = None,
    ) -> ControllerState:
        """Restart one character at frame 0 (vector-env autoreset); the others are untouched.

        text_emb: (text_dim,); waypoints: (K, 2)/(K, 3) or None; start: (3,) or None (origin).
        """
        b = state.pos.shape[0]
        if not 0 <= int(index) < b:
            raise IndexError(f"character index {index} out of range for a batch of {b}")
        i = int(index)
        one = self.init_state(
            torch.as_tensor(text_emb, dtype=torch.float32).reshape(1, -1),
            [waypoints],
            None if start is None else np.asarray(start, dtype=np.float32).reshape(1, 3),
            generator=generator,
        )
        state = self.set_waypoints(state, waypoints, index=i)
        fields = {}
        for name in ("pos", "theta", "vel", "hidden", "frame", "text", "queue"):
            value = getattr(state, name).clone()
            value[i] = getattr(one, name)[0]
            fields[name] = value
        return replace(state, **fields)

    def set_text(
        self, state: ControllerState, text_emb: torch.Tensor, index: int | None = None
    ) -> ControllerState:
        """Change the caption of one character (`index`) or of all (None).

        text_emb: (text_dim,) or, for all, (B, text_dim).
        """
        text_emb = torch.as_tensor(text_emb, dtype=torch.float32, device=self.device)
        text = state.text.clone()
        if index is None:
            text[:] = text_emb
        else:
            text[int(index)] = text_emb.reshape(-1)
        return replace(state, text=text)

    def _advance_queue(self, state: ControllerState) -> ControllerState:
        """Move each character's target past reached waypoints (timed: frame reached; untimed: near)."""
        if self.compiled and jit_enabled() and state.pos.device.type == "cpu":
            from motion_env.models.controller_jit import advance_queue  # numba only when it runs

            return replace(state, queue=advance_queue(state, self.config.arrive_radius))
        queue = next_queue(
            state.waypoints, state.count, state.queue, state.pos, state.frame, self.config.arrive_radius
        )
        return replace(state, queue=queue)

    # ------------------------------------------------------------------ the network
    def step_inputs(self, state: ControllerState, ops: TorchOps = TORCH) -> Array:
        """(B, ``step_input_dim``) what the network reads at `state`'s frame: the captions'
        projection, the waypoint features and the last velocity (halved), as :meth:`_frame` builds
        them inline (for the look-ahead head, :mod:`motion_env.models.lookahead`), in `ops`'s
        arrays (:meth:`frame_ops`: numpy for a few characters, at a third of torch's cost).

        The waypoint features, per slot of the next `num_slots` waypoints: the offset (lateral,
        forward) / max(dist, 1) (a direction far away, the offset in metres up close), log(1 +
        dist), timed flag, time to go (s), the speed a timed waypoint asks for (m/s), is-last flag,
        valid flag (any route at all), and log(1 + the distance from the previous slot) for the
        shape of the route ahead. The route's part (:func:`route_view`) changes only with the
        queue; a roll-out makes it once per waypoint passed, :func:`slot_features` every frame."""
        c = self.config
        if ops is self._numpy and self.compiled and jit_enabled():
            from motion_env.models.controller_jit import jit_state, step_inputs

            arrays = jit_state(self._text_features(state.text).numpy(), state)
            return step_inputs(arrays, c.input_dim, self._jit_constants())
        view = ops.view(route_view(state.waypoints, state.count, state.queue, c.num_slots))
        frame = ops.array(state.frame.unsqueeze(1).float())
        const = ops.constants(c.step_scale, c.turn_scale, state.pos.dtype)
        pos, theta, vel = (ops.array(x) for x in (state.pos, state.theta, state.vel))
        feats, _ = slot_features(view, pos, theta, frame, c.max_time_to_go, const, ops)
        return ops.cat([ops.array(self._text_features(state.text)), feats, vel * const.half], -1)

    def _text_features(self, text: torch.Tensor) -> torch.Tensor:
        """(B, text_proj) the captions' projection. A rollout keeps one caption tensor for many
        frames, so without gradients the projection is made once per tensor, not every frame."""
        if torch.is_grad_enabled():
            return self.text_proj(text)
        # The weights' version counters change with every optimiser step or load.
        version = (self.text_proj.weight._version, self.text_proj.bias._version)
        cache = self._text_cache
        if cache is None or cache[0] is not text or cache[1] != version:
            cache = self._text_cache = (text, version, self.text_proj(text))  # holding `text` keeps it alive
        return cache[2]

    def _weights(self) -> tuple[torch.Tensor, ...]:
        """The parameters of the input MLP, the GRU and the output MLP, in :meth:`_frame`'s order."""
        return (
            self.inp[0].weight, self.inp[0].bias, self.inp[2].weight, self.inp[2].bias,
            self.gru.weight_ih, self.gru.weight_hh, self.gru.bias_ih, self.gru.bias_hh,
            self.out[0].weight, self.out[0].bias, self.out[2].weight, self.out[2].bias,
        )  # fmt: skip

    def frame_ops(self, batch: int = 1) -> TorchOps:
        """The backend a roll-out of `batch` characters runs on (:mod:`motion_env.models.frame_ops`),
        as :attr:`frame_backend` says. "auto": numpy on the CPU without gradients for a few
        characters (a third of torch's per-operation cost at one frame's sizes), else torch (its
        matrix products win from about 16 rows on: per frame 0.28 / 0.46 ms at one character,
        1.69 / 1.48 ms at 64, numpy / torch; ``motion-env bench``'s controller rows)."""
        numpy_ok = not torch.is_grad_enabled() and self.device.type == "cpu"
        on_numpy = numpy_chosen(
            "PathController.frame_backend", self.frame_backend, batch, NUMPY_MAX_BATCH, numpy_ok,
            "roll-outs without gradients on the CPU", lambda: f"{gradients_state()}, device {self.device}",
        )  # fmt: skip
        return self._numpy if on_numpy else TORCH

    def _frame(
        self,
        ops: TorchOps,
        weights: tuple[Array, ...],
        const: Constants,
        text: Array,
        view: RouteView,
        pos: Array,
        theta: Array,
        vel: Array,
        hidden: Array,
        frame: Array,
    ) -> tuple[Array, Array, Array, Array]:
        """One frame of the network, the arrive gating and the integration: (pos, theta, vel, hidden)
        of the next frame, in `ops`'s arrays. `text` is the (B, text_proj) captions' projection
        (:meth:`_text_features`), `frame` (B, 1) float, `weights` :meth:`_weights` as
        ``ops.weights`` makes them: the modules' forward passes are called as functions (the same
        kernels, without the modules' overhead)."""
        c = self.config
        w1, b1, w2, b2, w_ih, w_hh, b_ih, b_hh, w3, b3, w4, b4 = weights
        wfeat, target = slot_features(view, pos, theta, frame, c.max_time_to_go, const, ops)
        # Velocities in m/s and rad/s are O(1) already; halve them to keep sprints in range.
        x = ops.cat([text, wfeat, vel * const.half], -1)
        z = ops.gelu(ops.linear(ops.gelu(ops.linear(x, w1, b1)), w2, b2))  # self.inp: (B, mlp)
        hidden = ops.gru_cell(z, hidden, w_ih, w_hh, b_ih, b_hh)  # self.gru: (B, hidden)
        raw = ops.linear(ops.gelu(ops.linear(ops.cat([hidden, z], -1), w3, b3)), w4, b4)  # self.out: (B, 3)
        step_xz = raw[:, :2] * const.step_scale  # (B, 2) metres per frame, heading frame
        turn = raw[:, 2] * const.turn_scale  # (B,) radians per frame
        if view.any_final:
            # Arrive gating: near the last waypoint, blend into a direct approach with zero turn. The
            # gate falls quadratically so the approach (linear in the distance) always wins up
            # close. (Elsewhere the gate is 1: the step is the network's, computed as such.)
            dist = ops.norm(target)
            gate = ops.where(view.final, ops.clip(dist / c.arrive_radius, max=1.0) ** 2, 1.0)
            step_xz = gate[:, None] * step_xz + (1.0 - gate[:, None]) * c.seek_rate * target
            turn = gate * turn
        new_theta = theta + turn
        pos = pos + from_heading_frame_torch(step_xz, theta + turn * const.half, ops)
        vel = ops.cat([step_xz, turn[:, None]], -1) * const.fps
        return pos, new_theta, vel, hidden

    def run(
        self, state: ControllerState, num_steps: int, trace: bool = False
    ) -> tuple[ControllerState, Trace]:
        """Advance every character by `num_steps` frames: the closed loop of training and inference.

        Differentiable when gradients are on (then on torch; without them on the CPU the frames
        run on numpy, :meth:`frame_ops`). Per frame only the network and the features that move with
        the character are computed; the route's part of the features (:func:`route_view`) is
        made again only when a waypoint is passed (tested on each character's current target: a
        timed one by its frame, without touching tensors, an untimed one by its distance).

        Returns:
            (the state after the last frame, the :class:`Trace` of frames 1..num_steps: roots
            always, with `trace` also velocities, GRU states and queues).
        """
        c = self.config
        num_steps = int(num_steps)
        ops = self.frame_ops(state.pos.shape[0])
        weights = ops.weights(self._weights())
        if ops is self._numpy and self.compiled and jit_enabled():
            return self._run_compiled(state, num_steps, trace, weights)
        const = ops.constants(c.step_scale, c.turn_scale, state.pos.dtype)
        pos, theta, vel, hidden = (ops.array(x) for x in (state.pos, state.theta, state.vel, state.hidden))
        queue = state.queue
        frames = ops.array(
            (state.frame.unsqueeze(1) + torch.arange(num_steps + 1, device=state.frame.device)).float()
        )
        # With gradients each frame's root (and captions' projection) is made as the frame goes (the
        # order in which the gradients are summed stays that of stepping frame by frame); without,
        # the projection once and the roots all at the end.
        grad = torch.is_grad_enabled()
        text = None if grad else ops.array(self._text_features(state.text))
        roots, poss, thetas, vels, hiddens, queues = [], [], [], [], [], []
        view = due = None
        for n in range(num_steps + 1):
            if n:
                if self._passed(ops, view, due, n, pos):
                    frame = state.frame + n
                    pos_t = ops.tensor(pos, state.pos)
                    queue = next_queue(state.waypoints, state.count, queue, pos_t, frame, c.arrive_radius)
                    view = None
                if grad:
                    roots.append(torch.cat([pos, theta.unsqueeze(1)], dim=-1))
                else:
                    poss.append(pos)
                    thetas.append(theta)
                if trace:
                    vels.append(vel)
                    hiddens.append(hidden)
                    queues.append(queue)
            if n == num_steps:
                break
            if view is None:
                torch_view = route_view(state.waypoints, state.count, queue, c.num_slots)
                # The earliest step at which some character's timed target is due (frames are
                # whole numbers, so the comparison is exact in float64).
                due = n + (torch_view.due.double() - (state.frame + n).double()).min().item()
                view = ops.view(torch_view)
            captions = self._text_features(state.text) if grad else text
            pos, theta, vel, hidden = self._frame(
                ops, weights, const, captions, view, pos, theta, vel, hidden, frames[:, n : n + 1]
            )
        ends = dict(zip(("pos", "theta", "vel", "hidden"), (pos, theta, vel, hidden), strict=True))
        new = replace(
            state,
            **{k: ops.tensor(v, state.pos) for k, v in ends.items()},
            frame=state.frame + num_steps,
            queue=queue,
        )
        if not num_steps:
            return new, Trace(roots=state.pos.new_zeros((state.pos.shape[0], 0, 3)))
        if grad:
            roots = torch.stack(roots, dim=1)
        else:
            roots = ops.tensor(ops.cat([ops.stack(poss, 1), ops.stack(thetas, 1)[..., None]], -1), state.pos)
        if not trace:
            return new, Trace(roots=roots)
        vel, hidden = (ops.tensor(ops.stack(x, 1), state.pos) for x in (vels, hiddens))
        return new, Trace(roots, vel, hidden, torch.stack(queues, dim=1))

    def _jit_constants(self) -> tuple[int, float, float, float, float, float, float]:
        """The configuration's numbers the compiled loops read (:mod:`motion_env.models.controller_jit`)."""
        c = self.config
        return c.num_slots, c.max_time_to_go, c.step_scale, c.turn_scale, c.arrive_radius, c.seek_rate, FPS

    def _run_compiled(
        self, state: ControllerState, num_steps: int, trace: bool, weights: tuple[np.ndarray, ...]
    ) -> tuple[ControllerState, Trace]:
        """:meth:`run`'s frames as one compiled loop (:mod:`motion_env.models.controller_jit`)."""
        from motion_env.models.controller_jit import jit_state, rollout

        arrays = jit_state(self._text_features(state.text).numpy(), state)
        out = rollout(weights, arrays, num_steps, self._jit_constants(), trace)
        device = state.pos.device
        new = replace(
            state,
            **{k: torch.from_numpy(getattr(out, k)).to(device) for k in ("pos", "theta", "vel", "hidden")},
            queue=torch.from_numpy(out.queue).to(device),
            frame=state.frame + num_steps,
        )
        roots = torch.from_numpy(out.roots)
        if not trace:
            return new, Trace(roots=roots)
        return new, Trace(roots, *(torch.from_numpy(x) for x in (out.vels, out.hiddens, out.queues)))

    def _passed(self, ops: TorchOps, view: RouteView, due: float, n: int, pos: Array) -> bool:
        """Whether some character passes its current target at step `n` of a roll-out: a timed one
        by its frame (`due`, the earliest), an untimed one by coming within the arrive radius."""
        if n >= due:
            return True
        if not view.any_near:
            return False
        near = ops.norm(view.xy[:, 0] - ops.detach(pos)) < self.config.arrive_radius
        return bool((near & view.near).any())

    def step(self, state: ControllerState) -> ControllerState:
        """Advance every character by one frame; returns the new state (its ``root`` is the new frame)."""
        return self.run(state, 1)[0]

    def forward(self, state: ControllerState, num_steps: int) -> tuple[torch.Tensor, ControllerState]:
        """Differentiable closed-loop rollout of `num_steps` frames after the state's frame.

        Returns:
            (roots (B, num_steps + 1, 3) including the starting frame, the final state).
        """
        new, trace = self.run(state, num_steps)
        return torch.cat([state.root[:, None], trace.roots], dim=1), new

    # ------------------------------------------------------------------ inference API
    @torch.no_grad()
    def rollout_batch(
        self,
        text_emb: torch.Tensor | np.ndarray,
        waypoints: list[np.ndarray | list | None] | None,
        num_frames: int,
        starts: np.ndarray | None = None,
        generator: torch.Generator | None = None,
    ) -> np.ndarray:
        """Root paths of B characters.

        Args:
            text_emb: (B, text_dim) caption embeddings.
            waypoints: None or B entries (each None or (K, 2)/(K, 3) waypoints).
            num_frames: T, frames of each path including the start frame.
            starts: (B, 3) x, z, heading; default origin facing +Z.
            generator: optional, for the random initial GRU state.

        Returns:
            (B, T, 3) float32 root paths (x, z, unwrapped heading).
        """
        if int(num_frames) < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        state = self.init_state(torch.as_tensor(text_emb), waypoints, starts, generator=generator)
        roots, _ = self(state, int(num_frames) - 1)
        return roots.cpu().numpy().astype(np.float32)

    def rollout(
        self,
        text_emb: torch.Tensor | np.ndarray,
        waypoints: np.ndarray | list | None,
        num_frames: int,
        start: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0),
        generator: torch.Generator | None = None,
    ) -> np.ndarray:
        """Root path of one character: (text_dim,) caption embedding -> (T, 3) x, z, heading."""
        text_emb = torch.as_tensor(text_emb, dtype=torch.float32).reshape(1, -1)
        start = np.asarray(start, dtype=np.float32).reshape(1, 3)
        return self.rollout_batch(text_emb, [waypoints], num_frames, start, generator)[0]

    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())


def _on_numpy(state: ControllerState) -> bool:
    """Whether :meth:`PathController.set_routes` writes `state`'s routes on numpy (CPU tensors)."""
    return state.waypoints.device.type == "cpu"
