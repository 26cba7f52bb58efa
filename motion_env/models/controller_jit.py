"""The path controller's roll-out compiled (numba): the frames of :meth:`PathController.run
<motion_env.models.controller.PathController.run>` without gradients on the CPU, for a few
characters.

On numpy a frame at batch 1 is some sixty array operations on a few hundred numbers, and their
dispatch (one to three microseconds each) is most of the frame's 160-190 us; compiled, the frame is
its six matrix products and a few loops over the numbers: about 40 us. A 200-frame clip's
roll-out (216 frames) drops from 35-40 ms to about 9.

One loop does what the torch/numpy frame (:meth:`PathController._frame
<motion_env.models.controller.PathController._frame>`), the waypoint features
(:func:`~motion_env.models.waypoint_features.slot_features`, the route's part made from the
queue, :func:`~motion_env.models.waypoint_features.route_view`) and the queue
(:func:`~motion_env.models.waypoint_features.next_queue`) do, in the same order on float32
numbers; the two agree to float32 rounding (``tests/models/test_controller_fast.py``). The queue is
tested every frame: a target not reached leaves it as it is, so this is what the roll-out's
test on the current target alone decides.

Compiled once per machine on first use (about 10 s; numba's cache, beside this file, keeps it for
later processes).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit

from motion_env.models.jit_cache import note_first_compile
from motion_env.models.jit_math import gelu

if TYPE_CHECKING:
    import torch

    from motion_env.models.controller_state import ControllerState

__all__ = ["JitRollout", "JitState", "advance_queue", "jit_state", "rollout", "step_inputs"]


class JitRollout(NamedTuple):
    """What :func:`rollout` returns: the state after the last frame and the per-frame trace of
    frames 1..n (roots (B, n, 3) always; vel, hidden, queue (B, n, ...) only when traced, else
    empty)."""

    pos: np.ndarray
    theta: np.ndarray
    vel: np.ndarray
    hidden: np.ndarray
    queue: np.ndarray
    roots: np.ndarray
    vels: np.ndarray
    hiddens: np.ndarray
    queues: np.ndarray


class JitState(NamedTuple):
    """A controller state's arrays as the compiled loops take them (:func:`jit_state`)."""

    text: np.ndarray  # (B, text_proj) the captions' projection
    waypoints: np.ndarray  # (B, K, 3) the routes
    count: np.ndarray  # (B,) their lengths
    queue: np.ndarray  # (B,) current targets
    pos: np.ndarray  # (B, 2)
    theta: np.ndarray  # (B,)
    vel: np.ndarray  # (B, 3)
    hidden: np.ndarray  # (B, hidden)
    frame: np.ndarray  # (B,) each character's current frame index


def jit_state(text: np.ndarray, state: ControllerState) -> JitState:
    """`state`'s arrays (and its captions' projection `text`) contiguous, float32 or int64; the
    ones a roll-out updates in place (queue, pos, theta, vel, hidden) are copies."""
    f32, i64 = np.float32, np.int64
    read = {name: getattr(state, name).numpy() for name in JitState._fields if name != "text"}  # CPU, no grad
    return JitState(
        text=np.ascontiguousarray(text, f32),
        waypoints=np.ascontiguousarray(read["waypoints"], f32),
        count=np.ascontiguousarray(read["count"], i64),
        queue=np.array(read["queue"], i64),
        pos=np.array(read["pos"], f32),
        theta=np.array(read["theta"], f32),
        vel=np.array(read["vel"], f32),
        hidden=np.array(read["hidden"], f32),
        frame=np.ascontiguousarray(read["frame"], i64),
    )


def rollout(
    weights: tuple[np.ndarray, ...],
    state: JitState,
    num_steps: int,
    constants: tuple[int, float, float, float, float, float, float],
    trace: bool,
) -> JitRollout:
    """Roll B characters out `num_steps` frames from `state` (whose arrays it updates).

    Args:
        weights: the controller's parameters as :meth:`NumpyOps.weights
            <motion_env.models.frame_ops.NumpyOps.weights>` holds them (matrices transposed):
            input MLP, GRU, output MLP.
        state: :func:`jit_state`.
        constants: num_slots, max_time_to_go, step_scale, turn_scale, arrive_radius, seek_rate, fps.
        trace: also return every frame's velocity, GRU state and queue.
    """
    note_first_compile(_rollout, "the path controller's roll-out")
    arrays = [np.ascontiguousarray(w, np.float32) for w in weights]
    return JitRollout(*_rollout(*arrays, *state, int(num_steps), *constants, bool(trace)))


