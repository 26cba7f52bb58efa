"""Joint targets and objectives in closed form: the path bent towards them, the limbs solved onto them.

The refinement (:mod:`motion_env.generation.refine`) brings the generated body close to its
targets by optimising what the generator produces; this module finishes the job exactly:

- :func:`implied_route`: timed waypoints where targets put the body (for targets without a route);
- :func:`bend_root`: the root path bent (as the waypoint snap bends it) so that the pelvis passes
  its targets exactly and the body's other targeted joints line up horizontally;
- :func:`detour`: the root path bent around :class:`~motion_env.objectives.KeepOut` cylinders and
  pushed inside :class:`~motion_env.objectives.StayInside` polygons, by the body's reach;
- :func:`solve_limbs`: closed-form IK on the limb chains, in order: pelvis height (head and pelvis
  height limits; the legs keep the feet where they were), spine (head targets: a two-bone solve
  pelvis - spine3 - head), legs (ankle and toe targets; feet planted elsewhere stay planted),
  arms (wrist targets). Every bone keeps its length.

A correction at a targeted frame reaches its neighbours through :func:`residual_field`: linear
between targets up to GAP frames apart, faded in and out over FADE frames (a smoothstep) elsewhere,
and held constant while a foot is planted, so nothing pops and a planted foot does not slide.
:func:`causal_field` is the stream's version: it needs no frame after the one being corrected.
"""

from __future__ import annotations

import numpy as np

from motion_env.generation.feet import LEGS, two_bone_ik
from motion_env.generation.recompose import route_anchors, snap_to_waypoints
from motion_env.motion.skeleton import JOINT_NAMES, NUM_JOINTS

__all__ = [
    "ARMS",
    "FADE",
    "GAP",
    "MISS_TOLERANCE",
    "causal_field",
    "detour",
    "solve_limbs",
    "implied_route",
    "limit_bounds",
    "residual_field",
    "target_errors",
]

FADE = 10
"""Frames (0.5 s) over which a correction fades in before a target and out after it."""
GAP = 2 * FADE
"""Targets at most this many frames apart are joined by a linear correction instead of two fades."""
MISS_TOLERANCE = 0.02
"""Metres: a target farther than this from its joint in the finished clip is reported as missed."""
ROUTE_SPACING = 20
"""Frames between the timed waypoints :func:`implied_route` gives the path controller."""
RAMP = 0.5
"""Metres: how much looser a height limit is FADE frames before (and after) the frames it covers."""
MARGIN = 0.02
"""Metres of clearance the closed-form finish keeps inside limits and outside KeepOut cylinders."""

PELVIS, SPINE3, HEAD = 0, 9, 15
ARMS: tuple[tuple[int, int, int], ...] = ((16, 18, 20), (17, 19, 21))  # shoulder, elbow, wrist
LOWER_SPINE = (3, 6)  # rotate with the pelvis -> spine3 segment
UPPER_BODY = (12, 13, 14, 15, 16, 17, 18, 19, 20, 21)  # hang from spine3
LEG_JOINTS = tuple(j for leg in LEGS for j in leg[1:])  # knees, ankles, toes: they keep the floor
PELVIS_MOVED = (0, 1, 2, 3, 6, 9, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21)  # move with the pelvis height
SOLVED = (PELVIS, HEAD, 7, 8, 10, 11, 20, 21)  # joints with a closed-form finish
_VERTICAL = set(PELVIS_MOVED) - {20, 21, 18, 19}  # height limits met by moving the pelvis


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def residual_field(
    known: np.ndarray, residual: np.ndarray, hold: np.ndarray | None = None, fade: int = FADE, gap: int = GAP
) -> np.ndarray:
    """A correction for every frame from the corrections at some frames.

    Args:
        known: (T,) bool, the frames whose correction is given.
        residual: (T, D) the corrections (read where `known`).
        hold: optional (T,) bool, frames that move as one block (a planted foot): a block that
            holds a known frame takes that frame's correction (linear between several).
        fade, gap: see FADE and GAP.

    Returns:
        (T, D) float64: `residual` at known frames, linear between known frames up to `gap`
        apart, faded out over `fade` frames elsewhere (0 beyond).
    """
    known = np.asarray(known, bool).copy()
    res = np.where(known[:, None], np.asarray(residual, np.float64), 0.0)
    t_all = np.arange(len(known))
    if hold is not None and known.any():
        hold = np.asarray(hold, bool)
        edges = np.flatnonzero(np.diff(np.concatenate([[0], hold.astype(int), [0]])))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            inside = np.flatnonzero(known[a:b]) + a
            if len(inside):
                block = np.arange(a, b)
                res[a:b] = np.stack(
                    [np.interp(block, inside, res[inside, d]) for d in range(res.shape[1])], -1
                )
                known[a:b] = True
    idx = np.flatnonzero(known)
    out = np.zeros_like(res)
    if not len(idx):
        return out
    nxt = np.searchsorted(idx, t_all)  # first known frame >= t
    prv = nxt - 1
    has_prev, has_next = prv >= 0, nxt < len(idx)
    p = idx[np.clip(prv, 0, len(idx) - 1)]
    n = idx[np.clip(nxt, 0, len(idx) - 1)]
    exact = has_next & (n == t_all)
    joined = has_prev & has_next & ~exact & (n - p <= gap)
    w = np.where(joined, (t_all - p) / np.maximum(n - p, 1), 0.0)
    out[joined] = (1 - w[joined, None]) * res[p[joined]] + w[joined, None] * res[n[joined]]
    apart = ~exact & ~joined
    fade_out = apart & has_prev
    fade_in = apart & has_next
    out[fade_out] += (1 - _smoothstep((t_all - p)[fade_out] / fade))[:, None] * res[p[fade_out]]
    out[fade_in] += (1 - _smoothstep((n - t_all)[fade_in] / fade))[:, None] * res[n[fade_in]]
    out[exact] = res[t_all[exact]]
    return out


