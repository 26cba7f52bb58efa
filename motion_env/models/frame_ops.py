"""The array operations the path controller's frame is written in, on torch tensors or on numpy
arrays, so that one implementation of the frame (:meth:`PathController._frame
<motion_env.models.controller.PathController._frame>`,
:func:`~motion_env.models.waypoint_features.slot_features`) runs on either.

Torch trains the controller (gradients) and runs it on any device. A roll-out without gradients on
the CPU runs on numpy: a frame at batch 1 is some sixty operations on a few hundred numbers, where
torch's per-operation cost (a few microseconds) is most of the frame and numpy's is a third of it
(the roll-out of a 200-frame clip, 216 frames: 131 -> 69 ms on the 2-core development CPU, one
thread). The two agree to float32 rounding (``tests/models/test_frame_ops.py``); the numpy side
holds the weights transposed, the layout a one-row product reads fastest.

A numpy step runs numpy's BLAS on as many threads as torch is set to (:func:`match_blas_threads`):
its products are a few rows wide, and on a busy 2-core machine a second BLAS thread waiting for a
core made a 4-row product 5x slower (46 -> 230 us) and one env's step p99 8x longer.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import fields, replace
from typing import Any, NamedTuple

import numpy as np
import torch
import torch.nn.functional as F
from scipy.special import erf, expit
from threadpoolctl import threadpool_limits

from motion_env.motion.skeleton import FPS

Array = Any  # a torch.Tensor or a numpy array, as the ops object in hand makes them

# What a model's numpy switch may be set to (PathController.frame_backend, TokenGPT.step_backend,
# DecoderStream.backend): "auto" (numpy for a few rows where it can run, else torch), "torch", "numpy".
BACKENDS = ("auto", "torch", "numpy")
_blas_threads: int | None = None  # what match_blas_threads last set numpy's BLAS to


def match_blas_threads() -> None:
    """Limit numpy's BLAS to ``torch.get_num_threads()`` threads, so that the one thread count a
    caller sets (``torch.set_num_threads``, the commands' ``--threads``) holds for the numpy steps
    too. Set again only when torch's count changed (a limit costs about 0.4 ms; this runs at every
    step)."""
    global _blas_threads
    threads = torch.get_num_threads()
    if threads != _blas_threads:
        threadpool_limits(threads, user_api="blas")
        _blas_threads = threads


def numpy_chosen(
    owner: str, setting: str, rows: int, max_rows: int, numpy_ok: bool, needs: str, state: Callable[[], str]
) -> bool:
    """Whether a step of `rows` rows runs on numpy, as the switch `owner` (its name in errors) set
    to `setting` (:data:`BACKENDS`) says: "auto" takes numpy where it can run (`numpy_ok`) for up
    to `max_rows` rows. Forcing "numpy" where it cannot run is an error naming what it `needs`
    and, from `state()`, what it got (made only then: this runs at every step)."""
    if setting not in BACKENDS:
        raise ValueError(f"{owner} must be one of {BACKENDS}, got {setting!r}")
    if setting == "numpy" and not numpy_ok:
        raise ValueError(f"{owner}='numpy' runs {needs} only ({state()})")
    if setting == "torch" or not numpy_ok:
        return False
    chosen = setting == "numpy" or rows <= max_rows
    if chosen:
        match_blas_threads()
    return chosen


def gradients_state() -> str:
    """ "gradients on" or "gradients off", for the errors of :func:`numpy_chosen`."""
    return f"gradients {'on' if torch.is_grad_enabled() else 'off'}"


class Constants(NamedTuple):
    """The numbers a frame multiplies and divides by, made once per backend and dtype: for torch
    0-dim CPU tensors (a tensor operation takes them as it takes a Python number, a CPU scalar on
    any device: the same kernel, the same rounding, without wrapping the number again at every
    operation), for numpy float32 scalars (float32 arithmetic stays float32)."""

    half: Any
    quarter: Any
    fps: Any
    step_scale: Any
    turn_scale: Any


class TorchOps:
    """The frame's operations on torch tensors (training, any device). Axes are passed by
    position (torch's `dim`, numpy's `axis`)."""

    def __init__(self) -> None:
        self._constants: dict[tuple[float, float, torch.dtype], Constants] = {}

    def constants(
        self, step_scale: float, turn_scale: float, dtype: torch.dtype = torch.float32
    ) -> Constants:
        """The :class:`Constants` of a controller's step and turn scales (made once per dtype)."""
        key = (step_scale, turn_scale, dtype)
        if key not in self._constants:
            values = (0.5, 0.25, float(FPS), step_scale, turn_scale)
            self._constants[key] = Constants(*(self._scalar(v, dtype) for v in values))
        return self._constants[key]

    @staticmethod
    def _scalar(value: float, dtype: torch.dtype) -> Any:
        return torch.tensor(value, dtype=dtype)

    cat = staticmethod(torch.cat)
    stack = staticmethod(torch.stack)

    @staticmethod
    def norm(x: Array) -> Array:
        """Euclidean norm over the last axis."""
        return torch.linalg.vector_norm(x, dim=-1)

    clip = staticmethod(torch.clamp)
    where = staticmethod(torch.where)
    log1p = staticmethod(torch.log1p)
    cos = staticmethod(torch.cos)
    sin = staticmethod(torch.sin)
    linear = staticmethod(F.linear)  # (x, weight (out, in), bias)
    gelu = staticmethod(F.gelu)
    gru_cell = staticmethod(torch.gru_cell)

    @staticmethod
    def weights(weights: tuple[torch.Tensor, ...]) -> tuple[torch.Tensor, ...]:
        """The controller's parameters as :meth:`linear` and :meth:`gru_cell` take them."""
        return weights

    @staticmethod
    def detach(x: Array) -> Array:
        return x.detach()

    @staticmethod
    def array(x: torch.Tensor) -> Array:
        """A state tensor as this backend's array."""
        return x

    @staticmethod
    def tensor(x: Array, like: torch.Tensor) -> torch.Tensor:
        """This backend's array as a tensor on `like`'s device."""
        return x

    @staticmethod
    def view(view: Any) -> Any:
        """A :class:`~motion_env.models.waypoint_features.RouteView` with this backend's arrays."""
        return view


