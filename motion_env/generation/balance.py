"""Horizontal physics for whole clips: the root path shifted so that the floor's push passes
through the centre of mass.

The physics stage (:mod:`motion_env.generation.physics`) makes the vertical motion obey gravity
and leaves horizontal positions alone. But a body standing on one foot can only be pushed along
the line from that foot to its centre of mass (the floor pushes, it cannot twist the body), so
in stance the horizontal acceleration of the centre of mass must be that line's share of the
vertical push, ``(c - p) * (a_y + g) / c_y`` (c: centre of mass, p: the middle of the standing
foot, both horizontal; c_y: its height), and in flight it is zero. A generated run misses that by
about twice what a real run does, and the MuJoCo replay then needs a torque at the root that the
floor cannot give (the model card's Naturalness, session 18).

:func:`balance_shift` finds a horizontal shift d(t) of the root path (the feet stage then keeps
the planted feet where they are, so the shift moves the centre of mass against them) that makes
the shifted body's horizontal acceleration as close to that as it can while the shift stays
small (:data:`BALANCE_WEIGHT`) and is zero at the start and at the route's waypoints, which the
clip keeps passing exactly: banded least squares over the frames, O(frames).

:class:`StreamBalance` is the same balance for the stream, causal: each token's frames get their
shift from the same least squares over a short window, which begins at the two frames already
emitted (their shift kept) and looks :data:`STREAM_HORIZON` frames past the token. The body of
those frames is not decoded yet: there the window asks only that the shift's velocity hold and
the shift stay small, which keeps the token from ending on a shift that runs away (as a whole
clip's later frames do; without it a long run's shift grows). Test runs streamed: plausible 21
-> 24 of 28 (seeds 0-3); the horizon's length (2-32 frames) and what it assumes of the stance
change one clip at most.
"""

from __future__ import annotations

import numpy as np

from motion_env.generation.ground import sole_heights
from motion_env.generation.height_plan import GRAVITY
from motion_env.motion.least_squares import three_point_least_squares
from motion_env.motion.mass import centre_of_mass
from motion_env.motion.skeleton import FPS, LEGS

__all__ = ["BALANCE_WEIGHT", "STREAM_HORIZON", "StreamBalance", "balance_shift"]

BALANCE_WEIGHT = 100.0
"""(m/s^2 per metre) What a shift of the path costs against a miss of the wanted horizontal
acceleration: 1 cm of shift as much as 1 m/s^2 of miss. Test and val, seeds 0-3: runs plausible
89 -> 100 % and 93 -> 100 %, the largest shift 12 cm."""
STREAM_HORIZON = 16
"""Frames past a streamed token that its balance looks at (the body there not yet decoded)."""
_MIN_HEIGHT = 0.3  # metres: a centre of mass lower than this is taken at this height (a crouch)
_ANCHOR = 1e10  # weight of a frame whose shift is held at zero


