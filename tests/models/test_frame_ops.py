"""The controller frame's two backends: numpy's operations against torch's, one by one and over whole
roll-outs of the shipped controller's size (routes timed and untimed, the arrive gating, no route),
which backend a roll-out takes, and the numpy weights made again when the parameters change."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from motion_env.models.controller import NUMPY_MAX_BATCH, ControllerConfig, PathController
from motion_env.models.frame_ops import TORCH, NumpyOps, numpy_chosen
from motion_env.models.waypoint_features import from_heading_frame_torch, to_heading_frame_torch

NP = NumpyOps()


def _close(a: np.ndarray, b: torch.Tensor, atol: float = 1e-6) -> bool:
    return bool(np.abs(a - b.numpy()).max() <= atol)


def test_numpy_operations_equal_torch_ones() -> None:
    g = torch.Generator().manual_seed(0)
    x = torch.randn(3, 40, generator=g) * 3
    assert _close(NP.gelu(x.numpy()), F.gelu(x))
    w, b = torch.randn(24, 40, generator=g), torch.randn(24, generator=g)
    # Outputs up to about 50, sums of 40 float32 products: the BLAS's order of summation moves
    # the last bits (numpy 2.4.6's: 2e-5 apart, a few float32 steps at that size).
    assert _close(NP.linear(x.numpy(), w.numpy().T.copy(), b.numpy()), F.linear(x, w, b), 5e-5)
    h = torch.randn(3, 16, generator=g)
    w_ih, w_hh = torch.randn(48, 40, generator=g), torch.randn(48, 16, generator=g)
    b_ih, b_hh = torch.randn(48, generator=g), torch.randn(48, generator=g)
    w_ih_t, w_hh_t = w_ih.numpy().T.copy(), w_hh.numpy().T.copy()
    got = NP.gru_cell(x.numpy(), h.numpy(), w_ih_t, w_hh_t, b_ih.numpy(), b_hh.numpy())
    assert _close(got, torch.gru_cell(x, h, w_ih, w_hh, b_ih, b_hh), 1e-5)
    v, theta = torch.randn(3, 5, 2, generator=g), torch.randn(3, 5, generator=g)
    assert _close(to_heading_frame_torch(v.numpy(), theta.numpy(), NP), to_heading_frame_torch(v, theta))
    assert _close(from_heading_frame_torch(v.numpy(), theta.numpy(), NP), from_heading_frame_torch(v, theta))
    assert _close(NP.norm(v.numpy()), TORCH.norm(v))
    assert _close(NP.clip(x.numpy(), min=-1.0), TORCH.clip(x, min=-1.0))
    assert _close(NP.clip(x.numpy(), max=0.5), TORCH.clip(x, max=0.5))
    assert _close(NP.stack([x.numpy(), x.numpy() * 2], -1), TORCH.stack([x, x * 2], -1))


# Every kind of route, the first a short timed one whose last waypoint comes early (the arrive
# gating runs), then none, untimed, timed and mixed.
ROUTES = [
    np.array([[0.3, 0.5, 25.0], [0.2, 0.9, 50.0]], np.float32),
    None,
    np.array([[1.0, 2.5], [3.0, 4.0], [5.5, 3.0]], np.float32),
    np.array([[0.0, 2.0, 40.0], [2.0, 4.0, 90.0], [4.0, 4.5, 140.0]], np.float32),
    np.array([[-1.0, 2.0, 30.0], [-2.5, 3.5, np.nan], [-4.0, 3.0, 120.0]], np.float32),
]


@pytest.mark.parametrize("batch", [1, 5])
def test_a_numpy_roll_out_equals_the_torch_one(batch: int) -> None:
    """The shipped controller's sizes: the closed loop does not carry float32 rounding away."""
    torch.manual_seed(batch)
    model = PathController.drifting(ControllerConfig(text_dim=32), 0.5).eval()
    rng = np.random.default_rng(batch)
    starts = rng.normal(size=(batch, 3)).astype(np.float32)
    with torch.no_grad():
        state = model.init_state(
            torch.randn(batch, 32), ROUTES[:batch], starts, generator=torch.Generator().manual_seed(0)
        )
        assert model.frame_ops(batch) is model._numpy
        new, trace = model.run(state, 150, trace=True)
        model.frame_backend = "torch"
        ref, ref_trace = model.run(state, 150, trace=True)
    assert torch.allclose(trace.roots, ref_trace.roots, rtol=0.0, atol=2e-5)
    assert torch.allclose(trace.vel, ref_trace.vel, rtol=0.0, atol=1e-4)
    assert torch.allclose(trace.hidden, ref_trace.hidden, rtol=0.0, atol=1e-5)
    assert torch.equal(trace.queue, ref_trace.queue)
    for name in ("pos", "theta", "vel", "hidden"):
        got, want = getattr(new, name), getattr(ref, name)
        assert got.dtype == want.dtype and got.shape == want.shape, name
    assert torch.equal(new.queue, ref.queue) and torch.equal(new.frame, ref.frame)
    assert bool((ref.queue == state.count - 1)[state.count > 0].any())  # the arrive gating ran