def causal_field(
    current: np.ndarray, target: np.ndarray, known: np.ndarray, last: tuple[int, np.ndarray] | None
) -> tuple[np.ndarray, tuple[int, np.ndarray] | None]:
    """The stream's correction of one joint over a few new frames, without looking past them.

    Args:
        current: (n, 3) the joint's positions in the new frames (before the correction).
        target: (n + FADE, 3) its targets in those frames and the FADE frames after (NaN = none).
        known: (n + FADE,) bool, where `target` is given.
        last: (frames since the last target, residual there) carried from the previous call.

    Returns:
        (n, 3) desired positions, and the carry for the next call. Towards a coming target the
        joint is blended into it (smoothstep over FADE frames, exact at the target's frame);
        after one, the residual it had there fades out over FADE frames.
    """
    n = len(current)
    out = current.astype(np.float64).copy()
    for t in range(n):
        if last is not None:
            last = (last[0] + 1, last[1])
        fading = np.zeros(3)
        if last is not None and last[0] < FADE:
            fading = (1 - _smoothstep(np.array(last[0] / FADE))) * last[1]
        ahead = np.flatnonzero(known[t : t + FADE + 1])
        w = 0.0
        if len(ahead):
            w = 1.0 if ahead[0] == 0 else float(_smoothstep(np.array(1.0 - ahead[0] / (FADE + 1))))
            out[t] = (1 - w) * (current[t] + fading) + w * target[t + int(ahead[0])]
        else:
            out[t] = current[t] + fading
        if known[t]:
            last = (0, target[t] - current[t])
    return out, last


# ----------------------------------------------------------------------------------------------
# The root path
# ----------------------------------------------------------------------------------------------


def implied_route(targets: np.ndarray, spacing: int = ROUTE_SPACING) -> np.ndarray | None:
    """Timed waypoints (K, 3) where the targets put the body: the pelvis target's x, z where there
    is one, else the mean x, z of the frame's targeted joints; one every `spacing` frames at most,
    and the last targeted frame. None when no frame after 0 has a target."""
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
    return snap_to_waypoints(path, wp, keep_start=True)


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


def _shortest_arc(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 3) rotation matrices turning the directions of `a` onto those of `b` (Rodrigues)."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-9)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-9)
    v = np.cross(a, b)
    c = (a * b).sum(-1)
    k = np.zeros(v.shape + (3,))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    scale = 1.0 / np.maximum(1.0 + c, 1e-6)
    return np.eye(3) + k + (k @ k) * scale[:, None, None]


