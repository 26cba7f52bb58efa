"""The controller's rollout loop (PathController.run) against the frame-by-frame form it replaced:
the same roots, states and gradients to the last bit on torch (to float32 rounding on the numpy
backend of roll-outs without gradients), the vectorised waypoint queue against its loop, and the
trace the stream records."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from motion_env.models.controller import ControllerConfig, ControllerState, PathController
from motion_env.models.frame_ops import TORCH
from motion_env.models.waypoint_features import from_heading_frame_torch, next_queue, to_heading_frame_torch
from motion_env.motion.skeleton import FPS

TINY = ControllerConfig(text_dim=16, text_proj=8, hidden=32, mlp=32)


def _tiny(seed: int = 0, scale: float = 0.5) -> PathController:
    torch.manual_seed(seed)
    return PathController.drifting(TINY, scale).eval()


# ---------------------------------------------------------------------------------- the reference
# The per-frame step as it was before PathController.run: every feature, the queue loop and the
# module calls made afresh each frame. The run loop must give the same numbers.


def _reference_queue(model: PathController, state: ControllerState) -> torch.Tensor:
    queue = state.queue.clone()
    batch = torch.arange(queue.shape[0])
    frame = state.frame.to(torch.float32)
    for _ in range(state.waypoints.shape[1]):
        wp = state.waypoints[batch, queue]
        timed = ~torch.isnan(wp[:, 2])
        passed_time = timed & (wp[:, 2].nan_to_num(0.0) <= frame)
        near = ~timed & ((wp[:, :2] - state.pos.detach()).norm(dim=-1) < model.config.arrive_radius)
        move = (passed_time | near) & (queue < state.count - 1)
        if not move.any():
            break
        queue = queue + move.long()
    return queue


def _reference_step(model: PathController, state: ControllerState) -> ControllerState:
    c = model.config
    b = state.pos.shape[0]
    batch = torch.arange(b)
    slots = state.queue[:, None] + torch.arange(c.num_slots)[None]
    slots = torch.minimum(slots, (state.count - 1).clamp(min=0)[:, None])
    wp = state.waypoints[batch[:, None], slots]
    offset = to_heading_frame_torch(wp[..., :2] - state.pos[:, None], state.theta[:, None])
    dist = offset.norm(dim=-1)
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
    ) * valid[..., None]  # fmt: skip
    final = (state.count > 0) & (state.queue == state.count - 1)
    target = offset[:, 0]
    x = torch.cat([model.text_proj(state.text), feats.reshape(b, -1), 0.5 * state.vel], dim=-1)
    z = model.inp(x)
    hidden = model.gru(z, state.hidden)
    raw = model.out(torch.cat([hidden, z], dim=-1))
    step_xz = raw[:, :2] * c.step_scale
    turn = raw[:, 2] * c.turn_scale
    dist = target.norm(dim=-1)
    gate = torch.where(final, (dist / c.arrive_radius).clamp(max=1.0) ** 2, torch.ones_like(dist))
    step_xz = gate[:, None] * step_xz + (1.0 - gate[:, None]) * c.seek_rate * target
    turn = gate * turn
    theta = state.theta + turn
    pos = state.pos + from_heading_frame_torch(step_xz, state.theta + 0.5 * turn)
    vel = torch.cat([step_xz, turn[:, None]], dim=-1) * FPS
    new = replace(state, pos=pos, theta=theta, vel=vel, hidden=hidden, frame=state.frame + 1)
    return replace(new, queue=_reference_queue(model, new))


def _routes(rng: np.random.Generator, b: int) -> list[np.ndarray | None]:
    """Every kind of route: none, untimed, timed, mixed, and one that starts on its first point."""
    out: list[np.ndarray | None] = []
    for i in range(b):
        k = int(rng.integers(1, 6))
        pts = np.cumsum(rng.normal(size=(k, 2)), 0).astype(np.float32)
        times = np.cumsum(rng.integers(3, 25, size=k)).astype(np.float32)[:, None]
        kind = i % 5
        if kind == 0:
            out.append(None)
        elif kind == 1:
            out.append(pts)
        else:
            wp = np.concatenate([pts * (0.1 if kind == 4 else 1.0), times], 1)
            if kind == 3:
                wp[rng.random(k) < 0.5, 2] = np.nan
            out.append(wp)
    return out


@pytest.mark.parametrize("backend", ["torch", "numpy", "compiled"])
@pytest.mark.parametrize("batch", [1, 3, 7])
def test_run_equals_the_frame_by_frame_reference(batch: int, backend: str) -> None:
    model = _tiny(batch)
    if backend == "torch":  # what a roll-out on a GPU runs without gradients
        model.frame_backend = "torch"
    model.compiled = backend == "compiled"  # the numpy backend as one compiled loop, or frame by frame
    rng = np.random.default_rng(batch)
    emb = torch.randn(batch, 16)
    starts = rng.normal(size=(batch, 3)).astype(np.float32)
    with torch.no_grad():
        state = model.init_state(emb, _routes(rng, batch), starts, generator=torch.Generator().manual_seed(1))
        roots, new = model(state, 90)
        ref, frames = state, [state.root]
        for _ in range(90):
            ref = _reference_step(model, ref)
            frames.append(ref.root)
    if backend == "torch":
        same = torch.equal
    else:  # float32 rounding of other kernels, not carried away by the closed loop
        with torch.no_grad():
            assert model.frame_ops(batch) is model._numpy
        same = lambda a, b: torch.allclose(a, b, rtol=0.0, atol=2e-5)  # noqa: E731
    assert same(roots, torch.stack(frames, dim=1))
    for name in ("pos", "theta", "vel", "hidden"):
        assert same(getattr(new, name), getattr(ref, name)), name
    for name in ("frame", "queue"):
        assert torch.equal(getattr(new, name), getattr(ref, name)), name


def test_gradients_equal_the_frame_by_frame_reference() -> None:
    model = _tiny(4).train()
    rng = np.random.default_rng(4)
    emb = torch.randn(6, 16)
    state = model.init_state(emb, _routes(rng, 6), generator=torch.Generator().manual_seed(2))

    def grads(roll) -> tuple[torch.Tensor, list[torch.Tensor]]:
        model.zero_grad()
        roots = roll()
        (roots.square().sum() + roots[..., 2].sin().sum()).backward()
        return roots.detach(), [p.grad.clone() for p in model.parameters()]

    def reference() -> torch.Tensor:
        s, frames = state, [state.root]
        for _ in range(40):
            s = _reference_step(model, s)
            frames.append(s.root)
        return torch.stack(frames, dim=1)

    roots, g = grads(lambda: model(state, 40)[0])
    ref_roots, ref_g = grads(reference)
    assert torch.equal(roots, ref_roots)
    assert all(torch.equal(a, b) for a, b in zip(g, ref_g, strict=True))


def test_waypoint_queue_equals_its_loop() -> None:
    """next_queue and its compiled twin (controller_jit.advance_queue) against the loop they replace."""
    from motion_env.models.controller_jit import advance_queue

    model = _tiny()
    rng = np.random.default_rng(0)
    for trial in range(40):
        b = int(rng.integers(1, 9))
        state = model.init_state(
            torch.zeros(b, 16), _routes(rng, b), rng.normal(size=(b, 3)).astype(np.float32)
        )
        k = state.waypoints.shape[1]
        queue = torch.minimum(
            torch.from_numpy(rng.integers(0, k, size=b)), (state.count - 1).clamp(min=0)
        )  # any queue a rollout can hold
        state = replace(
            state,
            queue=queue,
            frame=torch.from_numpy(rng.integers(0, 80, size=b)),
            pos=state.waypoints[torch.arange(b), queue, :2] + torch.randn(b, 2) * 0.3,
        )
        got = next_queue(state.waypoints, state.count, state.queue, state.pos, state.frame, 0.3)
        assert torch.equal(got, _reference_queue(model, state)), trial
        compiled = advance_queue(state, 0.3)
        assert torch.equal(compiled, got) and compiled.dtype == got.dtype, trial


def test_trace_holds_every_frame_of_stepping() -> None:
    model = _tiny(2)
    rng = np.random.default_rng(2)
    emb = torch.randn(4, 16)
    with torch.no_grad():
        state = model.init_state(emb, _routes(rng, 4), generator=torch.Generator().manual_seed(3))
        new, trace = model.run(state, 30, trace=True)
        s = state
        for n in range(30):
            s = model.step(s)
            assert torch.equal(trace.roots[:, n], s.root)
            assert torch.equal(trace.vel[:, n], s.vel) and torch.equal(trace.hidden[:, n], s.hidden)
            assert torch.equal(trace.queue[:, n], s.queue)
        assert torch.equal(new.root, s.root) and torch.equal(new.frame, s.frame)
        empty, nothing = model.run(state, 0)
        assert nothing.roots.shape == (4, 0, 3) and torch.equal(empty.root, state.root)


def test_a_ring_restores_every_row_as_it_restores_some() -> None:
    """StateRing.restore of every row in order (a vector env's learners: no take / put) gives the
    state that restoring the rows one group at a time gives."""
    from motion_env.models.controller_state import StateRing

    model = _tiny(3)
    rng = np.random.default_rng(3)
    with torch.no_grad():
        state = model.init_state(
            torch.randn(4, 16), _routes(rng, 4), generator=torch.Generator().manual_seed(4)
        )
        ring = StateRing(4, 16, TINY.hidden, "cpu")
        every = torch.arange(4)
        ring.record(every, state)
        first = state.frame
        state, trace = model.run(state, 10, trace=True)
        ring.record_trace(every, first, trace)
    frames = torch.tensor([3, 7, 0, 9])
    whole = ring.restore(state, every, frames)
    by_parts = ring.restore(
        ring.restore(state, torch.tensor([2, 0]), frames[[2, 0]]), torch.tensor([1, 3]), frames[[1, 3]]
    )
    for name in ("pos", "theta", "vel", "hidden", "queue", "frame", "text", "waypoints", "count"):
        torch.testing.assert_close(
            getattr(whole, name), getattr(by_parts, name), rtol=0, atol=0, equal_nan=True
        )
    assert torch.equal(whole.hidden[1], trace.hidden[1, 6])  # frame 7: the 7th frame of the run


def test_routes_are_set_alike_on_numpy_and_on_torch(monkeypatch: pytest.MonkeyPatch) -> None:
    """set_routes writes a CPU state's routes on numpy and other devices' on torch (forced here on
    the CPU): the same waypoints (padded by their last, the tensor widened), counts and queues,
    a row given twice taking its last route, a row cleared to no route."""
    import motion_env.models.controller as controller_module

    model = _tiny(4)
    rng = np.random.default_rng(8)
    with torch.no_grad():
        state = model.init_state(
            torch.randn(5, 16), _routes(rng, 5), generator=torch.Generator().manual_seed(9)
        )
        state, _ = model.run(state, 12)
        long = np.array(
            [[0.5, 0.5, 20], [1, 1, 30], [2, 2, 40], [3, 3, 50], [4, 4, 60], [5, 5, 70], [6, 6, 80]],
            np.float32,
        )
        state = replace(state, queue=torch.tensor([0, 1, 2, 0, 1]))  # targets past the first
        rows, routes = [4, 1, 4, 2], [long, np.array([[0.1, 0.2]], np.float32), long[:2], None]
        got, kept = {}, {}
        for on_numpy in (True, False):
            monkeypatch.setattr(controller_module, "_on_numpy", lambda _, on=on_numpy: on)
            got[on_numpy] = model.set_routes(state, rows, routes)
            # a route the tensor holds without widening: written into a copy, the state given unchanged
            before = state.waypoints.clone()
            kept[on_numpy] = model.set_routes(state, [0], [state.waypoints[3, :2].numpy()])
            assert torch.allclose(state.waypoints, before, equal_nan=True)
    a, b = got[True], got[False]
    torch.testing.assert_close(kept[True].waypoints, kept[False].waypoints, rtol=0, atol=0, equal_nan=True)
    for name in ("waypoints", "count", "queue", "pos", "frame"):
        torch.testing.assert_close(getattr(a, name), getattr(b, name), rtol=0, atol=0, equal_nan=True)
    assert a.waypoints.shape[1] == max(7, state.waypoints.shape[1])
    assert a.count.tolist()[1:5] == [1, 0, state.count[3].item(), 2]
    assert a.queue[1] == 0 and a.queue[2] == 0 and a.queue[4] == 0 and a.queue[3] == state.queue[3]
    assert np.array_equal(a.waypoints[4].numpy(), np.concatenate([long[:2], np.repeat(long[1:2], 5, 0)]))
    assert torch.equal(state.waypoints[0], a.waypoints[0, : state.waypoints.shape[1]])  # the others kept


def test_a_ring_keeps_the_same_frames_in_numpy_as_in_torch() -> None:
    """The CPU ring (numpy arrays, numpy indexing) and the ring of other devices (torch tensors,
    forced here on the CPU) record, restore and report queues alike, to the bit."""
    from motion_env.models.controller_state import _RECORDED, StateRing

    model = _tiny(3)
    rng = np.random.default_rng(5)
    rings = [StateRing(4, 16, TINY.hidden, "cpu") for _ in range(2)]
    rings[1]._on_cpu = False  # what a GPU's ring does, on the CPU's tensors
    rings[1]._fields = {name: getattr(rings[1], name) for name in _RECORDED}
    with torch.no_grad():
        state = model.init_state(
            torch.randn(4, 16), _routes(rng, 4), generator=torch.Generator().manual_seed(6)
        )
        timed = np.array([[0.1, 0.1, 3], [0.2, 0.2, 6], [0.5, 0.5, 12], [1.0, 1.0, 200]], np.float32)
        state = model.set_routes(state, [3], [timed])  # row 3's queue moves on by time
        some = torch.tensor([1, 3])
        for ring in rings:
            ring.record(torch.arange(4), state)
        for steps in (5, 20):  # 20: more frames than the ring holds
            first = state.take(some).frame
            sub, trace = model.run(state.take(some), steps, trace=True)
            state = state.put(some, sub)
            for ring in rings:
                ring.record_trace(some, first, trace)
                ring.set_queue(some[:1], first[:1] + 2, torch.tensor([7]))
    frames = torch.tensor([3, 23, 0, 20])
    a, b = (ring.restore(state, torch.tensor([3, 1]), frames[[3, 1]]) for ring in rings)
    for name in ("pos", "theta", "vel", "hidden", "queue", "frame"):
        assert torch.equal(getattr(a, name), getattr(b, name)), name
    # Row 1 at frame 23 and row 3 at frame 20: frames 18 and 15 of the 20-frame run (from frame 5);
    # row 1's queue there is the one set_queue wrote (frame 7's slot is frame 23's now).
    assert torch.equal(a.root[[1, 3]], trace.roots[[0, 1], [17, 14]])
    assert torch.equal(a.vel[[1, 3]], trace.vel[[0, 1], [17, 14]])
    assert torch.equal(a.hidden[[1, 3]], trace.hidden[[0, 1], [17, 14]])
    assert a.queue[1] == 7 and a.queue[3] == trace.queue[1, 14] == 3
    assert np.array_equal(rings[0].roots[[1, 3], [7, 4]], trace.roots[[0, 1], [17, 14]].numpy())
    for name in _RECORDED:
        assert torch.equal(getattr(rings[0], name), getattr(rings[1], name)), name
    assert np.array_equal(rings[0].roots, rings[1].roots) and rings[0].roots[1].any()
    rows, at = np.array([1, 3]), np.array([22, 24])
    assert rings[0].queue_at(rows, at) == rings[1].queue_at(rows, at)


@pytest.mark.parametrize("batch", [5, 8])
def test_the_compiled_loop_traces_the_numpy_frames(batch: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """controller_jit's loop against PathController._frame on numpy: every frame's root, velocity,
    GRU state and queue, over routes timed, untimed, mixed, none and arrived at (the gating)."""
    model = _tiny(batch + 10, scale=1.0)
    rng = np.random.default_rng(batch)
    emb = torch.randn(batch, 16)
    routes = _routes(rng, batch)
    routes[2] = np.array([[1.0, 1.0, 5], [2.0, 2.0, 10], [3.0, 3.0, 200]], np.float32)  # passed by its frames
    with torch.no_grad():
        state = model.init_state(emb, routes, rng.normal(size=(batch, 3)).astype(np.float32))
        model.compiled = False
        ref_state, ref = model.run(state, 120, trace=True)
        model.compiled = True
        monkeypatch.setattr(model, "_frame", lambda *a: pytest.fail("the numpy frame ran"))
        new, trace = model.run(state, 120, trace=True)
    assert torch.equal(trace.queue, ref.queue) and torch.equal(new.queue, ref_state.queue)
    assert int(ref_state.queue.max()) > 0  # some waypoints were passed on the way
    pairs = [(getattr(trace, k), getattr(ref, k), k) for k in ("roots", "vel", "hidden")]
    for got, want, name in pairs:  # the first frames to float32 rounding
        np.testing.assert_allclose(got[:, :10], want[:, :10], rtol=0, atol=2e-5, err_msg=name)
    # Over 120 frames the closed loop carries the products' float32 rounding on, which differs
    # between the BLAS kernels numba's and numpy's products pick on a CPU (AVX-512: 1.2e-4 m/s
    # after 35 frames of the route passed by its frames).
    pairs += [(getattr(new, k), getattr(ref_state, k), k) for k in ("pos", "theta", "vel", "hidden")]
    for got, want, name in pairs:
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-3, err_msg=name)
    assert torch.equal(new.frame, state.frame + 120)


def test_the_compiled_step_inputs_are_the_numpy_ones(monkeypatch: pytest.MonkeyPatch) -> None:
    """controller_jit.step_inputs (the look-ahead head's inputs) against PathController.step_inputs
    on numpy's operations, frame after frame of a roll-out over every kind of route, to float32
    rounding; the numpy features do not run when it is compiled."""
    from motion_env.models import controller as controller_module
    from motion_env.models import jit_cache

    batch = 6
    model = _tiny(batch + 10, scale=1.0)
    rng = np.random.default_rng(4)
    routes = _routes(rng, batch)
    with torch.no_grad():
        starts = rng.normal(size=(batch, 3)).astype(np.float32)
        state = model.init_state(torch.randn(batch, 16), routes, starts)
        ops = model.frame_ops(batch)
        assert ops is not TORCH
        for _ in range(12):
            state, _ = model.run(state, 7)
            monkeypatch.setattr(jit_cache, "_enabled", False)
            want = model.step_inputs(state, ops)
            monkeypatch.setattr(jit_cache, "_enabled", True)
            with monkeypatch.context() as m:
                m.setattr(controller_module, "slot_features", lambda *a: pytest.fail("numpy's features ran"))
                got = model.step_inputs(state, ops)
            assert got.shape == want.shape == (batch, model.config.input_dim)
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6)
    assert int(state.queue.max()) > 0  # waypoints were passed on the way
