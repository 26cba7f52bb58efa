"""Joint targets and objectives in closed form: the path bent towards them, the limbs solved onto them.

The refinement (:mod:`motion_env.generation.refine`) brings the generated body close to its
targets by optimising what the generator produces; this module finishes the job exactly:

- the root path bent towards the targets and around the objectives:
  :mod:`motion_env.generation.root_bending`;
- :func:`solve_limbs`: closed-form IK on the limb chains, in order: pelvis height (pelvis targets,
  head and pelvis height limits, the height a head target asks for; the legs keep the feet where
  they were), spine (head targets: the upper body leans about the pelvis), legs (ankle and toe
  targets; feet planted elsewhere stay planted), arms (wrist targets). Every bone keeps its length.

A correction at a targeted frame reaches its neighbours through :func:`residual_field`: linear
between targets up to GAP frames apart, faded in and out over FADE frames (a smoothstep) elsewhere,
and held constant while a foot is planted, so nothing pops and a planted foot does not slide;
every stage's is then rounded off in time (:func:`smooth_field`, still exact at the targets): a
plant next to a target made a leg jump, and targets a frame or two apart, each met by a
correction joined linearly to the next, put a kink at every one (head targets on a quarter of a
wave's frames: a wrist at 3.65x the clip's largest acceleration without targets; smoothed,
the head at 1.56x).
:func:`causal_field` is the stream's version: it needs no frame after the one being corrected.

Smoothness (measured with ``scripts/measure_refine_smoothness.py``: a corrected clip's largest
joint acceleration against the same clip's): a two-bone chain solved near full extension or
folded flat moves its middle joint by far more than its end moves (a straight leg lowered 5 mm
bends its knee 4 cm), so :func:`_two_bone` keeps the middle joint on the side it bent to,
measured against the chain's own axis while the chain is open and as close as it can stay to
where it was while it is folded, and reaches the last SOFT_LEG / SOFT_ARM metres before full
extension softly (the end stops a few millimetres short instead of snapping the chain straight);
a wrist correction fades as a turn about the shoulder and a change of reach (a straight cut from
a folded arm's wrist passes by the shoulder, where the elbow swings); a head target is met by the
pelvis height and a lean of the upper body about the pelvis (not by bending the nearly straight
spine, whose middle swings with every centimetre the head's distance to the pelvis changes); the
knees bend the way the body faces (not the toes, which turn as a foot lifts); where a target swings
a chain so far from the decoded one that the side its middle joint bent to flips, the flip is
spread over the frames around it (:func:`_steady_poles`); a head target out of reach near the
pelvis is leaned towards as if it were a spine's length away.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from motion_env.generation.feet import soft_limit
from motion_env.motion.least_squares import three_point_least_squares
from motion_env.motion.skeleton import JOINT_NAMES, LEGS, NUM_JOINTS

__all__ = [
    "MARGIN",
    "PELVIS",
    "smoothstep",
    "ARMS",
    "FADE",
    "HEAD_DROP",
    "GAP",
    "MISS_TOLERANCE",
    "causal_field",
    "solve_limbs",
    "limit_bounds",
    "residual_field",
    "smooth_field",
    "target_errors",
]

FADE = 10
"""Frames (0.5 s) over which a correction fades in before a target and out after it."""
GAP = 2 * FADE
"""Targets at most this many frames apart are joined by a linear correction instead of two fades."""
MISS_TOLERANCE = 0.02
"""Metres: a target farther than this from its joint in the finished clip is reported as missed."""
RAMP = 0.5
"""Metres: how much looser a height limit is FADE frames before (and after) the frames it covers."""
MARGIN = 0.02
"""Metres of clearance the closed-form finish keeps inside limits and outside KeepOut cylinders."""
SOFT_LEG, SOFT_ARM = 0.01, 0.03
"""Metres before full extension where a leg's (arm's) IK starts to reach its target softly."""
FOLD = (0.15, 0.45)
"""Chain openings (end-to-root distance over the chain's length) between which :func:`_two_bone`
turns from keeping the middle joint where it was (folded) to keeping its side (open)."""
SMOOTH_FRAMES = 6.0
"""Frames: the time scale over which :func:`smooth_field` rounds off a leg correction's kinks
(chosen on 48 controlled val clips: 3 / 4 / 6 / 8 frames gave a 90th-percentile ratio to the clip
without targets of 1.40 / 1.35 / 1.29 / 1.28, unsmoothed 1.56; errors unchanged; foot targets'
clips skate a little more, 0.205 -> 0.210: the slide)."""
PLANT_WEIGHT = 4.0
"""How much more a planted foot's frames than free frames hold their correction (smooth_field)."""
ARM_ACCEL = 0.025
"""Metres per frame squared (10 m/s^2): a wrist correction fades in and out over FADE frames, or
longer where its size needs it to stay under this acceleration (a smoothstep of D metres over F
frames peaks at 6 D / F^2): a target a metre's sweep from the sampled wrist, faded over 10 frames,
swung it at 115 m/s^2 (val: the largest controlled clip's acceleration over its starting clip's,
2.49 -> 2.13x; 10 m/s^2 and 5 m/s^2 gave the same; test unchanged)."""
POLE_TURN, POLE_SIGMA = 0.3, 2.0
"""Radians a frame, frames: where a middle joint's bend plane turns about its chain faster than
POLE_TURN from one frame to the next (a target that swings the chain far from the decoded one,
where the side the joint bent to is poorly defined), the turn is spread over the frames around it
by a Gaussian of POLE_SIGMA frames (:func:`_steady_poles`)."""
HEAD_DROP, HEAD_RISE = 0.3, 0.03
"""Metres the pelvis goes down (up) at most so that a head target keeps the spine's length."""

PELVIS, SPINE3, HEAD = 0, 9, 15
ARMS: tuple[tuple[int, int, int], ...] = ((16, 18, 20), (17, 19, 21))  # shoulder, elbow, wrist
LOWER_SPINE = (3, 6)  # between the pelvis and spine3
UPPER_BODY = (12, 13, 14, 15, 16, 17, 18, 19, 20, 21)  # hang from spine3
LEG_JOINTS = tuple(j for leg in LEGS for j in leg[1:])  # knees, ankles, toes: they keep the floor
PELVIS_MOVED = (0, 1, 2, 3, 6, 9, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21)  # move with the pelvis height
SOLVED = (PELVIS, HEAD, 7, 8, 10, 11, 20, 21)  # joints with a closed-form finish
_VERTICAL = set(PELVIS_MOVED) - {20, 21, 18, 19}  # height limits met by moving the pelvis


def smoothstep(x: np.ndarray) -> np.ndarray:
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
    out[fade_out] += (1 - smoothstep((t_all - p)[fade_out] / fade))[:, None] * res[p[fade_out]]
    out[fade_in] += (1 - smoothstep((n - t_all)[fade_in] / fade))[:, None] * res[n[fade_in]]
    out[exact] = res[t_all[exact]]
    return out


def smooth_field(
    field: np.ndarray, exact: np.ndarray, weight: np.ndarray, frames: float = SMOOTH_FRAMES
) -> np.ndarray:
    """`field` (T, D) with its kinks and steps rounded off over about `frames` frames (a weighted
    Whittaker smoother: least squares on the distance from `field`, `weight` per frame, plus the
    squared second difference times frames^4), equal to `field` at the `exact` frames (T,) bool.

    :func:`residual_field` holds a planted foot's correction and joins targets linearly: between a
    plant and a target a few frames later it jumped tens of cm in 2-3 frames (a foot target 42 cm
    off: a 70 m/s^2 foot, 1.9x the clip without targets). Smoothed, the plant gives way instead.
    """
    t = len(field)
    if t < 3 or frames <= 0 or exact.all() or not np.abs(field).any():
        return np.asarray(field, np.float64)
    field = np.asarray(field, np.float64)
    second = np.tile(frames**2 * np.array([1.0, -2.0, 1.0]), (t - 2, 1))  # frames^2 x the second difference
    w = np.where(exact, 1e8, np.asarray(weight, np.float64))
    return three_point_least_squares(second, np.zeros((t - 2, field.shape[1])), w, field)


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
            fading = (1 - smoothstep(np.array(last[0] / FADE))) * last[1]
        ahead = np.flatnonzero(known[t : t + FADE + 1])
        w = 0.0
        if len(ahead):
            w = 1.0 if ahead[0] == 0 else float(smoothstep(np.array(1.0 - ahead[0] / (FADE + 1))))
            out[t] = (1 - w) * (current[t] + fading) + w * target[t + int(ahead[0])]
        else:
            out[t] = current[t] + fading
        if known[t]:
            last = (0, target[t] - current[t])
    return out, last


# ----------------------------------------------------------------------------------------------
# The root path
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


def _two_bone(
    root: np.ndarray,
    mid: np.ndarray,
    end: np.ndarray,
    target: np.ndarray,
    hint: np.ndarray | None = None,
    soft: float = 0.0,
    frames: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Two-bone IK per frame (root fixed, bone lengths kept, the end moved to `target`) whose middle
    joint moves as smoothly as the target: all (N, 3); returns (new middle, new end).

    The middle joint keeps the side it bent to: measured against the chain's own root-end axis
    while the chain is open (as :func:`~motion_env.generation.feet.two_bone_ik`: against the new
    axis a nearly straight chain's side is noise), as close to where it was as it can stay while
    the chain is folded (end near the root, where the axis itself turns with every millimetre the
    end moves), blended between the FOLD openings. `hint` (e.g. the way the body faces) adds a
    5 cm bias, so a straight chain bends that way. Within `soft` metres of full extension, a
    target beyond where the end already was is reached softly (exponentially): the end stops a
    few millimetres short rather than snapping the chain straight (0: exact, clamped). `frames`
    (N,) int, the rows' frame numbers: rows of consecutive frames turn their bend plane no faster
    than :func:`_steady_poles` allows.
    """
    l1 = np.linalg.norm(mid - root, axis=-1)
    l2 = np.linalg.norm(end - mid, axis=-1)
    to = target - root
    d = np.linalg.norm(to, axis=-1)
    u = to / np.maximum(d, 1e-9)[:, None]
    lo, hi = np.abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4
    chain = end - root
    d0 = np.linalg.norm(chain, axis=-1)
    if soft > 0:
        # Softened only beyond where the end was, so an unmoved chain stays exactly as it was.
        start = np.maximum(np.minimum(d0, hi - 1e-4), hi - soft)
        d = soft_limit(d, start, np.maximum(hi - start, 1e-6))
    d = np.clip(d, lo, hi)
    axis0 = chain / np.maximum(d0, 1e-9)[:, None]
    bend = (mid - root) - ((mid - root) * axis0).sum(-1, keepdims=True) * axis0
    if hint is not None:
        bend = bend + 0.05 * hint / np.maximum(np.linalg.norm(hint, axis=-1, keepdims=True), 1e-9)
    # Open: the side it bent to. A chain swung far from the decoded one (a foot target past hip
    # height) loses that side (it shrinks to nothing and flips); `frames` spreads such a flip.
    side = bend - (bend * u).sum(-1, keepdims=True) * u
    near = (mid - root) - ((mid - root) * u).sum(-1, keepdims=True) * u  # folded: where it was
    side /= np.maximum(np.linalg.norm(side, axis=-1, keepdims=True), 1e-12)
    near /= np.maximum(np.linalg.norm(near, axis=-1, keepdims=True), 1e-12)
    w = smoothstep((d0 / np.maximum(l1 + l2, 1e-9) - FOLD[0]) / (FOLD[1] - FOLD[0]))[:, None]
    pole = w * side + (1.0 - w) * near
    pole_n = np.linalg.norm(pole, axis=-1, keepdims=True)
    # A straight chain with no hint has no bend plane: bend along the original second bone.
    fallback = (end - mid) - ((end - mid) * u).sum(-1, keepdims=True) * u
    pole = np.where(pole_n > 1e-6, pole / np.maximum(pole_n, 1e-12), fallback)
    pole /= np.maximum(np.linalg.norm(pole, axis=-1, keepdims=True), 1e-12)
    if frames is not None:
        pole = _steady_poles(pole, u, frames)
    a = (l1**2 - l2**2 + d**2) / (2 * d)
    h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
    return root + a[:, None] * u + h[:, None] * pole, root + d[:, None] * u


def _steady_poles(pole: np.ndarray, axis: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Unit bend directions `pole` (N, 3), each perpendicular to its chain's `axis` (N, 3), with
    the turns faster than POLE_TURN a frame spread in time (rows of consecutive `frames` (N,)).

    Each run of consecutive frames measures its poles' angle about the axis against a reference
    carried from frame to frame (the last frame's reference, made perpendicular to the new axis),
    unwraps it, and replaces it near the fast turns by its Gaussian average (POLE_SIGMA frames),
    blended back to the pole as it was a few frames away from them.
    """
    out = pole.copy()
    for run in np.split(np.arange(len(frames)), np.flatnonzero(np.diff(frames) != 1) + 1):
        if len(run) < 3:
            continue
        p, ax = pole[run], axis[run]
        ref = np.empty_like(p)
        ref[0] = p[0]
        for t in range(1, len(run)):
            v = ref[t - 1] - (ref[t - 1] @ ax[t]) * ax[t]
            n = np.linalg.norm(v)
            ref[t] = v / n if n > 1e-9 else p[t]
        across = np.cross(ax, ref)
        theta = np.unwrap(np.arctan2((p * across).sum(-1), (p * ref).sum(-1)))
        fast = np.zeros(len(run))
        fast[1:] = np.abs(np.diff(theta)) > POLE_TURN
        if not fast.any():
            continue
        fast[:-1] = np.maximum(fast[:-1], fast[1:])
        near = np.clip(gaussian_filter1d(fast, POLE_SIGMA) * np.sqrt(2 * np.pi) * POLE_SIGMA, 0.0, 1.0)
        angle = theta + near * (gaussian_filter1d(theta, POLE_SIGMA, mode="nearest") - theta)
        out[run] = np.cos(angle)[:, None] * ref + np.sin(angle)[:, None] * across
    return out


def _rotvec(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 3) rotation vectors (axis x angle) turning the directions of `a` onto those of `b`."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-9)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-9)
    axis = np.cross(a, b)
    sin = np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = np.arctan2(sin, (a * b).sum(-1, keepdims=True))
    return axis / np.maximum(sin, 1e-12) * angle


def _rotate(v: np.ndarray, rotvec: np.ndarray) -> np.ndarray:
    """(N, 3) vectors turned by (N, 3) rotation vectors (Rodrigues)."""
    angle = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    k = rotvec / np.maximum(angle, 1e-12)
    cos, sin = np.cos(angle), np.sin(angle)
    return v * cos + np.cross(k, v) * sin + k * (k * v).sum(-1, keepdims=True) * (1 - cos)


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
    # A head target (where no pelvis target or limit says otherwise): the pelvis height at which
    # the head's distance to the pelvis is the spine's own, so the spine only leans (stage 2).
    head = ~np.isnan(targets[:, HEAD, 1]) & ~known
    if head.any():
        p, goal = j[head, PELVIS], targets[head, HEAD]
        spine = np.linalg.norm(j[head, HEAD] - p, axis=-1)
        across = np.linalg.norm((goal - p)[:, [0, 2]], axis=-1)
        dy = goal[:, 1] - p[:, 1] - np.sqrt(np.maximum(spine**2 - across**2, 0.0))
        need[head] = np.clip(dy, -HEAD_DROP, HEAD_RISE)
        known |= head
    if known.any():
        dy = smooth_field(residual_field(known, need[:, None]), known, np.ones(t), SMOOTH_FRAMES)[:, 0]
        j[:, list(PELVIS_MOVED), 1] += dy[:, None]


def _solve_spine(j: np.ndarray, targets: np.ndarray) -> None:
    """Stage 2: head targets, the upper body (spine and all above) leaning about the pelvis; in place.

    Stage 1 put the pelvis at the height where the target is as far from it as the head is, so
    the lean meets the target (a target lower than HEAD_DROP, or higher than HEAD_RISE, is missed
    by the difference and reported)."""
    known = ~np.isnan(targets[:, HEAD, 0])
    if not known.any():
        return
    field = residual_field(known, np.nan_to_num(targets[:, HEAD] - j[:, HEAD]))
    field = smooth_field(field, known, np.ones(len(j)), SMOOTH_FRAMES)
    rows = np.flatnonzero(np.abs(field).sum(1) > 1e-9)
    if not len(rows):
        return
    p, h = j[rows, PELVIS], j[rows, HEAD]
    # A target nearer the pelvis than the spine is long (lower than HEAD_DROP lets the pelvis go)
    # is aimed at as if that much higher: near the pelvis its direction turns with every
    # centimetre, and the upper body swung round the pelvis (260 m/s^2 at the head).
    spine = h - p
    aim = h + field[rows] - p
    length = np.linalg.norm(spine, axis=1, keepdims=True)
    short = np.maximum(length - np.linalg.norm(aim, axis=1, keepdims=True), 0.0)
    lean = _shortest_arc(spine, aim + short * spine / np.maximum(length, 1e-9))
    for k in (*LOWER_SPINE, SPINE3, *UPPER_BODY):
        j[rows, k] = p + np.einsum("nij,nj->ni", lean, j[rows, k] - p)


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
        field = smooth_field(field, known, np.where(planted[:, leg], PLANT_WEIGHT, 1.0), SMOOTH_FRAMES)
        want = before[:, ankle] + field
        moved = np.flatnonzero(
            (np.abs(field).sum(1) > 1e-9) | (np.abs(j[:, hip] - before[:, hip]).sum(1) > 1e-9)
        )
        if not len(moved):
            continue
        # A knee bends the way the body faces (the toes turn as the foot lifts: the knee flipped).
        facing = np.cross(before[moved, 1] - before[moved, 2], np.array([0.0, 1.0, 0.0]))
        # The leg as it was, carried along with its hip (so the IK reads the true bone lengths).
        carry = j[moved, hip] - before[moved, hip]
        knee0, ankle0 = before[moved, knee] + carry, before[moved, ankle] + carry
        new_knee, new_ankle = _two_bone(j[moved, hip], knee0, ankle0, want[moved], facing, SOFT_LEG, moved)
        new_foot = before[moved, toe] - before[moved, ankle]
        both = has_ankle[moved] & has_toe[moved]
        if both.any():  # the foot turned towards its toe target, its length kept
            aim = targets[moved[both], toe] - new_ankle[both]
            aim /= np.maximum(np.linalg.norm(aim, axis=1, keepdims=True), 1e-9)
            new_foot[both] = aim * np.linalg.norm(new_foot[both], axis=1, keepdims=True)
        j[moved, knee], j[moved, ankle], j[moved, toe] = new_knee, new_ankle, new_ankle + new_foot


def _solve_arms(j: np.ndarray, targets: np.ndarray, low: np.ndarray, high: np.ndarray) -> None:
    """Stage 4: wrist targets and wrist height limits, a two-bone solve shoulder - elbow - wrist
    (:func:`_two_bone`) on a correction faded as a turn about the shoulder and a change of reach."""
    for shoulder, elbow, wrist in ARMS:
        goal = targets[:, wrist].copy()
        y = j[:, wrist, 1]
        dy = np.clip(low[:, wrist] + MARGIN - y, 0.0, None) + np.clip(high[:, wrist] - MARGIN - y, None, 0.0)
        rows = (dy != 0) & np.isnan(goal[:, 0])
        goal[rows] = j[rows, wrist] + np.array([0.0, 1.0, 0.0]) * dy[rows, None]
        known = ~np.isnan(goal[:, 0])
        if not known.any():
            continue
        # The correction as a turn about the shoulder and a change of reach, each faded in time:
        # the wrist sweeps round the shoulder rather than cutting past it (a straight cut from a
        # folded arm's wrist to a target passes by the shoulder, where the elbow swung 30 cm in
        # a frame).
        rel = j[:, wrist] - j[:, shoulder]
        want = np.nan_to_num(goal) - j[:, shoulder]
        reach = np.linalg.norm(want, axis=1) - np.linalg.norm(rel, axis=1)
        turn = _rotvec(rel, want)
        # A big correction fades over more frames (ARM_ACCEL); targets up to twice that apart join.
        size = np.linalg.norm(turn[known], axis=1) * np.linalg.norm(rel[known], axis=1) + np.abs(reach[known])
        fade = max(FADE, int(np.ceil(np.sqrt(6.0 * float(size.max()) / ARM_ACCEL))))
        field = residual_field(known, np.concatenate([turn, reach[:, None]], 1), fade=fade, gap=2 * fade)
        field = smooth_field(field, known, np.ones(len(j)), SMOOTH_FRAMES)
        rows = np.flatnonzero(np.abs(field).sum(1) > 1e-9)
        dist = np.linalg.norm(rel[rows], axis=1)
        turned = _rotate(rel[rows] / np.maximum(dist, 1e-9)[:, None], field[rows, :3])
        aim = j[rows, shoulder] + turned * (dist + field[rows, 3])[:, None]
        new_elbow, new_wrist = _two_bone(
            j[rows, shoulder], j[rows, elbow], j[rows, wrist], aim, soft=SOFT_ARM, frames=rows
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