def _ramped(low: np.ndarray, high: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height bounds eased in and out: over the FADE frames before and after a limited stretch the
    bound moves from RAMP metres looser to its value, so the body starts to duck (or rise) before
    the limit begins instead of jumping at its first frame (frame by frame, so the stream can too)."""
    out = []
    for bound, sign in ((low, -1.0), (high, 1.0)):
        b = bound.copy()
        idx = np.flatnonzero(np.isfinite(bound))
        if len(idx):
            t = np.arange(len(b))
            nxt = np.clip(np.searchsorted(idx, t), 0, len(idx) - 1)
            prv = np.clip(nxt - 1, 0, len(idx) - 1)
            near = np.where(np.abs(idx[prv] - t) < np.abs(idx[nxt] - t), idx[prv], idx[nxt])
            dist, value = np.abs(near - t), bound[near]  # the nearest limited frame
            ramp = (dist > 0) & (dist <= FADE)
            b[ramp] = value[ramp] + sign * RAMP * dist[ramp] / FADE
        out.append(b)
    return out[0], out[1]


def limit_bounds(limits: list, num_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(T, 22) lowest and highest allowed height per joint and frame from HeightLimit objectives."""
    low, high = np.full((num_frames, NUM_JOINTS), -np.inf), np.full((num_frames, NUM_JOINTS), np.inf)
    for lim in limits:
        lo, hi = _ramped(*lim.bounds(num_frames))
        low[:, lim.index] = np.maximum(low[:, lim.index], lo)
        high[:, lim.index] = np.minimum(high[:, lim.index], hi)
    return low, high


def _solve_pelvis_height(j: np.ndarray, targets: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
    """Stage 1: the pelvis (and all it carries) up or down; in place (the legs are re-solved later)."""
    t = len(j)
    up, down = np.zeros(t), np.zeros(t)
    known = np.zeros(t, bool)
    for k in sorted(_VERTICAL):
        y = j[:, k, 1]
        up = np.maximum(up, np.clip(low[:, k] + MARGIN - y, 0.0, None))
        down = np.minimum(down, np.clip(high[:, k] - MARGIN - y, None, 0.0))
        known |= np.isfinite(low[:, k]) | np.isfinite(high[:, k])
    need = np.where(down < 0, down, up)  # a ceiling wins over a floor
    pelvis = ~np.isnan(targets[:, PELVIS, 1])
    need[pelvis] = targets[pelvis, PELVIS, 1] - j[pelvis, PELVIS, 1]
    known |= pelvis
    if known.any():
        dy = residual_field(known, need[:, None])[:, 0]
        j[:, list(PELVIS_MOVED), 1] += dy[:, None]


def _solve_spine(j: np.ndarray, targets: np.ndarray) -> None:
    """Stage 2: head targets, a two-bone solve pelvis - spine3 - head; in place."""
    known = ~np.isnan(targets[:, HEAD, 0])
    if not known.any():
        return
    field = residual_field(known, np.nan_to_num(targets[:, HEAD] - j[:, HEAD]))
    rows = np.flatnonzero(np.abs(field).sum(1) > 1e-9)
    if not len(rows):
        return
    p, s3, h = j[rows, PELVIS], j[rows, SPINE3], j[rows, HEAD]
    across = j[rows, 1] - j[rows, 2]  # left hip - right hip
    forward = np.cross(across, np.array([0.0, 1.0, 0.0]))
    new_s3, new_h = two_bone_ik(p, s3, h, h + field[rows], -forward)  # a slouch rather than an arch
    r1 = _shortest_arc(s3 - p, new_s3 - p)
    r2 = _shortest_arc(h - s3, new_h - new_s3)
    for k in LOWER_SPINE:
        j[rows, k] = p + np.einsum("nij,nj->ni", r1, j[rows, k] - p)
    for k in UPPER_BODY:
        j[rows, k] = new_s3 + np.einsum("nij,nj->ni", r2, j[rows, k] - s3)
    j[rows, SPINE3] = new_s3


def _solve_legs(
    j: np.ndarray,
    before: np.ndarray,
    targets: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    planted: np.ndarray,
) -> None:
    """Stage 3: each ankle where it was before stage 1, or on its (ankle or toe) target; in place."""
    for leg, (hip, knee, ankle, toe) in enumerate(LEGS):
        foot = before[:, toe] - before[:, ankle]
        goal = np.full((len(j), 3), np.nan)
        has_ankle = ~np.isnan(targets[:, ankle, 0])
        has_toe = ~np.isnan(targets[:, toe, 0])
        goal[has_toe] = targets[has_toe, toe] - foot[has_toe]
        goal[has_ankle] = targets[has_ankle, ankle]
        for k, shift_joint in ((ankle, ankle), (toe, toe)):
            y = before[:, shift_joint, 1]
            dy = np.clip(low[:, k] + MARGIN - y, 0.0, None) + np.clip(high[:, k] - MARGIN - y, None, 0.0)
            rows = (dy != 0) & np.isnan(goal[:, 0])
            goal[rows] = before[rows, ankle] + np.array([0.0, 1.0, 0.0]) * dy[rows, None]
        known = ~np.isnan(goal[:, 0])
        field = residual_field(known, np.nan_to_num(goal - before[:, ankle]), hold=planted[:, leg])
        want = before[:, ankle] + field
        moved = np.flatnonzero(
            (np.abs(field).sum(1) > 1e-9) | (np.abs(j[:, hip] - before[:, hip]).sum(1) > 1e-9)
        )
        if not len(moved):
            continue
        toes = before[moved, toe] - before[moved, ankle]
        toes[:, 1] = 0.0
        # The leg as it was, carried along with its hip (so the IK reads the true bone lengths).
        carry = j[moved, hip] - before[moved, hip]
        knee0, ankle0 = before[moved, knee] + carry, before[moved, ankle] + carry
        new_knee, new_ankle = two_bone_ik(j[moved, hip], knee0, ankle0, want[moved], toes)
        new_foot = before[moved, toe] - before[moved, ankle]
        both = has_ankle[moved] & has_toe[moved]
        if both.any():  # the foot turned towards its toe target, its length kept
            aim = targets[moved[both], toe] - new_ankle[both]
            aim /= np.maximum(np.linalg.norm(aim, axis=1, keepdims=True), 1e-9)
            new_foot[both] = aim * np.linalg.norm(new_foot[both], axis=1, keepdims=True)
        j[moved, knee], j[moved, ankle], j[moved, toe] = new_knee, new_ankle, new_ankle + new_foot


def _solve_arms(j: np.ndarray, targets: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
    """Stage 4: wrist targets and wrist height limits, a two-bone solve shoulder - elbow - wrist."""
    for shoulder, elbow, wrist in ARMS:
        goal = targets[:, wrist].copy()
        y = j[:, wrist, 1]
        dy = np.clip(low[:, wrist] + MARGIN - y, 0.0, None) + np.clip(high[:, wrist] - MARGIN - y, None, 0.0)
        rows = (dy != 0) & np.isnan(goal[:, 0])
        goal[rows] = j[rows, wrist] + np.array([0.0, 1.0, 0.0]) * dy[rows, None]
        known = ~np.isnan(goal[:, 0])
        if not known.any():
            continue
        field = residual_field(known, np.nan_to_num(goal - j[:, wrist]))
        rows = np.flatnonzero(np.abs(field).sum(1) > 1e-9)
        new_elbow, new_wrist = two_bone_ik(
            j[rows, shoulder], j[rows, elbow], j[rows, wrist], j[rows, wrist] + field[rows]
        )
        j[rows, elbow], j[rows, wrist] = new_elbow, new_wrist


def solve_limbs(
    joints: np.ndarray,
    targets: np.ndarray,
    limits: list,
    planted: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """The closed-form finish (stages in the module docstring): (T, 22, 3) joints -> (T, 22, 3) float32.

    Args:
        joints: the composed body with its feet pinned.
        targets: (T, 22, 3) joint targets, NaN = free.
        limits: HeightLimit objectives.
        planted: (T, 2) bool, the left and right foot in contact (the decoder's flags): a
            correction of a foot is held constant over a contact that holds its target.
        bounds: (T, 22) lowest and highest heights instead of those of `limits` (the stream's
            window of :func:`limit_bounds`).
    """
    j = np.array(joints, np.float64)
    before = j.copy()
    low, high = limit_bounds(limits, len(j)) if bounds is None else bounds
    _solve_pelvis_height(j, targets, low, high)
    _solve_spine(j, targets)
    _solve_legs(j, before, targets, low, high, planted)
    _solve_arms(j, targets, low, high)
    return j.astype(np.float32)


def target_errors(joints: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances (m) of the targeted joints from their targets: ((N,) distances, (N, 2) frame, joint)."""
    known = ~np.isnan(targets[..., 0])
    where = np.argwhere(known)
    dist = np.linalg.norm(joints[known] - targets[known], axis=-1)
    return dist, where


def describe_misses(
    dist: np.ndarray, where: np.ndarray, tolerance: float = MISS_TOLERANCE, limit: int = 5
) -> str:
    """A sentence naming the worst targets missed by more than `tolerance` ('' when none)."""
    missed = np.flatnonzero(dist > tolerance)
    if not len(missed):
        return ""
    worst = missed[np.argsort(-dist[missed])][:limit]
    parts = [f"{JOINT_NAMES[where[k, 1]]} at frame {where[k, 0]} by {dist[k] * 100:.1f} cm" for k in worst]
    more = f" (and {len(missed) - len(worst)} more)" if len(missed) > len(worst) else ""
    return (
        f"{len(missed)} of {len(dist)} joint targets missed by more than {tolerance * 100:g} cm: "
        + ", ".join(parts)
        + more
    )
