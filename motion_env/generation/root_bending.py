"""The root path bent towards joint targets and around objectives, in closed form (the path half
of :mod:`motion_env.generation.closed_form`, whose limbs are solved onto the targets after it):

- :func:`implied_route`: timed waypoints where targets put the body (for targets without a route
  that the body's path does not already bring within reach, :func:`within_reach`);
- :func:`bend_root`: the root path bent (as the waypoint snap bends it) so that the pelvis passes
  its targets exactly and the body's other targeted joints line up horizontally;
- :func:`detour`: the root path bent around :class:`~motion_env.objectives.KeepOut` cylinders and
  pushed inside :class:`~motion_env.objectives.StayInside` polygons, by the body's reach.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from motion_env.generation.closed_form import FADE, MARGIN, PELVIS, residual_field, smoothstep
from motion_env.generation.recompose import route_anchors, snap_to_waypoints
from motion_env.motion.trajectory import wrap_angle

__all__ = ["bend_root", "detour", "implied_route", "within_reach"]

ROUTE_SPACING = 20
"""Frames between the timed waypoints :func:`implied_route` gives the path controller."""
TURN_SIGMA = 3.0
"""Frames (Gaussian) over which :func:`bend_root` smooths the heading's turn with the bent path."""
REACH: dict[int, float] = {0: 0.4, 15: 0.5, 7: 0.7, 8: 0.7, 10: 0.75, 11: 0.75, 20: 0.9, 21: 0.9}
"""Metres (horizontal) from the root path at which a joint's target is within the body's reach
without walking (:func:`within_reach`; other joints: REACH_OTHER). The pelvis's is how far
:func:`bend_root` may slide the path instead."""
REACH_OTHER = 0.6


def within_reach(targets: np.ndarray, path: np.ndarray) -> bool:
    """Whether every joint target is within the body's reach (REACH, horizontally) of the root path
    (>= T, 3) at its frame: the body gets there without walking anywhere else."""
    known = ~np.isnan(targets[..., 0])
    frames, joints = np.nonzero(known)
    if not len(frames):
        return True
    dist = np.linalg.norm(targets[frames, joints][:, [0, 2]] - path[frames, :2], axis=1)
    reach = np.array([REACH.get(int(j), REACH_OTHER) for j in joints])
    return bool((dist <= reach).all())


def implied_route(
    targets: np.ndarray, spacing: int = ROUTE_SPACING, path: np.ndarray | None = None
) -> np.ndarray | None:
    """Timed waypoints (K, 3) where the targets put the body: the pelvis target's x, z where there
    is one, else the mean x, z of the frame's targeted joints; one every `spacing` frames at most,
    and the last targeted frame. None when no frame after 0 has a target, or when `path` (the
    root path the body takes without targets) already brings every target within reach
    (:func:`within_reach`): steered, the body would be sampled anew, a different motion from the
    one without targets (measured: up to 5x its largest joint acceleration), where the
    refinement only has to reach."""
    if path is not None and within_reach(targets, path):
        return None
    known = ~np.isnan(targets[..., 0])  # (T, 22)
    frames = np.flatnonzero(known.any(axis=1))
    frames = frames[frames > 0]
    if not len(frames):
        return None
    keep, last = [], -spacing
    for f in frames:
        if f - last >= spacing:
            keep.append(int(f))
            last = f
    if keep[-1] != frames[-1]:
        if frames[-1] - keep[-1] < spacing // 2:
            keep[-1] = int(frames[-1])
        else:
            keep.append(int(frames[-1]))
    rows = []
    for f in keep:
        xz = (
            targets[f, PELVIS, [0, 2]] if known[f, PELVIS] else np.nanmean(targets[f, known[f]][:, [0, 2]], 0)
        )
        rows.append([xz[0], xz[1], f])
    return np.array(rows, np.float32)