def step_inputs(
    state: JitState, width: int, constants: tuple[int, float, float, float, float, float, float]
) -> np.ndarray:
    """(B, width) what the network reads at `state`'s frame (:meth:`PathController.step_inputs
    <motion_env.models.controller.PathController.step_inputs>`): the captions' projection, the
    waypoint features and the last velocity, halved, as the roll-out builds its frame's input;
    `constants` as :func:`rollout`'s."""
    note_first_compile(_step_inputs, "the path controller's step inputs")
    num_slots, max_time_to_go, *_, fps = constants
    s = state
    return _step_inputs(
        s.text, s.waypoints, s.count, s.queue, s.pos, s.theta, s.vel, s.frame,
        int(width), int(num_slots), float(fps), float(max_time_to_go),
    )  # fmt: skip


@njit(cache=True, nogil=True, error_model="numpy")
def _step_inputs(text, waypoints, count, queue, pos, theta, vel, frame, width, num_slots, fps, max_ttg):
    rows, f32 = pos.shape[0], np.float32
    x = np.zeros((rows, width), f32)
    x[:, : text.shape[1]] = text
    target, final = np.zeros((rows, 2), f32), np.zeros(rows, np.bool_)  # (the roll-out's; unread)
    _waypoint_inputs(
        x, text.shape[1], waypoints, count, queue, pos, theta, frame, num_slots, f32(fps),
        f32(max_ttg), target, final,
    )  # fmt: skip
    x[:, text.shape[1] + num_slots * 9 :] = vel * f32(0.5)
    return x


@njit(cache=True, nogil=True, error_model="numpy")
def _sigmoid(x: np.float32) -> np.float32:
    return np.float32(1.0) / (np.float32(1.0) + np.float32(math.exp(-x)))


@njit(cache=True, nogil=True, error_model="numpy")
def _next_queue(waypoints, count, queue, pos, frame, arrive):
    """Each character's target moved past the waypoints frame `frame` (B,) reached (timed: its
    frame; untimed: within `arrive`), never past its last one (next_queue), in place."""
    for b in range(pos.shape[0]):
        q = queue[b]
        while q < count[b] - 1:
            t = waypoints[b, q, 2]
            if math.isnan(t):
                dx, dz = waypoints[b, q, 0] - pos[b, 0], waypoints[b, q, 1] - pos[b, 1]
                if not np.float32(math.sqrt(dx * dx + dz * dz)) < arrive:
                    break
            elif not t <= np.float32(frame[b]):
                break
            q += 1
        queue[b] = q


def advance_queue(state: ControllerState, arrive_radius: float) -> torch.Tensor:
    """:func:`~motion_env.models.waypoint_features.next_queue` of a state's CPU tensors on the
    roll-out's compiled loop: a new (B,) long queue (a restore's new route: a dozen torch
    operations, 0.2 ms of a stream's token, as one loop)."""
    note_first_compile(_next_queue, "the controller's route queue")
    out = state.queue.clone()
    _next_queue(
        np.ascontiguousarray(state.waypoints.numpy(), np.float32),
        np.ascontiguousarray(state.count.numpy(), np.int64),
        out.numpy(),
        np.ascontiguousarray(state.pos.detach().numpy(), np.float32),
        np.ascontiguousarray(state.frame.numpy(), np.int64),
        np.float32(arrive_radius),
    )
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _waypoint_inputs(
    x, at, waypoints, count, queue, pos, theta, frame, num_slots, fps, max_ttg, target, final
):
    """The waypoint features of each character (slot_features) written into x[:, at:], its offset
    to the current target (heading frame) into `target` and whether that is its last into `final`."""
    f32 = np.float32
    quarter, one, zero = f32(0.25), f32(1.0), f32(0.0)
    for b in range(pos.shape[0]):
        c, s = f32(math.cos(theta[b])), f32(math.sin(theta[b]))
        last = count[b] - 1
        has_route = count[b] > 0
        final[b] = has_route and queue[b] == last
        now = f32(frame[b])
        prev_x, prev_z = pos[b, 0], pos[b, 1]
        for k in range(num_slots):
            slot = min(queue[b] + k, max(last, 0))
            wx, wz, wt = waypoints[b, slot, 0], waypoints[b, slot, 1], waypoints[b, slot, 2]
            dx, dz = wx - pos[b, 0], wz - pos[b, 1]
            lateral, forward = dx * c - dz * s, dx * s + dz * c
            dist = f32(math.sqrt(lateral * lateral + forward * forward))
            timed = not math.isnan(wt)
            ttg = min(max((wt - now) / fps, zero), max_ttg) if timed else zero
            speed = min(dist / (ttg + quarter), f32(10.0)) if timed else zero
            sx, sz = wx - prev_x, wz - prev_z
            seg = f32(math.sqrt(sx * sx + sz * sz))
            prev_x, prev_z = wx, wz
            if k == 0:
                target[b, 0], target[b, 1] = lateral, forward
            j = at + 9 * k
            if not has_route:
                x[b, j : j + 9] = zero
                continue
            x[b, j], x[b, j + 1], x[b, j + 2] = (
                lateral / max(dist, one),
                forward / max(dist, one),
                f32(math.log1p(dist)),
            )
            x[b, j + 3], x[b, j + 4], x[b, j + 5] = one if timed else zero, ttg, speed
            x[b, j + 6], x[b, j + 7], x[b, j + 8] = one if slot == last else zero, one, f32(math.log1p(seg))


