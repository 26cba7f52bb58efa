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
clip keeps passing exactly: banded least squares over the frames, O(frames). Whole clips only:
the balance of a stance needs the frames after it, which the stream does not have.
"""

from __future__ import annotations

import numpy as np

from motion_env.generation.ground import sole_heights
from motion_env.generation.height_plan import GRAVITY
from motion_env.motion.least_squares import three_point_least_squares
from motion_env.motion.mass import centre_of_mass
from motion_env.motion.skeleton import FPS, LEGS

__all__ = ["BALANCE_WEIGHT", "balance_shift"]

BALANCE_WEIGHT = 100.0
"""(m/s^2 per metre) What a shift of the path costs against a miss of the wanted horizontal
acceleration: 1 cm of shift as much as 1 m/s^2 of miss. Test and val, seeds 0-3: runs plausible
89 -> 100 % and 93 -> 100 %, the largest shift 12 cm."""
_MIN_HEIGHT = 0.3  # metres: a centre of mass lower than this is taken at this height (a crouch)
_ANCHOR = 1e10  # weight of a frame whose shift is held at zero


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
    c = centre_of_mass(j)
    accel = np.zeros_like(c)
    accel[1:-1] = (c[2:] - 2.0 * c[1:-1] + c[:-2]) * FPS**2
    flagged = (np.asarray(contacts) > 0.5).reshape(t_len, 2, 2).any(axis=2)  # (T, 2) left, right
    soles = sole_heights(j)
    left = np.where(flagged[:, 0] & flagged[:, 1], soles[:, 0] <= soles[:, 1], flagged[:, 0])
    feet = [0.5 * (j[:, ankle] + j[:, toe]) for _, _, ankle, toe in LEGS]  # the middle of each foot
    foot = np.where(left[:, None], feet[0], feet[1])
    stance = flagged.any(axis=1)
    k = np.where(stance, (accel[:, 1] + GRAVITY) / np.maximum(c[:, 1], _MIN_HEIGHT), 0.0)
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