def test_a_roll_out_with_gradients_or_many_rows_runs_on_torch() -> None:
    model = PathController.drifting(ControllerConfig(text_dim=8, text_proj=4, hidden=8, mlp=8), 0.5)
    state = model.init_state(torch.randn(2, 8), [np.array([[0.0, 2.0, 20.0]], np.float32), None])
    assert model.frame_ops(2) is TORCH
    roots, _ = model(state, 5)
    assert roots.requires_grad
    with torch.no_grad():
        assert model.frame_ops(2) is model._numpy
        assert model.frame_ops(NUMPY_MAX_BATCH + 1) is TORCH  # many rows: torch's matrix products win
        model.frame_backend = "numpy"
        assert model.frame_ops(NUMPY_MAX_BATCH + 1) is model._numpy


def _blas_threads() -> list[int]:
    from threadpoolctl import threadpool_info

    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_a_numpy_step_runs_blas_on_torchs_thread_count() -> None:
    """A busy 2-core machine made numpy's few-row products 5x slower on a second BLAS thread."""
    if not _blas_threads():
        pytest.skip("numpy reports no BLAS library to threadpoolctl")
    threads = torch.get_num_threads()
    try:
        for wanted in (2, 1):
            torch.set_num_threads(wanted)
            assert numpy_chosen("test", "auto", 1, 4, True, "", str)
            assert set(_blas_threads()) == {wanted}
        torch.set_num_threads(2)
        assert not numpy_chosen("test", "torch", 1, 4, True, "", str)  # torch's steps leave BLAS alone
        assert set(_blas_threads()) == {1}
    finally:
        torch.set_num_threads(threads)


def test_a_backend_that_cannot_run_is_named() -> None:
    model = PathController(ControllerConfig(text_dim=8, text_proj=4, hidden=8, mlp=8))
    state = model.init_state(torch.randn(1, 8), None)
    model.frame_backend = "jax"
    with torch.no_grad(), pytest.raises(ValueError, match="frame_backend must be one of"):
        model(state, 2)
    model.frame_backend = "numpy"
    with pytest.raises(ValueError, match="without gradients on the CPU only"):
        model(state, 2)


def test_numpy_weights_follow_the_parameters() -> None:
    """An optimiser step or a load changes the parameters in place: the numpy copy is made again."""
    model = PathController.drifting(ControllerConfig(text_dim=8, text_proj=4, hidden=8, mlp=8), 0.5).eval()
    state = model.init_state(torch.randn(1, 8), None)
    with torch.no_grad():
        before, _ = model(state, 10)
        for p in model.out.parameters():
            p.add_(0.3)
        after, _ = model(state, 10)
        ops = model._numpy
        cached = ops.weights(model._weights())[-1]
        assert ops.weights(model._weights())[-1] is cached  # made once while unchanged
    with torch.enable_grad():
        want, _ = model(state, 10)
    assert not torch.allclose(before, after)
    assert torch.allclose(after, want.detach(), rtol=0.0, atol=1e-5)
