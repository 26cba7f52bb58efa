"""The look-ahead head: the path controller's next ``horizon`` frames in one pass.

The stream (:mod:`motion_env.generation.streaming`) conditions each token on the root path one
second (``path_horizon`` = 20 frames) ahead of the frames it decodes. With the controller alone,
a new caption or route means rolling that second out again, 21 sequential GRU steps. The head
predicts the same window from the controller's state at one frame in one MLP pass: its GRU state,
its caption projection, its waypoint features (:meth:`PathController.step_inputs`) and its
last velocity. It is distilled from the controller's own roll-outs
(:mod:`motion_env.training.lookahead`), so it says where the controller would go, not where the
take went.

Output: per frame k = 1..horizon after the state's frame, the offset of the root in the state's
heading frame (lateral, forward, metres) and the change of heading (radians), each scaled by a
per-frame, per-channel ``out_scale`` (the spread of the distillation targets, stored with the
weights) so that every output is O(1) to the network.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from motion_env.models.checkpoint import load_checkpoint
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.models.controller_state import ControllerState
from motion_env.models.frame_ops import TORCH, Array, NumpyOps, TorchOps
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.models.waypoint_features import from_heading_frame_torch
from motion_env.motion.validation import CheckedConfig, PositiveInt

__all__ = [
    "LOOKAHEAD_FILE",
    "LookaheadConfig",
    "LookaheadHead",
    "controller_fingerprint",
    "controller_inputs",
    "load_lookahead",
]

LOOKAHEAD_FILE = "lookahead.pt"
CHECKPOINT_KIND = "lookahead"


@dataclass
class LookaheadConfig(CheckedConfig):
    """Sizes of :class:`LookaheadHead`.

    Attributes:
        input_dim: what the head reads: the GRU state of the controller it is distilled from
            beside what that controller's step reads (:meth:`for_controller` sets it).
        horizon: frames predicted after the state's frame (the stream's ``path_horizon``).
        width: width of the MLP's hidden layers.
        layers: hidden layers of the MLP.
    """

    input_dim: PositiveInt
    horizon: PositiveInt = 20
    width: PositiveInt = 384
    layers: PositiveInt = 3

    @classmethod
    def for_controller(cls, controller: ControllerConfig, **sizes: int) -> LookaheadConfig:
        """The head of a controller with these sizes (`sizes`: horizon, width, layers)."""
        return cls(input_dim=controller_inputs(controller), **sizes)


def controller_inputs(controller: ControllerConfig) -> int:
    """How many numbers a head reads of a controller's state (:meth:`LookaheadHead.inputs`)."""
    return controller.hidden + controller.input_dim


def controller_fingerprint(controller: PathController) -> float:
    """A number that tells one controller's weights from another's (the head is distilled from one)."""
    return float(sum(p.detach().double().abs().sum().item() for p in controller.parameters()))


