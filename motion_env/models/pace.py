"""The pace of a caption: caption embedding -> the speed (m/s) a take of that caption travels at.

The path controller reads the pace of walking or running from the caption, but on a route of
*untimed* waypoints it drifts towards the mean speed of the data: a run caption crossed a long
untimed route at 2.1 m/s, where the run takes go 2.8 m/s (the model card, "Caption
recognition"). This small regressor makes the pace explicit: it reads the embedding the
controller reads (the caption reader's output, so any wording the caption adapter understands)
and says how fast the takes of such captions travel, from the train split's takes and captions
(:mod:`motion_env.training.pace`). The route planner
(:func:`motion_env.generation.route_planning.pace_route`) turns an untimed route into one timed
at that pace, for whole clips (the stream keeps the controller's own pace: its causal bend cannot
bring back a waypoint that a timed route let the controller pass before reaching it).

A linear map (ridge regression) on the embedding, or with ``hidden > 0`` one hidden layer (GELU)
before it, clipped at zero: captions of standing motion (waves, bows) get a pace near 0 and leave
untimed routes untimed. The hidden layer is there because a linear map cannot give a style its own
effect on each action: elderly runs go half as fast as the others, elderly walks a third slower.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import torch
from torch import nn

from motion_env.models.checkpoint import load_checkpoint
from motion_env.motion.validation import CheckedConfig, NonNegativeInt, PositiveInt

__all__ = ["PACE_FILE", "PaceConfig", "PaceRegressor", "load_pace"]

PACE_FILE = "pace.pt"  # the pace regressor of a weights folder; optional


@dataclass
class PaceConfig(CheckedConfig):
    """Shape of a :class:`PaceRegressor`.

    Attributes:
        text_dim: width of the caption embedding it reads (the controller's ``text_dim``).
        max_pace: m/s; the prediction is clipped to [0, max_pace] (the fastest takes: 4.5 m/s).
        hidden: width of the hidden layer (0: none, a linear map).
    """

    text_dim: PositiveInt = 768
    max_pace: Annotated[float, "(0, 12]"] = 5.0
    hidden: NonNegativeInt = 0


class PaceRegressor(nn.Module):
    """(N, text_dim) caption embeddings -> (N,) pace in m/s (a linear map, or one hidden layer and a
    linear map; clipped)."""

    def __init__(self, config: PaceConfig) -> None:
        super().__init__()
        self.config = config
        self.hidden = nn.Linear(config.text_dim, config.hidden) if config.hidden else None
        self.linear = nn.Linear(config.hidden or config.text_dim, 1)
        nn.init.zeros_(self.linear.weight)
        nn.init.zeros_(self.linear.bias)

    def forward(self, emb: torch.Tensor) -> torch.Tensor:
        if emb.ndim != 2 or emb.shape[1] != self.config.text_dim:
            raise ValueError(
                f"the pace regressor reads (N, {self.config.text_dim}) caption embeddings, "
                f"got {tuple(emb.shape)}"
            )
        h = emb.to(self.linear.weight.dtype)
        if self.hidden is not None:
            h = nn.functional.gelu(self.hidden(h))
        return self.linear(h)[:, 0].clamp(0.0, self.config.max_pace)

    @torch.no_grad()
    def pace(self, emb: torch.Tensor | np.ndarray) -> np.ndarray:
        """(N, text_dim) embeddings (torch or numpy) -> (N,) float64 pace in m/s, as numpy."""
        emb = torch.as_tensor(emb, device=self.linear.weight.device)
        return self(emb).cpu().numpy().astype(np.float64)

    def set_weights(self, weight: np.ndarray, bias: float) -> None:
        """Load a fitted linear map (a regressor without a hidden layer): (text_dim,) weights and a bias."""
        if self.hidden is not None:
            raise ValueError("set_weights loads a linear map; this pace regressor has a hidden layer")
        weight = np.asarray(weight, np.float32).reshape(1, -1)
        if weight.shape[1] != self.config.text_dim or not np.isfinite(weight).all() or not np.isfinite(bias):
            raise ValueError(
                f"the pace regressor needs {self.config.text_dim} finite weights and a finite bias"
            )
        with torch.no_grad():
            self.linear.weight.copy_(torch.from_numpy(weight))
            self.linear.bias.fill_(float(bias))


def load_pace(
    folder: Path, encoder: str, text_dim: int, device: str | torch.device = "cpu"
) -> tuple[PaceRegressor | None, dict[str, Any] | None]:
    """The pace regressor of a weights folder and its checkpoint, or (None, None) without one.

    It must read the embeddings the controller reads: the caption encoder named `encoder`, of
    width `text_dim`; a ValueError names the file otherwise."""
    path = Path(folder) / PACE_FILE
    if not path.is_file():
        return None, None
    pace, ckpt = load_checkpoint(path, "pace", PaceConfig, PaceRegressor, device)
    reads = (ckpt.get("text_encoder") or {}).get("name")
    if reads != encoder or pace.config.text_dim != text_dim:
        raise ValueError(f"{path} reads {reads!r} embeddings, the controller reads {encoder!r}")
    return pace, ckpt
