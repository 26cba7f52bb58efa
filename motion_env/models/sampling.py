"""Token sampling: the one sampler, used by whole clips, the stream and the tests alike.

Multinomial sampling over the GPT's logits (optionally with temperature and nucleus top-p):
greedy or top-k decoding collapses to a held pose, as C-T2M reports.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import torch

from motion_env.motion.validation import CheckedConfig

__all__ = ["SAMPLING_FILE", "SamplingConfig", "load_sampling", "sample_tokens"]

# The sampling settings of a weights folder, as JSON.
SAMPLING_FILE = "sampling.json"


@dataclass
class SamplingConfig(CheckedConfig):
    """How tokens are sampled.

    Attributes:
        temperature: softmax temperature (> 0); 1 samples the model's distribution.
        top_p: nucleus mass in (0, 1], or None for the full distribution.
        guidance: classifier-free guidance scale (1 = off; > 1 follows the caption more at the
            cost of a second GPT row per character).
    """

    temperature: Annotated[float, "(0, inf)"] = 1.0
    top_p: float | None = None
    guidance: Annotated[float, "[1, inf)"] = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.top_p is not None and not 0.0 < self.top_p <= 1.0:
            raise ValueError(f"SamplingConfig.top_p must be in (0, 1] or None, got {self.top_p!r}")


def load_sampling(folder: Path) -> SamplingConfig | None:
    """The sampling settings saved in a weights `folder` (:data:`SAMPLING_FILE`), None without
    them; a ValueError names the file when they do not make a :class:`SamplingConfig`."""
    path = folder / SAMPLING_FILE
    if not path.is_file():
        return None
    try:
        return SamplingConfig(**json.loads(path.read_text()))
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{path}: {exc}") from exc


def sample_tokens(
    logits: torch.Tensor, generators: Sequence[torch.Generator], sampling: SamplingConfig
) -> torch.Tensor:
    """(N, V) logits -> (N,) token ids on the CPU, row n drawn with generators[n].

    One uniform number per row and an inverse-CDF lookup: a row's draw depends only on its own
    generator, so a character samples the same tokens alone or in a batch. The same generator
    may stand for several rows (it is then drawn from once per row, in order).
    """
    if len(generators) != logits.shape[0]:
        raise ValueError(f"got {len(generators)} generators for {logits.shape[0]} rows of logits")
    probs = torch.softmax(logits.detach().float().cpu() / sampling.temperature, dim=-1)  # (N, V)
    if sampling.top_p is not None and sampling.top_p < 1.0:
        sorted_p, order = probs.sort(dim=-1, descending=True)
        drop = sorted_p.cumsum(-1) - sorted_p >= sampling.top_p  # always keeps the top token
        probs = torch.zeros_like(probs).scatter_(-1, order, sorted_p.masked_fill(drop, 0.0))
    u = torch.stack([torch.rand((), generator=g) for g in generators])  # (N,)
    cdf = probs.cumsum(-1)
    idx = torch.searchsorted(cdf, (u * cdf[:, -1])[:, None], right=True)[:, 0]
    return idx.clamp(max=probs.shape[1] - 1)
