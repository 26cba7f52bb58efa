"""Per-token path features: what the body GPT reads about how the root moves next.

A root path (``(T, 3)`` x, z, heading; :mod:`motion_env.motion.trajectory`) becomes one
``D_PATH``-vector per motion token: the root's velocity and turn rate over the token and over the
next second, in the heading frame of the token's first frame.
"""

from __future__ import annotations

import numpy as np

from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.kinematics import to_heading_frame
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_root_path

__all__ = ["D_PATH", "LOOKAHEAD_FRAMES", "first_token_path_features", "token_path_features"]

# Per-token path features (see token_path_features): velocity (lateral, forward) and turn rate over
# the token, then the same over the next second.
D_PATH = 6
# The long horizon of the path features: one second ahead.
LOOKAHEAD_FRAMES = FPS


def _average_motion(path: np.ndarray, starts: np.ndarray, horizon: int) -> np.ndarray:
    """Mean velocity (lateral, forward; m/s) and turn rate (rad/s) from each start over `horizon`
    frames: (..., T, 3) paths with unwrapped headings -> (..., N, 3).

    The horizon is clamped at the end of the path; the average is over the frames actually
    available (zero at the last frame), so a clamped window still describes the speed.
    """
    n = path.shape[-2]
    ends = np.minimum(starts + horizon, n - 1)
    frames = np.maximum(ends - starts, 1).astype(np.float64)[:, None]
    disp = path[..., ends, :2] - path[..., starts, :2]  # (..., N, 2) world
    local = to_heading_frame(disp, path[..., starts, 2])  # (..., N, 2) lateral, forward
    turn = (path[..., ends, 2] - path[..., starts, 2])[..., None]  # (..., N, 1)
    return np.concatenate([local, turn], axis=-1) / frames * FPS


def token_path_features(root_path: np.ndarray, rate: int) -> np.ndarray:
    """Per-token path features that tell the body GPT how the root moves next.

    For the token starting at frame ``f = k * rate``, in the heading frame at ``f``: the mean
    velocity (lateral, forward; m/s) and turn rate (rad/s) from ``f`` to ``f + rate``, then the same
    from ``f`` to ``f + 20`` (one second ahead). Windows are clamped at the end of the path.
    Velocities in m/s and turn rates in rad/s keep the values O(1) (a walk is ~1.3 m/s).

    Args:
        root_path: (T, 3) x, z, heading (wrapped or unwrapped).
        rate: frames per token (the VQ-VAE's temporal downsampling).

    Returns:
        (ceil(T / rate), D_PATH) float32.
    """
    path = validate_root_path(root_path).astype(np.float64)
    if int(rate) != rate or rate < 1:
        raise ValueError(f"rate must be a positive integer (frames per token), got {rate!r}")
    rate = int(rate)
    path[:, 2] = np.unwrap(path[:, 2])
    starts = np.arange(0, path.shape[0], rate)
    short = _average_motion(path, starts, rate)
    long = _average_motion(path, starts, LOOKAHEAD_FRAMES)
    return np.concatenate([short, long], axis=1).astype(np.float32)


def first_token_path_features(paths: np.ndarray, rate: int) -> np.ndarray:
    """The path features of the first token of each of N root paths at once: (N, T, 3) paths
    (x, z, heading), each starting at a token's first frame -> (N, D_PATH) float32, row n equal to
    ``token_path_features(paths[n], rate)[0]`` (the stream needs only each character's next
    token's; its paths are checked where they are made). Compiled
    (:mod:`motion_env.models.path_features_jit`) where numba runs, the same numbers."""
    path = np.asarray(paths, np.float32).astype(np.float64)
    if jit_enabled() and path.ndim == 3 and path.shape[-1] == 3 and path.shape[1] >= 1:
        from motion_env.models.path_features_jit import first_token_features

        note_first_compile(first_token_features, "the stream's path features")
        return first_token_features(path, int(rate), LOOKAHEAD_FRAMES, float(FPS))
    path[..., 2] = np.unwrap(path[..., 2], axis=-1)
    first = np.zeros(1, dtype=np.int64)
    short = _average_motion(path, first, int(rate))
    long = _average_motion(path, first, LOOKAHEAD_FRAMES)
    return np.concatenate([short, long], axis=-1)[:, 0].astype(np.float32)
