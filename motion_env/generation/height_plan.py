"""The height plan of the physics stage (:mod:`motion_env.generation.physics`): heights of the
centre of mass that obey gravity in flight and stay within what legs can give on the floor, as
close to the wanted heights as they can, by bounded least squares over the second differences.

Short plans (the stream's tokens) are solved densely (:func:`_bounded_lstsq`); long ones (whole
clips) in the heights, where every step of the active set is one banded solve
(:func:`_banded_heights`), O(frames) instead of O(frames^3). :func:`plan_heights` of an (R, n) array plans the
same token of R characters at once (one batched solve per step of the active set, the same
heights within 1e-9 m): 15-20x less time than row by row at 64 characters.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.linalg import get_lapack_funcs
from scipy.optimize import lsq_linear

from motion_env.motion.skeleton import FPS

__all__ = ["GRAVITY", "STANCE_ACCELERATION", "plan_heights"]

GRAVITY = 9.81  # m/s^2
# Vertical acceleration (m/s^2) of the centre of mass while a foot is on the floor. The floor
# only pushes, and friction needs some push to carry horizontal forces, so the body falls slower
# than free fall; runners' legs push with up to about 2.5 body weights.
STANCE_ACCELERATION = (-0.75 * GRAVITY, 2.5 * GRAVITY)
# Weights of the height plan's least squares: keep the wanted heights, their velocities and
# (weakly) the changes of their accelerations.
_WEIGHT_POSITION, _WEIGHT_VELOCITY, _WEIGHT_JERK = 1.0, 1.0, 0.5
# Longer plans (frames, the past's included) are solved in the heights (:func:`_banded_heights`),
# shorter ones (the stream's tokens) over the second differences (:func:`_bounded_lstsq`).
_DENSE_FRAMES = 24


@functools.lru_cache(maxsize=64)
def _height_basis(m: int) -> np.ndarray:
    """(m, m) matrix B with heights = B @ x, x = (c_0, c_1, s_1 .. s_{m-2}): the first two heights
    and the second differences at frames 1..m-2 (m >= 2). Cached, read-only."""
    k = np.arange(m)[:, None]
    basis = np.zeros((m, m))
    basis[:, 0] = 1.0 - k[:, 0]
    basis[:, 1] = k[:, 0]
    basis[:, 2:] = np.maximum(k - np.arange(1, m - 1)[None, :], 0)
    basis.setflags(write=False)
    return basis


def plan_heights(
    raw: np.ndarray,
    flight: np.ndarray,
    past: np.ndarray | None = None,
    past_raw: np.ndarray | None = None,
) -> np.ndarray:
    """Heights of the centre of mass that obey gravity, as close to the wanted ones as they can.

    Bounded least squares over the second differences: in the air the centre of mass falls
    freely (acceleration -GRAVITY: a parabola through the take-off and the landing), with a foot
    on the floor its acceleration stays within :data:`STANCE_ACCELERATION`; the heights, their
    velocities and (weakly) the changes of their accelerations follow `raw`, so heights that obey
    both already stay as they are.

    Args:
        raw: (n,) wanted heights of the frames to plan; (R, n): R characters at once, each with
            the same numbers of past (h) and new (n) frames (the stream's token of every
            character), a leading R axis on every argument (:func:`_plan_rows`).
        flight: (h + n,) bool, frames in the air (:func:`flight_frames`), the past frames' first.
        past: (h,) heights of the h (0 to 3) frames before, which stay as they are (the stream's
            emitted frames); None: none.
        past_raw: (h,) their wanted heights.

    Returns:
        (n,) planned heights ((R, n) for R characters).
    """
    raw = np.asarray(raw, dtype=np.float64)
    if raw.ndim == 2:
        r = len(raw)
        none = np.zeros((r, 0))
        return _plan_rows(
            raw,
            np.asarray(flight, dtype=bool).reshape(r, -1),
            none if past is None else np.asarray(past, dtype=np.float64).reshape(r, -1),
            none if past_raw is None else np.asarray(past_raw, dtype=np.float64).reshape(r, -1),
        )
    past = np.zeros(0) if past is None else np.asarray(past, dtype=np.float64)
    past_raw = np.zeros(0) if past_raw is None else np.asarray(past_raw, dtype=np.float64)
    h, n = len(past), len(raw)
    m = h + n
    if m < 3:  # no frame with a neighbour on each side: no acceleration to plan
        return raw.copy()
    dt2 = 1.0 / FPS**2
    fixed = np.full(m, np.nan)  # x = (c_0, c_1, s_1 .. s_{m-2}); NaN: free
    fixed[: min(h, 2)] = past[:2]
    for i in range(1, h - 1):  # accelerations the emitted frames already show
        fixed[i + 1] = past[i + 1] - 2 * past[i] + past[i - 1]
    air = np.asarray(flight, dtype=bool)[1 : m - 1] & np.isnan(fixed[2:])
    fixed[2:][air] = -GRAVITY * dt2
    free = np.isnan(fixed)
    first = max(h, 1)
    wanted = np.concatenate([past_raw, raw])
    stencils = _objective(m, h, first, raw, wanted)
    lo, hi = np.full(m, -np.inf), np.full(m, np.inf)
    lo[2:], hi[2:] = STANCE_ACCELERATION[0] * dt2, STANCE_ACCELERATION[1] * dt2
    if m > _DENSE_FRAMES and free.any():
        return _banded_heights(stencils, fixed, lo, hi)[h:]
    basis = _height_basis(m)
    x = fixed.copy()
    if free.any():
        a = _dense_over_x(m, h, first)
        b = stencils[2]
        rhs = b - a[:, ~free] @ fixed[~free]
        x[free] = _bounded_lstsq(a[:, free], rhs, lo[free], hi[free])
    return (basis @ x)[h:]


def _plan_rows(raw: np.ndarray, flight: np.ndarray, past: np.ndarray, past_raw: np.ndarray) -> np.ndarray:
    """:func:`plan_heights` of R characters: (R, n) raw, (R, h + n) flight, (R, h) past and
    past_raw -> (R, n) heights, the same row by row within float rounding (1e-9 m).

    Short plans (h + n <= 24 frames) solve every row's active set together: each step is one
    batched solve of the normal equations over the free variables (held and fixed ones tied by
    identity rows), instead of one least squares per row and step; longer plans are planned row
    by row.
    """
    r, n = raw.shape
    h = past.shape[1]
    m = h + n
    if m < 3:
        return raw.copy()
    if m > _DENSE_FRAMES:
        return np.stack([plan_heights(raw[k], flight[k], past[k], past_raw[k]) for k in range(r)])
    dt2 = 1.0 / FPS**2
    fixed = np.full((r, m), np.nan)  # as plan_heights, a row per character
    fixed[:, : min(h, 2)] = past[:, :2]
    for i in range(1, h - 1):
        fixed[:, i + 1] = past[:, i + 1] - 2 * past[:, i] + past[:, i - 1]
    air = flight[:, 1 : m - 1] & np.isnan(fixed[:, 2:])
    fixed[:, 2:][air] = -GRAVITY * dt2
    first = max(h, 1)
    wanted = np.concatenate([past_raw, raw], axis=1)
    targets = np.concatenate(
        [
            _WEIGHT_POSITION * raw,
            _WEIGHT_VELOCITY * np.diff(wanted, axis=1)[:, first - 1 :],
            _WEIGHT_JERK * np.diff(wanted, 3, axis=1),
        ],
        axis=1,
    )
    lo, hi = np.full(m, -np.inf), np.full(m, np.inf)
    lo[2:], hi[2:] = STANCE_ACCELERATION[0] * dt2, STANCE_ACCELERATION[1] * dt2
    a = _dense_over_x(m, h, first)
    x = _bounded_normal_rows(a.T @ a, targets @ a, fixed, lo, hi)
    free = np.isnan(fixed)
    for k in np.nonzero(np.isnan(x).any(axis=1))[0]:  # rows the batched active set left unsettled
        x[k] = fixed[k]
        x[k, free[k]] = lsq_linear(
            a[:, free[k]], targets[k] - a[:, ~free[k]] @ fixed[k, ~free[k]], bounds=(lo[free[k]], hi[free[k]])
        ).x
    return (x @ _height_basis(m).T)[:, h:]


def _bounded_normal_rows(
    gram: np.ndarray, grad: np.ndarray, fixed: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """:func:`_bounded_lstsq`'s active set for R problems at once over the normal equations:
    argmin x^T G x / 2 - g_r^T x with x = `fixed` where not NaN and lo <= x <= hi elsewhere.
    `gram` (m, m) G = A^T A (shared), `grad` (R, m) g_r = A^T b_r -> (R, m) x; a row that does
    not settle within the steps :func:`_bounded_lstsq` allows is NaN."""
    r, m = grad.shape
    free = np.isnan(fixed)
    x = np.where(free, np.clip(0.0, lo, hi), fixed)
    held = np.zeros((r, m), dtype=bool)
    running = free.any(axis=1)
    eye = np.eye(m, dtype=bool)
    for _ in range(2 * m + 4):
        if not running.any():
            return x
        rows = np.nonzero(running)[0]
        tied = ~free[rows] | held[rows]
        # G over the untied variables; a tied one's row and column are the identity's.
        system = np.where(tied[:, :, None] | tied[:, None, :], eye, gram)
        rhs = np.where(tied, x[rows], grad[rows] - np.where(tied, x[rows], 0.0) @ gram)
        solution = np.linalg.solve(system, rhs[..., None])[..., 0]
        moving = ~tied
        xr = np.where(moving, solution, x[rows])
        crossed = moving & ((xr < lo) | (xr > hi))
        again = crossed.any(axis=1)
        xr = np.where(again[:, None] & free[rows], np.clip(xr, lo, hi), xr)
        held[rows] |= crossed
        pull = xr @ gram - grad[rows]  # the gradient: a held bound is released if it points inwards
        inwards = held[rows] & (((xr <= lo) & (pull < 0)) | ((xr >= hi) & (pull > 0))) & ~again[:, None]
        release = inwards.any(axis=1)
        which = np.argmax(np.abs(np.where(inwards, pull, 0.0)), axis=1)
        held[rows[release], which[release]] = False
        x[rows] = xr
        running[rows] = again | release
    x[running] = np.nan
    return x


def _objective(
    m: int, h: int, first: int, raw: np.ndarray, wanted: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The height plan's least squares, row by row over the m heights: each row asks
    sum_s coef_s heights[start + s] (s = 0..3) to be its target. Returns (R,) starts, (R, 4)
    weighted coefficients and (R,) weighted targets: the heights of the planned frames, their
    velocities, and (weakly) the changes of their accelerations (third differences)."""
    starts, coefs = _stencils(m, h, first)
    targets = np.concatenate(
        [
            _WEIGHT_POSITION * raw,
            _WEIGHT_VELOCITY * np.diff(wanted)[first - 1 :],
            _WEIGHT_JERK * np.diff(wanted, 3),
        ]
    )
    return starts, coefs, targets


