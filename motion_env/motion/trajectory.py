"""Root paths and waypoints (numpy): shared by training, the generator, the environments and evaluation.

A *root path* is a ``(T, 3)`` float32 array of the pelvis ground position and heading per frame:
``x, z`` in world metres and the yaw ``theta`` (radians, the :mod:`motion_env.motion.kinematics` convention:
facing direction ``(sin theta, cos theta)`` in ``(x, z)``, ``theta = 0`` faces +Z). Headings in a
root path are unwrapped (continuous across +-pi) so that differences along the path are turns.

*Waypoints* are ``(K, 2)`` or ``(K, 3)``: world ``x, z`` and optionally the frame index (20 fps) at
which the pelvis should pass; :func:`validate_waypoints` turns either into ``(K, 3)`` with NaN for
untimed rows.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from motion_env.motion.kinematics import heading_from_joints, to_heading_frame
from motion_env.motion.skeleton import NUM_JOINTS
from motion_env.motion.validation import check_finite

MAX_COORDINATE = 10_000.0
"""Metres: waypoints (and starts) lie within this of the origin in x and z; float32 keeps about a
millimetre there, and a skeleton placed much farther away loses its shape."""
# Gaussian sigma (frames) that takes the step-by-step sway (hips and shoulders twist with each
# stride) out of the heading of a root path while keeping turns sharp.
HEADING_SMOOTH_SIGMA = 5.0
# Gaussian sigma (frames) that takes the gait out of a real pelvis path before the body GPT sees it
# in training (see gait_free_path).
GAIT_SMOOTH_SIGMA = 6.0

__all__ = [
    "GAIT_SMOOTH_SIGMA",
    "MAX_COORDINATE",
    "HEADING_SMOOTH_SIGMA",
    "gait_free_path",
    "relative_waypoints",
    "root_path_from_joints",
    "validate_root_path",
    "validate_waypoints",
    "waypoint_errors",
    "wrap_angle",
]


def wrap_angle(angle: np.ndarray) -> np.ndarray:
    """Wrap angles (any shape) into [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def root_path_from_joints(joints: np.ndarray, smooth_sigma: float = HEADING_SMOOTH_SIGMA) -> np.ndarray:
    """The root path of a motion.

    Args:
        joints: (T, 22, 3) world joint positions (or (B, T, 22, 3): B paths).
        smooth_sigma: Gaussian sigma (frames) applied to the unwrapped heading; 0 keeps the raw
            per-frame facing.

    Returns:
        (T, 3) (or (B, T, 3)) float32: pelvis x, z and the unwrapped, smoothed heading from the hips and
        shoulders (:func:`motion_env.motion.heading_from_joints`).
    """
    joints = np.asarray(joints, dtype=np.float32)
    if joints.ndim not in (3, 4) or joints.shape[-2:] != (NUM_JOINTS, 3) or joints.shape[-3] < 1:
        raise ValueError(f"joints must have shape (T, {NUM_JOINTS}, 3) with T >= 1, got {joints.shape}")
    theta = np.unwrap(np.asarray(heading_from_joints(joints), dtype=np.float64), axis=-1)
    if smooth_sigma > 0:
        theta = gaussian_filter1d(theta, smooth_sigma, axis=-1, mode="nearest")
    return np.stack([joints[..., 0, 0], joints[..., 0, 2], theta.astype(np.float32)], axis=-1)


def gait_free_path(root_path: np.ndarray, sigma: float = GAIT_SMOOTH_SIGMA) -> np.ndarray:
    """A root path with the sway of the steps smoothed out of its x, z (heading unchanged).

    A real pelvis surges and sways with every step (forward speed at the step rate, about 2 Hz,
    sideways at the stride rate); the path controller's paths do not. A body GPT trained on path
    features of real pelvis paths reads the gait's phase from them and, given the controller's
    smooth paths, steps at a rhythm of its own (2.2-2.5 steps/s at any speed). A Gaussian of 6
    frames keeps 2 % of a 1.5 Hz sway and 38 % of a 0.75 Hz one, and turns taking a second or more.

    Args:
        root_path: (T, 3) x, z, heading.
        sigma: Gaussian sigma in frames (0: unchanged).
    """
    path = validate_root_path(root_path).astype(np.float64)
    if sigma > 0:
        path[:, :2] = gaussian_filter1d(path[:, :2], sigma, axis=0, mode="nearest")
    return path.astype(np.float32)


def validate_root_path(root_path: np.ndarray, name: str = "root_path", batched: bool = False) -> np.ndarray:
    """Check a root path and return it as (T, 3) float32 (with `batched`, also (B, T, 3) paths;
    raises ValueError naming the problem)."""
    path = np.asarray(root_path, dtype=np.float32)
    ndim_ok = path.ndim == 2 or (batched and path.ndim == 3)
    if not ndim_ok or path.shape[-1] != 3 or path.shape[-2] < 1:
        shape = "(T, 3)" + (" or (B, T, 3)" if batched else "")
        raise ValueError(f"{name} must have shape {shape} (x, z, heading) with T >= 1, got {path.shape}")
    check_finite(path.reshape(-1, 3), name, "frames")
    return path


def validate_waypoints(waypoints: np.ndarray | list) -> np.ndarray:
    """Check waypoints and return them as (K, 3) float32 with a NaN time for untimed ones.

    Args:
        waypoints: (K, 2) world x, z or (K, 3) x, z, frame index; a time may be NaN (untimed) in
            a (K, 3) array, so timed and untimed waypoints can be mixed.

    Raises:
        ValueError: empty or wrongly shaped input, NaN/infinite coordinates, infinite or negative
            times, or timed waypoints whose times do not strictly increase.
    """
    try:
        wp = np.array(waypoints, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"waypoints must be a numeric (K, 2) or (K, 3) array: {exc}") from exc
    if wp.size == 0:
        raise ValueError("waypoints is empty: give at least one waypoint, or None for no path")
    if wp.ndim != 2 or wp.shape[1] not in (2, 3):
        hint = " (one waypoint: use [[x, z]] or [[x, z, t]])" if wp.ndim == 1 else ""
        raise ValueError(f"waypoints must have shape (K, 2) or (K, 3), got {wp.shape}{hint}")
    if not np.isfinite(wp[:, :2]).all():
        bad = np.unique(np.nonzero(~np.isfinite(wp[:, :2]))[0])
        raise ValueError(f"waypoints have NaN or infinite x/z at rows {bad[:10].tolist()}")
    far = np.nonzero(np.abs(wp[:, :2]).max(axis=1) > MAX_COORDINATE)[0]
    if len(far):
        raise ValueError(
            f"waypoints must lie within {MAX_COORDINATE:g} m of the origin in x and z, rows "
            f"{far[:10].tolist()} do not (largest {np.abs(wp[:, :2]).max():.4g} m)"
        )
    if wp.shape[1] == 2:
        wp = np.concatenate([wp, np.full((wp.shape[0], 1), np.nan)], axis=1)
    times = wp[:, 2]
    timed = ~np.isnan(times)
    if np.isinf(times).any():
        raise ValueError(f"waypoint times must be finite frame indices, got {times[np.isinf(times)][:5]}")
    if (times[timed] < 0).any():
        rows = np.nonzero(timed & (times < 0))[0]
        raise ValueError(
            f"waypoint times must be >= 0 (frame indices), rows {rows[:10].tolist()} are negative"
        )
    t = times[timed]
    if t.size > 1 and not (np.diff(t) > 0).all():
        i = int(np.nonzero(np.diff(t) <= 0)[0][0])
        rows = np.nonzero(timed)[0]
        raise ValueError(
            f"timed waypoints must have strictly increasing times: row {rows[i + 1]} (t={t[i + 1]:g}) "
            f"does not come after row {rows[i]} (t={t[i]:g})"
        )
    return wp.astype(np.float32)


def relative_waypoints(position: np.ndarray, heading: np.ndarray, waypoints_xz: np.ndarray) -> np.ndarray:
    """Waypoints seen from the character: offsets in its heading frame.

    Args:
        position: (..., 2) the character's x, z.
        heading: (...,) its heading.
        waypoints_xz: (..., K, 2) world x, z of the waypoints.

    Returns:
        (..., K, 2) float32 (lateral, + = the character's left; forward) offsets in metres.
    """
    position = np.asarray(position, dtype=np.float64)
    offsets = np.asarray(waypoints_xz, dtype=np.float64) - position[..., None, :]
    theta = np.broadcast_to(np.asarray(heading, dtype=np.float64)[..., None], offsets.shape[:-1])
    return np.asarray(to_heading_frame(offsets, theta), dtype=np.float32)


def waypoint_errors(root_xz: np.ndarray, waypoints: np.ndarray | list) -> np.ndarray:
    """Distance (metres, XZ) between the pelvis and each waypoint.

    Timed waypoints are measured at their frame (the root error of ``docs/metrics.md``; a time past the end of
    the motion is measured at the last frame, a fractional one at the nearest frame); untimed ones
    at the closest approach after the previous waypoint's frame of passage.

    Args:
        root_xz: (T, 2) pelvis x, z per frame (or a (T, 3) root path).
        waypoints: (K, 2) or (K, 3) as accepted by :func:`validate_waypoints`.

    Returns:
        (K,) float32 distances.
    """
    xz = np.asarray(root_xz, dtype=np.float64)
    if xz.ndim != 2 or xz.shape[1] not in (2, 3) or xz.shape[0] < 1:
        raise ValueError(f"root_xz must have shape (T, 2) or (T, 3), got {xz.shape}")
    xz = xz[:, :2]
    wp = validate_waypoints(waypoints).astype(np.float64)
    last = xz.shape[0] - 1
    errors = np.empty(len(wp))
    after = 0  # frame of passage of the previous waypoint: untimed ones are searched from there
    for k, (x, z, t) in enumerate(wp):
        if np.isnan(t):
            dist = np.linalg.norm(xz[after:] - (x, z), axis=1)
            i = int(np.argmin(dist))
            errors[k] = dist[i]
            after += i
        else:
            f = min(int(np.rint(t)), last)
            errors[k] = np.linalg.norm(xz[f] - (x, z))
            after = f
    return errors.astype(np.float32)
