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

import numpy as np
import torch
from torch import nn

from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_waypoints
from motion_env.motion.validation import check_above, check_at_least, check_interval

# Features per waypoint slot (see PathController.waypoint_features).
WAYPOINT_FEATURES = 9


@dataclass
class ControllerConfig:
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

    text_dim: int = 384
    text_proj: int = 64
    num_slots: int = 4
    hidden: int = 384
    mlp: int = 256
    arrive_radius: float = 0.3
    seek_rate: float = 0.25
    step_scale: float = 0.1
    turn_scale: float = 0.1
    max_time_to_go: float = 10.0
    h0_noise: float = 0.3

    def __post_init__(self) -> None:
        check_at_least(self, 1, "text_dim", "text_proj", "num_slots", "hidden", "mlp")
        check_above(self, 0, "arrive_radius", "step_scale", "turn_scale", "max_time_to_go")
        check_interval(self, "(0, 1]", "seek_rate")
        check_at_least(self, 0, "h0_noise")

    @property
    def input_dim(self) -> int:
        return self.text_proj + self.num_slots * WAYPOINT_FEATURES + 3


def to_heading_frame_torch(vec: torch.Tensor, theta: torch.Tensor) -> torch.Tensor:
    """Torch twin of :func:`motion_env.motion.to_heading_frame`: world (..., 2) -> (lateral, forward)."""
    c, s = torch.cos(theta), torch.sin(theta)
    return torch.stack([vec[..., 0] * c - vec[..., 1] * s, vec[..., 0] * s + vec[..., 1] * c], dim=-1)


def from_heading_frame_torch(vec: torch.Tensor, theta: torch.Tensor) -> torch.Tensor:
    """Torch twin of :func:`motion_env.motion.from_heading_frame`: (lateral, forward) -> world (..., 2)."""
    c, s = torch.cos(theta), torch.sin(theta)
    return torch.stack([vec[..., 0] * c + vec[..., 1] * s, -vec[..., 0] * s + vec[..., 1] * c], dim=-1)


@dataclass
class ControllerState:
    """Everything a rollout carries from one frame to the next, batched over B characters.

    Attributes:
        pos: (B, 2) world x, z of the current frame.
        theta: (B,) heading of the current frame (unwrapped).
        vel: (B, 3) the last step as (lateral m/s, forward m/s, turn rad/s) in the heading frame.
        hidden: (B, hidden) GRU state.
        frame: (B,) long, index of the current frame in each character's episode.
        text: (B, text_dim) caption embeddings.
        waypoints: (B, K, 3) x, z, frame index (NaN = untimed), padded past ``count``.
        count: (B,) long, number of real waypoints (0 = no route: follow the caption).
        queue: (B,) long, index of the current target waypoint.
    """

    pos: torch.Tensor
    theta: torch.Tensor
    vel: torch.Tensor
    hidden: torch.Tensor
    frame: torch.Tensor
    text: torch.Tensor
    waypoints: torch.Tensor
    count: torch.Tensor
    queue: torch.Tensor

    @property
    def root(self) -> torch.Tensor:
        """(B, 3) x, z, heading of the current frame."""
        return torch.cat([self.pos, self.theta[:, None]], dim=-1)