def bend_root(
    path: np.ndarray, joints: np.ndarray, targets: np.ndarray, route: np.ndarray | None, sigma: float = 6.0
) -> np.ndarray:
    """The root path bent so the pelvis meets its targets and the other targeted joints line up.

    Args:
        path: (n, 3) root path the body `joints` was composed on (frame 0 = the start).
        joints: (>= T, 22, 3) the body composed on it.
        targets: (T, 22, 3) joint targets, NaN = free.
        route: the planned route the path was snapped through (its waypoints keep their frames).
        sigma: frames; the horizontal residual of the non-pelvis targets is smoothed over this
            (Gaussian, between targeted frames), so a dense target's step-by-step sway stays in
            the body, for the refinement and the IK, rather than in the path.

    Returns:
        (n, 3) float32 path through the pelvis targets (exactly) and shifted by the smoothed
        residual of the other targets (PCHIP between targeted frames, held after the last).
    """
    t_len = targets.shape[0]
    known = ~np.isnan(targets[..., 0])
    pelvis = known[:, PELVIS]
    others = known.copy()
    others[:, PELVIS] = False
    frames = np.flatnonzero(others.any(axis=1) & ~pelvis)
    res = np.zeros((t_len, 2))
    if len(frames):
        diff = np.where(others[..., None], targets[..., [0, 2]] - joints[:t_len, :, [0, 2]], 0.0)
        mean = diff.sum(1) / np.maximum(others.sum(1), 1)[:, None]
        w = np.exp(-0.5 * ((frames[:, None] - frames[None, :]) / sigma) ** 2)
        res[frames] = (w @ mean[frames]) / w.sum(1, keepdims=True)
        # Frame 0 is where the body is: near it the limbs reach (the path would jump to them).
        res[frames] *= smoothstep(frames / FADE)[:, None]
    pf = np.flatnonzero(pelvis)
    res[pf] = targets[pf, PELVIS][:, [0, 2]] - path[pf, :2]
    anchors = {int(f): res[f] for f in np.concatenate([frames, pf])}
    if route is not None:
        for _, _, f in route_anchors(path, route):
            anchors.setdefault(int(f), np.zeros(2))
    if not anchors:
        return path
    keys = sorted(anchors)
    wp = np.array([[*(path[k, :2] + anchors[k]), k] for k in keys], np.float64)
    out = snap_to_waypoints(path, wp, keep_start=True)
    # The heading turns with the bent path's direction of travel; targets a few frames apart
    # wiggle it (a 12 cm side step spun the body 80 degrees and back in 8 frames): smoothed.
    turn = wrap_angle(out[:, 2].astype(np.float64) - path[:, 2])
    turn = gaussian_filter1d(turn, TURN_SIGMA, mode="nearest")
    out[:, 2] = path[:, 2] + turn * np.clip(np.arange(len(out)) / 4.0, 0.0, 1.0)
    return out


def detour(path: np.ndarray, joints: np.ndarray, objectives: list, margin: float = MARGIN) -> np.ndarray:
    """The root path bent around KeepOut cylinders and pushed inside StayInside polygons.

    The body's reach at each frame (the farthest joint from the pelvis, horizontally, of the body
    `joints` composed on `path`) is added to each cylinder's radius: a pelvis outside the grown
    circle keeps every joint out. A stretch of path that enters it is replaced by an arc around
    it, from the entry to the exit, on the side the path passes closest. A frame where a joint
    leaves a polygon moves the pelvis inwards by as much (faded in and out around it).
    """
    from motion_env.objectives import KeepOut, StayInside

    out = np.array(path, np.float64)
    n = min(len(out), len(joints))
    reach = np.linalg.norm(joints[:n, :, [0, 2]] - joints[:n, :1, [0, 2]], axis=-1).max(axis=1)
    for obj in objectives:
        if isinstance(obj, KeepOut):
            rows = np.zeros(len(out), bool)
            start, stop = obj.frames or (0, len(out))
            rows[start:stop] = True
            c = np.asarray(obj.center)
            grown = np.full(len(out), obj.radius + margin)
            grown[:n] += reach
            grown[n:] += reach[-1]
            rel = out[:, :2] - c
            inside = rows & (np.linalg.norm(rel, axis=1) < grown)
            edges = np.flatnonzero(np.diff(np.concatenate([[0], inside.astype(int), [0]])))
            for a, b in zip(edges[::2], edges[1::2], strict=True):
                a0, b0 = max(a - 1, 0), min(b, len(out) - 1)
                ang_a = np.arctan2(rel[a0, 1], rel[a0, 0])
                ang_b = np.arctan2(rel[b0, 1], rel[b0, 0])
                close = a + int(np.argmin(np.linalg.norm(rel[a:b], axis=1)))
                side = np.arctan2(rel[close, 1], rel[close, 0])
                # The arc from entry to exit that passes the side of the closest approach.
                sweep = (ang_b - ang_a) % (2 * np.pi)
                via = (side - ang_a) % (2 * np.pi)
                if via > sweep:
                    sweep -= 2 * np.pi
                t = np.arange(a, b)
                frac = (t - a0 + 1e-9) / max(b0 - a0, 1)
                ang = ang_a + sweep * frac
                radius = np.maximum(np.linalg.norm(rel[t], axis=1), grown[t])
                out[t, :2] = c + radius[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)
        elif isinstance(obj, StayInside):
            j = np.array(joints[:n], np.float64)
            j[..., [0, 2]] += (out[:n, :2] - j[:, 0, [0, 2]])[:, None]
            a_pts, normals = obj.edges()
            rows = np.zeros(n, bool)
            start, stop = obj.frames or (0, n)
            rows[start:stop] = True
            shift = np.zeros((n, 2))
            for _ in range(3):
                xz = j[..., [0, 2]] + shift[:, None]
                inward = ((xz[..., None, :] - a_pts) * normals).sum(-1)  # (n, J, K)
                worst = inward.min(axis=1)  # (n, K): the farthest joint past each edge
                need = np.clip(margin - worst, 0.0, None) * rows[:, None]
                shift += (need[..., None] * normals).sum(1)
            known = np.abs(shift).sum(1) > 0
            out[:n, :2] += residual_field(known, shift)
    return out.astype(np.float32)


# ----------------------------------------------------------------------------------------------
# The closed-form finish
# ----------------------------------------------------------------------------------------------
