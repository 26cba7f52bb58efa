"""Feature normalisation that travels with the VQ-VAE: the training set's per-channel Mean/Std.

The VQ-VAE reads and writes normalised 263-d features, ``x = (features - mean) / std``; the
statistics are stored in the VQ-VAE's checkpoint (keys ``mean`` and ``std``) and loaded with it,
so nothing outside this class writes the formula out by hand.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch

from motion_env.motion.skeleton import FEATURE_DIM

__all__ = ["Normalizer"]


class Normalizer:
    """Per-channel feature statistics: ``normalize(f) = (f - mean) / std``, ``denormalize`` its inverse.

    Args:
        mean, std: (263,) arrays (any float dtype; kept as float32), std > 0.
    """

    def __init__(self, mean: np.ndarray, std: np.ndarray) -> None:
        mean = np.asarray(mean, dtype=np.float32).reshape(-1)
        std = np.asarray(std, dtype=np.float32).reshape(-1)
        if mean.shape != (FEATURE_DIM,) or std.shape != (FEATURE_DIM,):
            raise ValueError(
                f"mean and std must have shape ({FEATURE_DIM},), got {mean.shape} and {std.shape}"
            )
        if not (np.isfinite(mean).all() and np.isfinite(std).all() and (std > 0).all()):
            raise ValueError("mean must be finite and std finite and > 0")
        self.mean, self.std = mean, std

    def normalize(self, features: np.ndarray) -> np.ndarray:
        """(..., 263) features -> the VQ-VAE's normalised input (float32)."""
        return (np.asarray(features, dtype=np.float32) - self.mean) / self.std

    def denormalize(self, x: np.ndarray | torch.Tensor) -> np.ndarray:
        """(..., 263) normalised values (a decoder's output, any device) -> float32 features."""
        if isinstance(x, torch.Tensor):
            x = x.detach().float().cpu().numpy()
        return x * self.std + self.mean

    def denormalize_torch(self, x: torch.Tensor) -> torch.Tensor:
        """(..., 263) normalised values -> features, as a tensor on `x`'s device that keeps its
        gradient (the refinement optimises through the decoder and this)."""
        mean = torch.as_tensor(self.mean, device=x.device, dtype=x.dtype)
        std = torch.as_tensor(self.std, device=x.device, dtype=x.dtype)
        return x * std + mean

    def checkpoint_entries(self) -> dict[str, torch.Tensor]:
        """The ``mean`` / ``std`` entries of the VQ-VAE checkpoint."""
        return {"mean": torch.from_numpy(self.mean.copy()), "std": torch.from_numpy(self.std.copy())}

    @classmethod
    def from_checkpoint(cls, ckpt: dict[str, Any], path: str | Path) -> Normalizer:
        """Read the statistics stored with a VQ-VAE checkpoint (`path` names it in errors)."""
        if "mean" not in ckpt or "std" not in ckpt:
            raise ValueError(f"{path}: no dataset 'mean'/'std' stored with the VQ-VAE")
        try:
            return cls(ckpt["mean"].float().numpy(), ckpt["std"].float().numpy())
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from exc