def _support(joints: np.ndarray, contacts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre of mass (..., 3), the middle of the standing foot (..., 3) and stance (...) bool of
    (..., 22, 3) joints with (..., 4) contact channels: a frame with a flagged foot stands on it
    (on the lower of two)."""
    c = centre_of_mass(joints)
    flagged = (np.asarray(contacts) > 0.5).reshape(*contacts.shape[:-1], 2, 2).any(axis=-1)  # left, right
    soles = sole_heights(joints)
    left = np.where(flagged[..., 0] & flagged[..., 1], soles[..., 0] <= soles[..., 1], flagged[..., 0])
    feet = [0.5 * (joints[..., ankle, :] + joints[..., toe, :]) for _, _, ankle, toe in LEGS]
    foot = np.where(left[..., None], feet[0], feet[1])
    return c, foot, flagged.any(axis=-1)


def _stiffness(accel_y: np.ndarray, com_y: np.ndarray, stance: np.ndarray) -> np.ndarray:
    """k = (a_y + g) / c_y in stance, 0 in flight: the horizontal acceleration the floor's push
    gives per metre between the foot and the centre of mass."""
    return np.where(stance, (accel_y + GRAVITY) / np.maximum(com_y, _MIN_HEIGHT), 0.0)


def balance_shift(joints: np.ndarray, contacts: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """(T, 2) float64 horizontal shift (x, z) of a clip's root path.

    Args:
        joints: (T, 22, 3) the composed body on its root path (before the feet stage).
        contacts: (T, 4) the decoded contact channels (left ankle, left toe, right ankle, right
            toe; > 0.5 = in contact): a frame with a flagged foot is in stance, on the flagged
            foot (on the lower of two).
        anchors: frames whose shift is zero (the start, the waypoints' frames).
    """
    j = np.asarray(joints, dtype=np.float64)
    t_len = len(j)
    if t_len < 3:
        return np.zeros((t_len, 2))
    c, foot, stance = _support(j, np.asarray(contacts))
    accel = np.zeros_like(c)
    accel[1:-1] = (c[2:] - 2.0 * c[1:-1] + c[:-2]) * FPS**2
    k = _stiffness(accel[:, 1], c[:, 1], stance)
    # Each frame t in 1..T-2: FPS^2 (d[t-1] - 2 d[t] + d[t+1]) - k d[t] = k (c - p) - a (horizontal).
    rhs = np.where(stance[:, None], k[:, None] * (c - foot)[:, [0, 2]], 0.0) - accel[:, [0, 2]]
    f2 = float(FPS**2)
    coef = np.stack([np.full(t_len, f2), -2.0 * f2 - k, np.full(t_len, f2)], axis=1)[1:-1]  # (T-2, 3)
    held = np.asarray(anchors, dtype=np.int64)
    held = held[(held >= 0) & (held < t_len)]
    weight = np.full(t_len, BALANCE_WEIGHT**2)
    weight[held] += _ANCHOR
    shift = three_point_least_squares(coef, rhs[1:-1], weight, np.zeros((t_len, 2)))
    shift[held] = 0.0  # within 1e-6 m of it already
    return shift


class StreamBalance:
    """:func:`balance_shift` for the stream, one token at a time (module docstring).

    Per character it keeps what the next token's first equations read of the frames already
    emitted: the shift and the (unshifted) centre of mass of the last two, the standing foot and
    stance of the last.
    """

    def __init__(self, batch_size: int) -> None:
        self._shift = np.zeros((batch_size, 2, 2))
        self._com = np.full((batch_size, 2, 3), np.nan)  # nan: no frame emitted yet
        self._foot = np.zeros((batch_size, 3))
        self._stance = np.zeros(batch_size, bool)

    def reset(self, i: int) -> None:
        """Character i starts again (its first frame's shift is zero, as a whole clip's)."""
        self._shift[i], self._com[i] = 0.0, np.nan

    def shift_rows(
        self,
        rows: np.ndarray,
        joints: np.ndarray,
        contacts: np.ndarray,
        anchors: list[np.ndarray],
        held: np.ndarray | None = None,
    ) -> np.ndarray:
        """(N, R, 2) horizontal shift (x, z) of the token just composed for each of `rows`.

        Args:
            rows: (N,) the characters.
            joints: (N, R, 22, 3) their token's frames, composed on the root path.
            contacts: (N, R, 4) its decoded contact channels.
            anchors: per row, the frames (counted from the token's first) whose shift is zero:
                waypoints within the token and the horizon after it.
            held: (N,) bool, rows not shifted (joint control: as whole clips, not balanced).
        """
        n, rate = joints.shape[:2]
        span = 2 + rate + STREAM_HORIZON  # the window: 2 frames emitted, the token, the horizon
        c, foot, stance = _support(np.asarray(joints, np.float64), np.asarray(contacts))
        # The equations centred on the token's frames -1 .. rate - 2 read frames -2 .. rate - 1.
        com = np.concatenate([self._com[rows], c], axis=1)
        accel = (com[:, 2:] - 2.0 * com[:, 1:-1] + com[:, :-2]) * FPS**2
        standing = np.concatenate([self._stance[rows, None], stance[:, :-1]], axis=1)
        on = np.concatenate([self._foot[rows, None], foot[:, :-1]], axis=1)
        k = _stiffness(accel[..., 1], com[:, 1:-1, 1], standing)
        rhs = np.where(standing[..., None], k[..., None] * (com[:, 1:-1] - on), 0.0) - accel
        known = np.isfinite(accel).all(axis=-1)  # not on a first token, before its first frame
        f2 = float(FPS**2)
        # The horizon's equations (k 0, rhs 0): the shift's velocity holds.
        k_all = np.concatenate([np.where(known, k, 0.0), np.zeros((n, span - 2 - rate))], axis=1)
        coef = np.stack([np.full_like(k_all, f2), -2.0 * f2 - k_all, np.full_like(k_all, f2)], -1)
        coef[:, :rate] *= known[..., None]  # an equation on frames not emitted drops out
        rows_rhs = np.zeros((n, span - 2, 2))
        rows_rhs[:, :rate] = np.where(known[..., None], rhs[..., [0, 2]], 0.0)
        pull = np.full((n, span), BALANCE_WEIGHT**2)
        pull[:, :2] += _ANCHOR  # the emitted frames keep their shift
        first = np.isnan(self._com[rows, 1, 0])
        pull[first, 2] += _ANCHOR  # a first frame is not shifted
        target = np.zeros((n, span, 2))
        target[:, :2] = self._shift[rows]
        ahead = [np.asarray(f, np.int64) for f in anchors]
        ahead = [f[(f >= 0) & (f < span - 2)] for f in ahead]  # the window's frames after the emitted
        for r, frames in enumerate(ahead):
            pull[r, frames + 2] += _ANCHOR
        shift = three_point_least_squares(coef, rows_rhs, pull, target)[:, 2 : 2 + rate]
        shift[first, 0] = 0.0
        for r, frames in enumerate(ahead):
            shift[r, frames[frames < rate]] = 0.0  # within 1e-6 m of it already
        if held is not None:
            shift[held] = 0.0
        self._shift[rows] = shift[:, -2:]
        self._com[rows], self._foot[rows], self._stance[rows] = c[:, -2:], foot[:, -1], stance[:, -1]
        return shift