def pack_waypoints(
    waypoints: list[np.ndarray | list | None] | None, batch: int, device: torch.device | str = "cpu"
) -> tuple[torch.Tensor, torch.Tensor]:
    """Validate per-character waypoints and pad them into one tensor.

    Args:
        waypoints: None (no route for anyone) or a list of B entries, each None or a (K, 2)/(K, 3)
            array accepted by :func:`motion_env.motion.trajectory.validate_waypoints`.
        batch: B.

    Returns:
        ((B, Kmax, 3) float32 padded by repeating the last row, (B,) long counts).
    """
    if waypoints is None:
        waypoints = [None] * batch
    if len(waypoints) != batch:
        raise ValueError(f"got {len(waypoints)} waypoint lists for {batch} characters")
    rows = [None if w is None else validate_waypoints(w) for w in waypoints]
    kmax = max([1] + [len(r) for r in rows if r is not None])
    out = np.zeros((batch, kmax, 3), np.float32)
    counts = np.zeros(batch, np.int64)
    for b, r in enumerate(rows):
        if r is None:
            continue
        out[b, : len(r)] = r
        out[b, len(r) :] = r[-1]
        counts[b] = len(r)
    return torch.from_numpy(out).to(device), torch.from_numpy(counts).to(device)


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
        self, state: ControllerState, rows: Sequence[int], routes: Sequence[np.ndarray | list | None]
    ) -> ControllerState:
        """Replace the routes of several characters at once: ``routes[n]`` for character ``rows[n]``
        (None: no route). The others keep theirs; the tensor of waypoints only ever grows, its
        padding repeats each route's last waypoint as :func:`pack_waypoints` does."""
        b = state.pos.shape[0]
        rows = [int(i) for i in rows]
        for i in rows:
            if not 0 <= i < b:
                raise IndexError(f"character index {i} out of range for a batch of {b}")
        new = [None if r is None else validate_waypoints(r) for r in routes]
        width = max([state.waypoints.shape[1]] + [len(r) for r in new if r is not None])
        wp = state.waypoints
        if width > wp.shape[1]:
            wp = torch.cat([wp, wp[:, -1:].expand(-1, width - wp.shape[1], -1)], dim=1)
        wp, count = wp.clone(), state.count.clone()
        for i, r in zip(rows, new):
            if r is None:
                wp[i], count[i] = 0.0, 0
            else:
                route = torch.as_tensor(r, dtype=wp.dtype, device=wp.device)
                wp[i, : len(r)], wp[i, len(r) :], count[i] = route, route[-1], len(r)
        queue = state.queue.clone()
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
        queue = state.queue.clone()
        batch = torch.arange(queue.shape[0], device=queue.device)
        pos = state.pos.detach()
        frame = state.frame.to(torch.float32)
        for _ in range(state.waypoints.shape[1]):
            wp = state.waypoints[batch, queue]  # (B, 3)
            timed = ~torch.isnan(wp[:, 2])
            passed_time = timed & (wp[:, 2].nan_to_num(0.0) <= frame)
            near = ~timed & ((wp[:, :2] - pos).norm(dim=-1) < self.config.arrive_radius)
            move = (passed_time | near) & (queue < state.count - 1)
            if not move.any():
                break
            queue = queue + move.long()
        return replace(state, queue=queue)

    # ------------------------------------------------------------------ the network
    def waypoint_features(self, state: ControllerState) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Features of the next `num_slots` waypoints relative to the character.

        Returns:
            (features (B, num_slots * 9), offset to the current target (B, 2) in the heading frame,
            final (B,) bool: the current target is the last waypoint).
            Per slot: the offset (lateral, forward) / max(dist, 1) (a direction far away, the
            offset in metres up close), log(1 + dist), timed flag, time to go (s), the speed a
            timed waypoint asks for (m/s), is-last flag, valid flag (any route at all), and
            log(1 + the distance from the previous slot) for the shape of the route ahead.
        """
        c = self.config
        b = state.pos.shape[0]
        batch = torch.arange(b, device=state.pos.device)
        slots = state.queue[:, None] + torch.arange(c.num_slots, device=state.pos.device)[None]
        slots = torch.minimum(slots, (state.count - 1).clamp(min=0)[:, None])  # (B, S)
        wp = state.waypoints[batch[:, None], slots]  # (B, S, 3)
        offset = to_heading_frame_torch(wp[..., :2] - state.pos[:, None], state.theta[:, None])  # (B, S, 2)
        dist = offset.norm(dim=-1)  # (B, S)
        timed = ~torch.isnan(wp[..., 2])
        ttg = ((wp[..., 2].nan_to_num(0.0) - state.frame[:, None].float()) / FPS).clamp(0.0, c.max_time_to_go)
        ttg = torch.where(timed, ttg, torch.zeros_like(ttg))
        speed = torch.where(timed, dist / (ttg + 0.25), torch.zeros_like(dist)).clamp(max=10.0)
        is_last = (slots == (state.count - 1)[:, None]).float()
        valid = (state.count > 0)[:, None].expand(b, c.num_slots).float()
        prev = torch.cat([state.pos[:, None], wp[:, :-1, :2]], dim=1)
        seg = (wp[..., :2] - prev).norm(dim=-1)
        feats = torch.stack(
            [
                offset[..., 0] / dist.clamp(min=1.0),
                offset[..., 1] / dist.clamp(min=1.0),
                torch.log1p(dist),
                timed.float(),
                ttg,
                speed,
                is_last,
                valid,
                torch.log1p(seg),
            ],
            dim=-1,
        )  # (B, S, 9)
        feats = feats * valid[..., None]
        final = (state.count > 0) & (state.queue == state.count - 1)
        return feats.reshape(b, -1), offset[:, 0], final

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

    def step(self, state: ControllerState) -> ControllerState:
        """Advance every character by one frame; returns the new state (its ``root`` is the new frame)."""
        c = self.config
        wfeat, target, final = self.waypoint_features(state)
        # Velocities in m/s and rad/s are O(1) already; halve them to keep sprints in range.
        x = torch.cat([self._text_features(state.text), wfeat, 0.5 * state.vel], dim=-1)
        z = self.inp(x)  # (B, mlp)
        hidden = self.gru(z, state.hidden)  # (B, hidden)
        raw = self.out(torch.cat([hidden, z], dim=-1))  # (B, 3)
        step_xz = raw[:, :2] * c.step_scale  # (B, 2) metres per frame, heading frame
        turn = raw[:, 2] * c.turn_scale  # (B,) radians per frame
        # Arrive gating: near the last waypoint, blend into a direct approach with zero turn. The
        # gate falls quadratically so the approach (linear in the distance) always wins up close.
        dist = target.norm(dim=-1)
        gate = torch.where(final, (dist / c.arrive_radius).clamp(max=1.0) ** 2, torch.ones_like(dist))
        step_xz = gate[:, None] * step_xz + (1.0 - gate[:, None]) * c.seek_rate * target
        turn = gate * turn
        theta = state.theta + turn
        pos = state.pos + from_heading_frame_torch(step_xz, state.theta + 0.5 * turn)
        vel = torch.cat([step_xz, turn[:, None]], dim=-1) * FPS
        new = replace(state, pos=pos, theta=theta, vel=vel, hidden=hidden, frame=state.frame + 1)
        return self._advance_queue(new)

    def forward(self, state: ControllerState, num_steps: int) -> tuple[torch.Tensor, ControllerState]:
        """Differentiable closed-loop rollout of `num_steps` frames after the state's frame.

        Returns:
            (roots (B, num_steps + 1, 3) including the starting frame, the final state).
        """
        roots = [state.root]
        for _ in range(num_steps):
            state = self.step(state)
            roots.append(state.root)
        return torch.stack(roots, dim=1), state

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
