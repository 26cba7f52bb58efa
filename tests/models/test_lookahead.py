"""The look-ahead head: its config, checkpoint round trip, distillation pairs and the stream's use.

Tiny random-weight models (MotionGenerator.random()); the head is trained for a few steps only
where a test needs it to have seen its data.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from motion_env.generation.generator import MotionGenerator
from motion_env.models.checkpoint import save_checkpoint
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.lookahead import (
    LOOKAHEAD_FILE,
    LookaheadConfig,
    LookaheadHead,
    controller_fingerprint,
    load_lookahead,
)
from motion_env.training.controller import PathData
from motion_env.training.lookahead import LookaheadTrainConfig, distill_pairs, offsets_from_roots


def _head_for(controller: PathController, **kw) -> LookaheadHead:
    c = controller.config
    cfg = LookaheadConfig.for_controller(c, **kw)
    torch.manual_seed(0)
    return LookaheadHead(cfg)


@pytest.fixture
def gen(random_generator: MotionGenerator) -> MotionGenerator:
    return random_generator


def test_config_is_checked() -> None:
    with pytest.raises(ValueError, match="horizon"):
        LookaheadConfig(input_dim=10, horizon=0)
    with pytest.raises(ValueError, match="width"):
        LookaheadConfig(input_dim=10, width=-3)


def test_predict_shapes_and_the_start_frame(gen: MotionGenerator) -> None:
    ctrl = gen.pipeline.controller
    head = _head_for(ctrl, width=16, layers=1)
    emb = torch.randn(3, ctrl.config.text_dim)
    state = ctrl.init_state(emb, [[[1.0, 2.0]], None, [[0.0, 3.0, 40], [2.0, 4.0, 80]]], np.ones((3, 3)))
    roots = head.predict(ctrl, state)
    assert roots.shape == (3, head.config.horizon, 3)
    # Zero offsets mean "stay at the start": the world roots are then the start's.
    torch.nn.init.zeros_(head.last.weight)
    torch.nn.init.zeros_(head.last.bias)
    np.testing.assert_allclose(
        head.predict(ctrl, state).detach().numpy(), np.ones((3, head.config.horizon, 3))
    )
    with pytest.raises(ValueError, match="look-ahead inputs"):
        head(torch.zeros(2, 5))


@torch.no_grad()
def test_offsets_round_trip_through_predict(gen: MotionGenerator, monkeypatch: pytest.MonkeyPatch) -> None:
    """The training targets (offsets_from_roots) are what predict turns back into world roots."""
    ctrl = gen.pipeline.controller
    monkeypatch.setattr(ctrl, "frame_backend", "torch")  # the head's forward, replaced below, is torch's
    state = ctrl.init_state(torch.randn(2, ctrl.config.text_dim), None, np.array([[1, 2, 0.3], [-1, 0, 2.0]]))
    _, trace = ctrl.run(state, 20)
    offsets = offsets_from_roots(trace.roots, state)
    head = _head_for(ctrl, width=8, layers=1)
    head.forward = lambda x: offsets  # the head's integration alone
    np.testing.assert_allclose(head.predict(ctrl, state).numpy(), trace.roots.numpy(), atol=1e-5)


def test_checkpoint_round_trip_and_controller_check(gen: MotionGenerator, tmp_path) -> None:
    ctrl = gen.pipeline.controller
    head = _head_for(ctrl, width=16, layers=2)
    save_checkpoint(
        tmp_path / LOOKAHEAD_FILE, kind="lookahead", config=head.config, model=head,
        controller_fingerprint=controller_fingerprint(ctrl),
    )  # fmt: skip
    loaded, _ = load_lookahead(tmp_path, ctrl)
    x = torch.randn(4, head.config.input_dim)
    torch.testing.assert_close(loaded(x), head(x))
    assert load_lookahead(tmp_path / "nowhere", ctrl) == (None, None)
    other = PathController(replace(ctrl.config, seek_rate=0.5))  # same sizes, other weights
    with pytest.raises(ValueError, match="another controller"):
        load_lookahead(tmp_path, other)
    bigger = PathController(ControllerConfig(text_dim=ctrl.config.text_dim, hidden=ctrl.config.hidden + 1))
    with pytest.raises(ValueError, match="numbers of a controller"):
        load_lookahead(tmp_path, bigger)


def test_distilled_pairs_are_the_controllers_roll_outs(gen: MotionGenerator) -> None:
    """Each pair's target is exactly where the controller goes from the pair's state."""
    ctrl = gen.pipeline.controller
    rng = np.random.default_rng(0)
    paths = [np.cumsum(rng.normal(0, 0.02, (120, 3)), axis=0).astype(np.float32) for _ in range(3)]
    data = PathData(
        paths,
        [np.array([0]), np.array([1]), np.array([0, 1])],
        rng.normal(size=(2, ctrl.config.text_dim)).astype(np.float32),
    )
    settings = LookaheadTrainConfig(rows=4, burn_in=10, after=4, stride=2, progress=False)
    x, y = distill_pairs(ctrl, data, np.random.default_rng(1), settings, 20)
    assert x.shape == (4 * 3, _head_for(ctrl).config.input_dim) and y.shape == (12, 20, 3)
    assert torch.isfinite(x).all() and torch.isfinite(y).all()
    # The same draw again gives the same pairs (the pool is seeded).
    x2, y2 = distill_pairs(ctrl, data, np.random.default_rng(1), settings, 20)
    torch.testing.assert_close(x, x2)
    torch.testing.assert_close(y, y2)


def _steered_frames(gen: MotionGenerator, mode: str | None, steer: bool) -> tuple[np.ndarray, list[bool]]:
    stream = gen.stream(["a person walks"] * 2, [[[0.5, 2.0]], None], seed=3)
    if mode is not None:
        stream.lookahead = mode
    frames, behind = [], []
    for t in range(60):
        if steer and t in (9, 10, 11, 13):  # new targets on consecutive tokens
            stream.set_waypoints([[1.0 + t * 0.1, 3.0]], index=0)
        frames.append(stream.step())
        behind.append(bool(stream._predicted[0]))
    return np.stack(frames, axis=1), behind


def test_stream_head_mode(gen: MotionGenerator) -> None:
    with pytest.raises(ValueError, match="lookahead must be"):
        gen.stream(["a person walks"]).lookahead = "head"  # no head in these weights
    exact, _ = _steered_frames(gen, None, steer=True)
    assert gen.stream(["a person walks"]).lookahead == "exact"
    gen.pipeline.lookahead = _head_for(gen.pipeline.controller, width=16, layers=1)
    try:
        assert gen.stream(["a person walks"]).lookahead == "head"
        # Without a change the head is never used: the stream is the controller's alone.
        plain_exact, _ = _steered_frames(gen, "exact", steer=False)
        plain_head, behind = _steered_frames(gen, "head", steer=False)
        np.testing.assert_array_equal(plain_head, plain_exact)
        assert not any(behind)
        # "exact" reproduces the stream without a head, bit for bit.
        again, _ = _steered_frames(gen, "exact", steer=True)
        np.testing.assert_array_equal(again, exact)
        # With changes the look-ahead is predicted, then the roll-out catches up.
        steered, behind = _steered_frames(gen, "head", steer=True)
        assert any(behind[10:20]) and not any(behind[40:])
        assert not np.array_equal(steered, exact) and np.isfinite(steered).all()
        np.testing.assert_array_equal(steered[:, :12], exact[:, :12])  # frames decoded before the change
        np.testing.assert_allclose(steered[1], exact[1], atol=1e-5)  # the other character: rounding only
        # A head that predicts exactly what the controller does gives the exact stream: the
        # predicted frames land where the roll-out's would (up to the rounding of batch sizes).
        head = gen.pipeline.lookahead
        head.predict = lambda ctrl, state: ctrl.run(state, head.config.horizon)[1].roots
        oracle, _ = _steered_frames(gen, "head", steer=True)
        np.testing.assert_allclose(oracle, exact, atol=1e-4)
    finally:
        gen.pipeline.lookahead = None


@torch.no_grad()
@pytest.mark.parametrize("compiled", [False, True])
def test_predict_on_numpy_agrees_with_torch(
    gen: MotionGenerator, monkeypatch: pytest.MonkeyPatch, compiled: bool
) -> None:
    """A few characters without gradients predict on numpy (PathController.frame_ops), the MLP on
    numpy's operations or compiled (lookahead_jit): the same roots as torch's operations to
    float32 rounding, as a tensor."""
    if compiled:
        pytest.importorskip("numba")
    ctrl = gen.pipeline.controller
    torch.manual_seed(0)
    head = _head_for(ctrl, width=32, layers=2)
    for p in head.parameters():
        torch.nn.init.normal_(p, std=0.2)
    d, h = head.config.input_dim, head.config.horizon
    head.set_normalization(torch.randn(d), torch.rand(d) + 0.5, torch.rand(h, 3) + 0.1)
    routes = [[[1.0, 2.0]], None, [[0.0, 3.0, 40], [2.0, 4.0, 80]]]
    starts = np.array([[0, 0, 0.3], [1, 0, 2.0], [0, 1, -1.0]])
    state = ctrl.init_state(torch.randn(3, ctrl.config.text_dim), routes, starts)
    state, _ = ctrl.run(state, 7)
    roots = {"torch": head.predict(ctrl, state)}  # three characters: "auto" takes numpy
    monkeypatch.setattr(ctrl, "frame_backend", "torch")
    roots["torch"] = head.predict(ctrl, state)
    monkeypatch.setattr(ctrl, "frame_backend", "auto")
    monkeypatch.setattr(head, "forward", lambda x: pytest.fail("torch's forward ran on numpy's turn"))
    head.compiled = compiled
    roots["numpy"] = head.predict(ctrl, state)
    assert isinstance(roots["numpy"], torch.Tensor) and roots["numpy"].dtype == torch.float32
    np.testing.assert_allclose(roots["numpy"].numpy(), roots["torch"].numpy(), atol=2e-5)