@njit(cache=True, nogil=True, error_model="numpy")
def _gru_cell(z, hidden, w_ih, w_hh, b_ih, b_hh):
    """torch.gru_cell's update of `hidden` (gates reset, update, new), in place."""
    n = hidden.shape[1]
    gi, gh = z @ w_ih + b_ih, hidden @ w_hh + b_hh
    for b in range(hidden.shape[0]):
        for j in range(n):
            reset = _sigmoid(gi[b, j] + gh[b, j])
            update = _sigmoid(gi[b, n + j] + gh[b, n + j])
            new = np.float32(math.tanh(gi[b, 2 * n + j] + reset * gh[b, 2 * n + j]))
            hidden[b, j] = new + update * (hidden[b, j] - new)


@njit(cache=True, nogil=True, error_model="numpy")
def _integrate(raw, pos, theta, vel, target, final, step_scale, turn_scale, arrive, seek, fps):
    """The network's step `raw` (B, 3) gated near the last waypoint and integrated into pos,
    theta and vel, in place."""
    half, one = np.float32(0.5), np.float32(1.0)
    for b in range(pos.shape[0]):
        step_x, step_z, turn = raw[b, 0] * step_scale, raw[b, 1] * step_scale, raw[b, 2] * turn_scale
        if final[b]:  # arrive gating: a direct approach with zero turn
            tx, tz = target[b, 0], target[b, 1]
            gate = min(np.float32(math.sqrt(tx * tx + tz * tz)) / arrive, one) ** 2
            step_x = gate * step_x + (one - gate) * seek * tx
            step_z = gate * step_z + (one - gate) * seek * tz
            turn = gate * turn
        mid = theta[b] + turn * half
        c, s = np.float32(math.cos(mid)), np.float32(math.sin(mid))
        pos[b, 0] = pos[b, 0] + (step_x * c + step_z * s)
        pos[b, 1] = pos[b, 1] + (-step_x * s + step_z * c)
        theta[b] = theta[b] + turn
        vel[b, 0], vel[b, 1], vel[b, 2] = step_x * fps, step_z * fps, turn * fps


@njit(cache=True, nogil=True, error_model="numpy")
def _rollout(  # noqa: PLR0913 (one compiled loop: the parameters are the frame's arrays)
    w1, b1, w2, b2, w_ih, w_hh, b_ih, b_hh, w3, b3, w4, b4,
    text, waypoints, count, queue, pos, theta, vel, hidden, frame, num_steps,
    num_slots, max_time_to_go, step_scale, turn_scale, arrive_radius, seek_rate, fps, trace,
):  # fmt: skip
    f32 = np.float32
    rows, width, n_hidden = pos.shape[0], text.shape[1], hidden.shape[1]
    step_scale, turn_scale, fps = f32(step_scale), f32(turn_scale), f32(fps)
    arrive, seek, max_ttg = f32(arrive_radius), f32(seek_rate), f32(max_time_to_go)
    roots = np.empty((rows, num_steps, 3), f32)
    traced = num_steps if trace else 0
    vels = np.empty((rows, traced, 3), f32)
    hiddens = np.empty((rows, traced, n_hidden), f32)
    queues = np.empty((rows, traced), np.int64)
    x = np.zeros((rows, w1.shape[0]), f32)  # the network's input: caption, waypoints, last step
    x[:, :width] = text
    last_in = width + num_slots * 9  # the last velocity's columns
    target = np.zeros((rows, 2), f32)  # offset to the current target, heading frame
    final = np.zeros(rows, np.bool_)
    for n in range(num_steps + 1):
        if n:
            _next_queue(waypoints, count, queue, pos, frame + n, arrive)
            for b in range(rows):
                roots[b, n - 1, 0], roots[b, n - 1, 1], roots[b, n - 1, 2] = pos[b, 0], pos[b, 1], theta[b]
                if trace:
                    vels[b, n - 1], hiddens[b, n - 1], queues[b, n - 1] = vel[b], hidden[b], queue[b]
        if n == num_steps:
            break
        _waypoint_inputs(
            x, width, waypoints, count, queue, pos, theta, frame + n, num_slots, fps, max_ttg, target, final
        )
        x[:, last_in:] = vel * f32(0.5)
        z = gelu(gelu(x @ w1 + b1) @ w2 + b2)  # the input MLP
        _gru_cell(z, hidden, w_ih, w_hh, b_ih, b_hh)
        raw = gelu(np.concatenate((hidden, z), axis=1) @ w3 + b3) @ w4 + b4  # the output MLP
        _integrate(raw, pos, theta, vel, target, final, step_scale, turn_scale, arrive, seek, fps)
    return pos, theta, vel, hidden, queue, roots, vels, hiddens, queues