class NumpyOps(TorchOps):
    """The frame's operations on float32 numpy arrays (inference on the CPU)."""

    _SQRT1_2 = np.float32(1.0 / math.sqrt(2.0))

    def __init__(self) -> None:
        super().__init__()
        self._weights: tuple[tuple[int, ...], tuple[np.ndarray, ...]] | None = None

    @staticmethod
    def _scalar(value: float, dtype: torch.dtype) -> Any:
        return np.float32(value)  # the arrays are float32 whatever the state's dtype

    cat = staticmethod(np.concatenate)

    @staticmethod
    def stack(xs: list[Array], axis: int) -> Array:
        # np.stack checks and reshapes in Python (~10 us); a frame stacks on the last axis.
        if axis == -1:
            return np.concatenate([x[..., None] for x in xs], axis=-1)
        return np.stack(xs, axis=axis)

    @staticmethod
    def norm(x: Array) -> Array:
        return np.sqrt((x * x).sum(-1))

    @staticmethod
    def clip(x: Array, min: float | None = None, max: float | None = None) -> Array:  # noqa: A002 (torch's names)
        # The ufuncs themselves: np.clip's wrappers cost more than the clipping at these sizes.
        if min is not None:
            x = np.maximum(x, min)
        return x if max is None else np.minimum(x, max)

    where = staticmethod(np.where)
    log1p = staticmethod(np.log1p)
    cos = staticmethod(np.cos)
    sin = staticmethod(np.sin)

    @staticmethod
    def linear(x: Array, weight_t: Array, bias: Array) -> Array:
        """x @ weight.T + bias, with the weight held transposed ((in, out), :meth:`weights`)."""
        return x @ weight_t + bias

    @classmethod
    def gelu(cls, x: Array) -> Array:
        return x * np.float32(0.5) * (np.float32(1.0) + erf(x * cls._SQRT1_2))

    @staticmethod
    def gru_cell(x: Array, h: Array, w_ih_t: Array, w_hh_t: Array, b_ih: Array, b_hh: Array) -> Array:
        """torch.gru_cell's update (gates reset, update, new), weights held transposed."""
        gi, gh = x @ w_ih_t + b_ih, h @ w_hh_t + b_hh
        n = h.shape[-1]
        reset = expit(gi[:, :n] + gh[:, :n])
        update = expit(gi[:, n : 2 * n] + gh[:, n : 2 * n])
        new = np.tanh(gi[:, 2 * n :] + reset * gh[:, 2 * n :])
        return new + update * (h - new)

    def weights(self, weights: tuple[torch.Tensor, ...]) -> tuple[np.ndarray, ...]:
        """The parameters as numpy: matrices transposed, made again only when a parameter changed
        (the version counters move with every optimiser step or load)."""
        key = tuple(id(w) for w in weights) + tuple(w._version for w in weights)
        if self._weights is None or self._weights[0] != key:
            arrays = tuple(
                np.ascontiguousarray(w.detach().cpu().numpy().T if w.ndim == 2 else w.detach().cpu().numpy())
                for w in weights
            )
            self._weights = (key, arrays)
        return self._weights[1]

    @staticmethod
    def detach(x: Array) -> Array:
        return x

    @staticmethod
    def array(x: torch.Tensor) -> Array:
        return x.detach().numpy()

    @staticmethod
    def tensor(x: Array, like: torch.Tensor) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(x)).to(like.device)

    @staticmethod
    def view(view: Any) -> Any:
        arrays = {
            f.name: getattr(view, f.name).numpy()
            for f in fields(view)
            if isinstance(getattr(view, f.name), torch.Tensor)
        }
        return replace(view, **arrays)


TORCH = TorchOps()
"""The torch backend (it holds nothing but constants, so one serves every controller)."""