class LookaheadHead(nn.Module):
    """MLP: the controller's state at a frame -> its root path over the next ``horizon`` frames."""

    def __init__(self, config: LookaheadConfig) -> None:
        super().__init__()
        self.config = c = config
        dims = [c.input_dim] + [c.width] * c.layers
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in zip(dims[:-1], dims[1:], strict=True))
        self.last = nn.Linear(c.width, c.horizon * 3)
        # The normalisation of inputs and outputs, fitted on the distillation data (saved with the weights).
        self.register_buffer("in_mean", torch.zeros(c.input_dim))
        self.register_buffer("in_std", torch.ones(c.input_dim))
        self.register_buffer("out_scale", torch.ones(c.horizon, 3))
        self._numpy = NumpyOps()  # predict's backend for a few characters (PathController.frame_ops)
        # Whether the numpy backend's MLP runs as a compiled loop (lookahead_jit, numba) or on
        # numpy's operations (the reference it is tested against); the same to float32 rounding.
        self.compiled = True

    def check_controller(self, controller: PathController, where: str = "look-ahead head") -> None:
        """Raise a ValueError naming `where` when the controller's sizes are not the head's."""
        theirs = controller_inputs(controller.config)
        if theirs != self.config.input_dim:
            raise ValueError(
                f"{where} reads {self.config.input_dim} numbers of a controller's state (its GRU "
                f"state and step input), but this controller has {theirs}: distil a head for it "
                "(motion-env train lookahead)"
            )

    def set_normalization(self, in_mean: torch.Tensor, in_std: torch.Tensor, out_scale: torch.Tensor) -> None:
        """Set the input mean/std ((D,) each) and the output scale ((horizon, 3))."""
        with torch.no_grad():
            self.in_mean.copy_(in_mean)
            self.in_std.copy_(in_std.clamp(min=1e-3))
            self.out_scale.copy_(out_scale.clamp(min=1e-4))

    @staticmethod
    def inputs(controller: PathController, state: ControllerState, ops: TorchOps = TORCH) -> Array:
        """(B, input_dim) what the head reads of `state`: the GRU state beside what the
        controller's step reads (:meth:`PathController.step_inputs`), in `ops`'s arrays."""
        return ops.cat([ops.array(state.hidden), controller.step_inputs(state, ops)], -1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """(B, input_dim) inputs -> (B, horizon, 3) offsets in the start's heading frame (metres,
        lateral and forward) and heading changes (radians)."""
        if x.ndim != 2 or x.shape[1] != self.config.input_dim:
            raise ValueError(f"look-ahead inputs must be (B, {self.config.input_dim}), got {tuple(x.shape)}")
        h = (x - self.in_mean) / self.in_std
        for layer in self.layers:
            h = F.gelu(layer(h))
        return self.last(h).reshape(x.shape[0], self.config.horizon, 3) * self.out_scale

    def _forward_numpy(self, x: np.ndarray) -> np.ndarray:
        """:meth:`forward` on numpy float32 arrays (the layers' weights held transposed)."""
        ops = self._numpy
        layers = (*self.layers, self.last)
        weights = ops.weights(tuple(p for layer in layers for p in (layer.weight, layer.bias)))
        if self.compiled and jit_enabled():
            from motion_env.models.lookahead_jit import mlp  # numba is imported only when it runs

            note_first_compile(mlp, "the look-ahead head")
            out = mlp(
                np.ascontiguousarray(x, np.float32), self.in_mean.numpy(), self.in_std.numpy(),
                weights[0::2], weights[1::2], self.out_scale.numpy().reshape(-1),
            )  # fmt: skip
            return out.reshape(x.shape[0], self.config.horizon, 3)
        h = (x - self.in_mean.numpy()) / self.in_std.numpy()
        for i in range(len(self.layers)):
            h = ops.gelu(ops.linear(h, weights[2 * i], weights[2 * i + 1]))
        out = ops.linear(h, weights[-2], weights[-1])
        return out.reshape(x.shape[0], self.config.horizon, 3) * self.out_scale.numpy()

    def predict(self, controller: PathController, state: ControllerState) -> torch.Tensor:
        """(B, horizon, 3) world x, z, heading of frames frame+1 .. frame+horizon of each character.

        Runs where the controller's frames run (:meth:`PathController.frame_ops`): on numpy for a
        few characters without gradients on the CPU (one character: 0.3 ms where torch's
        operations took 1.2), the two agreeing to float32 rounding."""
        ops = controller.frame_ops(state.pos.shape[0])
        x = self.inputs(controller, state, ops)
        offsets = self(x) if ops is TORCH else self._forward_numpy(x)
        pos, theta = ops.array(state.pos), ops.array(state.theta)
        xz = pos[:, None] + from_heading_frame_torch(offsets[..., :2], theta[:, None], ops)
        return ops.tensor(ops.cat([xz, (theta[:, None] + offsets[..., 2])[..., None]], -1), state.pos)

    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())


def load_lookahead(
    folder: str | Path, controller: PathController, device: str | torch.device = "cpu"
) -> tuple[LookaheadHead | None, dict[str, Any] | None]:
    """The look-ahead head of a weights folder and its checkpoint, or (None, None) without one.

    It must have been distilled from `controller` (sizes and the weights' fingerprint); a
    ValueError names the file otherwise."""
    path = Path(folder) / LOOKAHEAD_FILE
    if not path.is_file():
        return None, None
    head, ckpt = load_checkpoint(path, CHECKPOINT_KIND, LookaheadConfig, LookaheadHead, device)
    head.check_controller(controller, str(path))
    stored = ckpt.get("controller_fingerprint")
    ours = controller_fingerprint(controller)
    if stored is None or not math.isclose(float(stored), ours, rel_tol=1e-5):
        raise ValueError(
            f"{path} was distilled from another controller (fingerprint {stored}, this one {ours:.6g}); "
            "train it again: motion-env train lookahead"
        )
    return head, ckpt
