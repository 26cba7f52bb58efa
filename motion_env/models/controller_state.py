"""The path controller's state: what a roll-out carries from one frame to the next, batched over
characters, with row-wise access (the stream advances, restores and resets some characters only).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import torch


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

    def take(self, rows: torch.Tensor) -> ControllerState:
        """The state of `rows` only."""
        return ControllerState(**{f.name: getattr(self, f.name)[rows] for f in fields(ControllerState)})

    def put(self, rows: torch.Tensor, sub: ControllerState) -> ControllerState:
        """A copy of this state with `rows` replaced by the rows of `sub` (waypoints padded to the
        wider of the two by repeating the last slot, the controller's own padding)."""
        values = {}
        for f in fields(ControllerState):
            full, part = getattr(self, f.name), getattr(sub, f.name)
            if f.name == "waypoints":
                k = max(full.shape[1], part.shape[1])
                full, part = pad_waypoints(full, k), pad_waypoints(part, k)
            full = full.clone()
            full[rows] = part.to(full.dtype)
            values[f.name] = full
        return ControllerState(**values)

    @property
    def root(self) -> torch.Tensor:
        """(B, 3) x, z, heading of the current frame."""
        return torch.cat([self.pos, self.theta[:, None]], dim=-1)


@dataclass
class Trace:
    """Per-frame outputs of :meth:`PathController.run` over frames 1..n of the rollout.

    Attributes:
        roots: (B, n, 3) x, z, heading.
        vel, hidden, queue: (B, n, 3), (B, n, hidden), (B, n) long, or None unless traced.
    """

    roots: torch.Tensor
    vel: torch.Tensor | None = None
    hidden: torch.Tensor | None = None
    queue: torch.Tensor | None = None


def pad_waypoints(wp: Any, k: int, copy: bool = False) -> Any:
    """(B, K, 3) -> (B, k, 3) by repeating the last slot (the controller's own padding), a tensor
    or a numpy array (`copy`: a numpy array never shares the input's memory)."""
    if wp.shape[1] >= k:
        return wp.copy() if copy else wp
    if isinstance(wp, np.ndarray):
        return np.concatenate([wp, np.repeat(wp[:, -1:], k - wp.shape[1], axis=1)], axis=1)
    return torch.cat([wp, wp[:, -1:].expand(-1, k - wp.shape[1], -1)], dim=1)


# The fields of ControllerState a StateRing keeps per frame (the caption and the route stay as
# they are: a roll-back keeps the current ones).
_RECORDED = ("pos", "theta", "vel", "hidden", "queue")


class StateRing:
    """The controller's state of B characters at each of their last `size` frames, indexed by
    frame % size: the stream rolls a character back to its last decoded frame when its caption or
    route changes, and reads the controller's root path of the frames ahead.

    On the CPU the frames are kept in numpy arrays (the fields below are torch views of them) and
    read and written with numpy's indexing: a token's bookkeeping is a dozen gathers and scatters
    of a few rows, each about a fifth of torch's cost at that size; on another device, in torch
    tensors there. Either way the same numbers.

    Attributes:
        hidden, pos, theta, vel, queue: (B, size, ...) tensors, the fields of
            :class:`ControllerState` per frame.
        roots: (B, size, 3) float32 numpy, the controller's x, z, heading per frame.
    """

    def __init__(self, batch: int, size: int, hidden: int, device: torch.device | str) -> None:
        self.size = size
        self._on_cpu = torch.device(device).type == "cpu"
        self.hidden = torch.zeros(batch, size, hidden, device=device)
        self.pos = torch.zeros(batch, size, 2, device=device)
        self.theta = torch.zeros(batch, size, device=device)
        self.vel = torch.zeros(batch, size, 3, device=device)
        self.queue = torch.zeros(batch, size, dtype=torch.long, device=device)
        self.roots = np.zeros((batch, size, 3), np.float32)
        # Where the fields are indexed: numpy views of the tensors on the CPU, the tensors elsewhere.
        self._fields = {name: self._host(getattr(self, name)) for name in _RECORDED}

    def _host(self, x: torch.Tensor) -> Any:
        """`x` as the ring indexes it: a numpy view on the CPU, the tensor itself elsewhere."""
        return x.numpy() if self._on_cpu else x

    def _tensor(self, x: Any) -> torch.Tensor:
        """A gathered `x` back as a tensor (on the ring's device)."""
        return torch.from_numpy(x) if self._on_cpu else x

    def record(self, rows: torch.Tensor, state: ControllerState) -> None:
        """Store the state of `rows` (the rows of `state`) at their current frame."""
        rows_h, slot = self._host(rows), self._host(state.frame.to(rows.device) % self.size)
        for name in _RECORDED:
            self._fields[name][rows_h, slot] = self._host(getattr(state, name))
        self.roots[_numpy(rows_h), _numpy(slot)] = _numpy(state.root)

    def record_trace(self, rows: torch.Tensor, first: torch.Tensor, trace: Trace) -> None:
        """Store frames first+1 .. first+n of `rows` (a controller run's trace)."""
        total = trace.roots.shape[1]
        n = min(total, self.size)  # older frames would be overwritten anyway
        rows_h, first_h = self._host(rows), self._host(first.to(rows.device))
        hidden, roots, vel, queue = (
            self._host(x[:, total - n :]) for x in (trace.hidden, trace.roots, trace.vel, trace.queue)
        )
        slot = (first_h[:, None] + _arange(first_h, n)[None] + (total - n + 1)) % self.size  # (N, n)
        at = (rows_h[:, None], slot)
        fields = self._fields
        fields["hidden"][at], fields["vel"][at], fields["queue"][at] = hidden, vel, queue
        fields["pos"][at], fields["theta"][at] = roots[..., :2], roots[..., 2]
        self.roots[_numpy(rows_h)[:, None], _numpy(slot)] = _numpy(roots)

    def record_roots(self, rows: np.ndarray, after: np.ndarray, roots: np.ndarray, count: np.ndarray) -> None:
        """Store the roots only (not a controller state: a prediction, never restored) of frames
        after+1 .. after+count[n] of each row n: `roots` (N, H, 3), count (N,) <= H."""
        k = np.arange(roots.shape[1])
        keep = k[None] < count[:, None]  # (N, H)
        slots = (after[:, None] + 1 + k[None]) % self.size
        at = np.broadcast_to(rows[:, None], slots.shape)
        self.roots[at[keep], slots[keep]] = roots[keep]

    def set_queue(self, rows: torch.Tensor, frames: torch.Tensor, queue: torch.Tensor) -> None:
        """Overwrite the recorded queue of `rows` at `frames` (a route replaced there)."""
        self._fields["queue"][self._host(rows), self._host(frames % self.size)] = self._host(queue)

    def queue_at(self, rows: np.ndarray, frames: np.ndarray) -> list[int]:
        """The recorded queue of each of `rows` at its frame of `frames`."""
        queue = self._fields["queue"]
        if self._on_cpu:
            return queue[rows, frames % self.size].tolist()
        device = queue.device
        return queue[
            torch.as_tensor(rows, device=device), torch.as_tensor(frames % self.size, device=device)
        ].tolist()

    def restore(self, state: ControllerState, rows: torch.Tensor, frames: torch.Tensor) -> ControllerState:
        """`state` with `rows` rolled back to their recorded state at `frames` (one each)."""
        rows_h, slots = self._host(rows), self._host(frames % self.size)
        recorded = {  # gathered: new arrays
            name: self._tensor(self._fields[name][rows_h, slots]) for name in _RECORDED
        }
        # Every row in order (a vector env's learners): no take and put, the caption and route as they are.
        if len(rows) == len(state.frame) and bool((rows_h == _arange(rows_h, len(rows_h))).all()):
            return replace(state, **recorded, frame=frames.to(state.frame.dtype))
        sub = state.take(rows)
        for name, value in recorded.items():
            setattr(sub, name, value)
        sub.frame = frames
        return state.put(rows, sub)


def _numpy(x: Any) -> np.ndarray:
    """`x` as a numpy array (a tensor copied to the host)."""
    return x if isinstance(x, np.ndarray) else x.cpu().numpy()


def _arange(like: Any, n: int) -> Any:
    """0 .. n-1 as `like`'s kind of array (numpy, or a tensor on its device)."""
    return np.arange(n) if isinstance(like, np.ndarray) else torch.arange(n, device=like.device)