@functools.lru_cache(maxsize=64)
def _stencils(m: int, h: int, first: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_objective`'s rows without their targets (they depend on the sizes only): (R,)
    starts and (R, 4) weighted coefficients. Cached (the stream plans the same sizes every
    token), read-only."""
    pos = np.arange(h, m)
    vel = np.arange(first, m)
    jerk = np.arange(m - 3)
    starts = np.concatenate([pos, vel - 1, jerk])
    coefs = np.zeros((len(starts), 4))
    coefs[: len(pos), 0] = _WEIGHT_POSITION
    coefs[len(pos) : len(pos) + len(vel), :2] = _WEIGHT_VELOCITY * np.array([-1.0, 1.0])
    coefs[len(pos) + len(vel) :] = _WEIGHT_JERK * np.array([-1.0, 3.0, -3.0, 1.0])
    starts.setflags(write=False)
    coefs.setflags(write=False)
    return starts, coefs


@functools.lru_cache(maxsize=64)
def _dense_over_x(m: int, h: int, first: int) -> np.ndarray:
    """(R, m) the rows of :func:`_objective` over x = (c_0, c_1, s_1 .. s_{m-2}) (dense, times
    :func:`_height_basis`). Cached, read-only."""
    starts, coefs = _stencils(m, h, first)
    a_y, _ = _dense((starts, coefs, np.zeros(len(starts))), m)
    a = a_y @ _height_basis(m)
    a.setflags(write=False)
    return a


def _dense(stencils: tuple, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows of :func:`_objective` as a dense (R, m) matrix over the heights and (R,) targets."""
    starts, coefs, targets = stencils
    a = np.zeros((len(starts), m + 3))
    rows = np.arange(len(starts))
    for s in range(4):
        a[rows, starts + s] = coefs[:, s]
    return a[:, :m], targets


def _height_basis_apply(x: np.ndarray) -> np.ndarray:
    """:func:`_height_basis` @ x in O(m): heights from the first two and the second differences."""
    velocity = (x[1] - x[0]) + np.cumsum(x[2:])
    return np.concatenate([x[:2], x[1] + np.cumsum(velocity)])


def _second_differences_of(y: np.ndarray) -> np.ndarray:
    """x = (c_0, c_1, s_1 .. s_{m-2}) of heights y (:func:`_height_basis`'s inverse)."""
    return np.concatenate([y[:2], y[2:] - 2 * y[1:-1] + y[:-2]])


# The KKT system of the banded plan, unknowns interleaved (height k at 2 k, the multiplier of x_k
# at 2 k + 1): a row of the least squares spans 4 frames, a constraint 3, so the system is banded.
_BAND = 6


def _banded_heights(stencils: tuple, fixed: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """:func:`_bounded_lstsq`'s active set over x = (c_0, c_1, s_1 .. s_{m-2}), solved in the
    heights: (m,) heights minimising the rows of :func:`_objective` with x fixed where `fixed` is
    not NaN and lo <= x <= hi elsewhere.

    In the heights each least-squares row spans 4 neighbouring frames and each x 3, so every step
    is one banded solve of the KKT system, O(m), where over x (dense) it costs O(m^3) and a clip
    of 400 frames took a minute; it takes :func:`_bounded_lstsq`'s steps to the same single
    solution (the problem is strictly convex)."""
    m = len(fixed)
    starts, coefs, targets = stencils
    # H = A^T A and A^T b of the heights, as (2 m) x (2 m) band entries at the height positions.
    band = np.zeros((2 * _BAND + 1, 2 * m))
    grad_b = np.zeros(m)
    for s in range(4):
        rows = starts + s < m  # a row's stencil may run past the last frame with zeros
        np.add.at(grad_b, starts[rows] + s, coefs[rows, s] * targets[rows])
        for t in range(4):
            both = rows & (starts + t < m)
            # entry (start + s, start + t) of H sits at band[_BAND + 2 (s - t), 2 (start + t)]
            np.add.at(band, (_BAND + 2 * (s - t), 2 * (starts[both] + t)), coefs[both, s] * coefs[both, t])
    # The constraint of x_k: heights k, k-1, k-2 with 1, -2, 1 (k >= 2), height k alone (k < 2).
    k = np.arange(m)
    cons_rows, cons_cols, cons_vals = [2 * k + 1], [2 * k], [np.ones(m)]
    cons_rows += [2 * k[2:] + 1, 2 * k[2:] + 1]
    cons_cols += [2 * (k[2:] - 1), 2 * (k[2:] - 2)]
    cons_vals += [np.full(m - 2, -2.0), np.ones(m - 2)]
    cons_rows, cons_cols = np.concatenate(cons_rows), np.concatenate(cons_cols)
    cons_vals, owner = np.concatenate(cons_vals), np.concatenate([k, k[2:], k[2:]])  # x each belongs to
    free = np.isnan(fixed)
    x = np.where(free, np.clip(0.0, lo, hi), fixed)
    held = np.zeros(m, dtype=bool)
    (gbsv,) = get_lapack_funcs(("gbsv",), (band,))
    for _ in range(2 * int(free.sum()) + 4):
        tied = ~free | held
        ab = np.zeros((3 * _BAND + 1, 2 * m))  # LAPACK's band layout: _BAND spare rows on top
        ab[_BAND:] = band
        on = tied[owner]
        # the constraint row (multiplier row) and, symmetric, its column
        ab[2 * _BAND + cons_rows[on] - cons_cols[on], cons_cols[on]] = cons_vals[on]
        ab[2 * _BAND + cons_cols[on] - cons_rows[on], cons_rows[on]] = cons_vals[on]
        ab[2 * _BAND, 2 * k[~tied] + 1] = 1.0  # an untied multiplier is 0
        rhs = np.zeros(2 * m)
        rhs[0::2] = grad_b
        rhs[1::2] = np.where(tied, x, 0.0)
        _, _, solution, info = gbsv(_BAND, _BAND, ab, rhs, overwrite_ab=True, overwrite_b=True)
        if info != 0:
            break  # singular (cannot happen for a strictly convex plan): the general solver
        y = solution[0::2]
        moving = free & ~held
        x[moving] = _second_differences_of(y)[moving]
        crossed = moving & ((x < lo) | (x > hi))
        if crossed.any():
            x = np.where(free, np.clip(x, lo, hi), x)
            held |= crossed
            continue
        residual = _band_matvec(band, y) - grad_b  # A^T (A y - b)
        pull = _basis_transpose(residual)  # the gradient over x
        inwards = held & (((x <= lo) & (pull < 0)) | ((x >= hi) & (pull > 0)))
        if not inwards.any():
            return _height_basis_apply(x)
        held[np.argmax(np.abs(np.where(inwards, pull, 0.0)))] = False
    a_y, b = _dense(stencils, m)
    a = a_y @ _height_basis(m)
    x[free] = lsq_linear(a[:, free], b - a[:, ~free] @ x[~free], bounds=(lo[free], hi[free]), method="bvls").x
    return _height_basis_apply(x)


def _band_matvec(band: np.ndarray, y: np.ndarray) -> np.ndarray:
    """H @ y for the height block of a :func:`_banded_heights` band (heights at even positions)."""
    m = len(y)
    out = np.zeros(m)
    for d in range(-3, 4):  # H couples heights up to 3 frames apart
        diag = band[_BAND - 2 * d, 0::2]  # entry (k, k + d) is at column 2 (k + d)
        if d >= 0:
            out[: m - d] += diag[d:] * y[d:]
        else:
            out[-d:] += diag[: m + d] * y[: m + d]
    return out


def _basis_transpose(v: np.ndarray) -> np.ndarray:
    """:func:`_height_basis`(m).T @ v in O(m): (m,) -> (m,)."""
    k = np.arange(len(v))
    once = np.cumsum(v[::-1])[::-1]  # sum over k >= i of v_k
    out = np.cumsum(once[::-1])[::-1]  # sum over k >= i of (k - i + 1) v_k
    out[0] = ((1.0 - k) * v).sum()
    out[1] = (k * v).sum()
    return out


def _bounded_lstsq(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """argmin |a x - b| with lo <= x <= hi: (M, N), (M,), (N,), (N,) -> (N,).

    An active set: bounds that the free solution crosses are held, and released again where the
    gradient pulls inwards. The stream's problems are a few variables, for which this is many
    times faster than scipy's general solver; that one finishes what does not settle here.
    """
    x = np.clip(np.zeros(a.shape[1]), lo, hi)
    held = np.zeros(a.shape[1], dtype=bool)
    for _ in range(2 * a.shape[1] + 4):
        free = ~held
        if free.any():
            x[free] = np.linalg.lstsq(a[:, free], b - a[:, held] @ x[held], rcond=None)[0]
        crossed = free & ((x < lo) | (x > hi))
        if crossed.any():
            x = np.clip(x, lo, hi)
            held |= crossed
            continue
        pull = a.T @ (a @ x - b)  # the gradient: a held bound is released if it points inwards
        inwards = held & (((x <= lo) & (pull < 0)) | ((x >= hi) & (pull > 0)))
        if not inwards.any():
            return x
        held[np.argmax(np.abs(np.where(inwards, pull, 0.0)))] = False
    return lsq_linear(a, b, bounds=(lo, hi), method="bvls").x
