"""The body on the floor: its soles, which feet touch the floor, and the legs' re-solve that puts
planted feet on it and lifts free feet out of it.

The physics stage (:mod:`motion_env.generation.physics`) plans the heights of the centre of mass
(:func:`motion_env.motion.mass.centre_of_mass`); this module measures the body that plan moves
(:func:`sole_heights`, :func:`flight_frames`, :func:`support_gap`) and places it
(:func:`place_body`, :func:`ground_feet`). The sole is the replay's humanoid's
(:mod:`motion_env.replay.humanoid`).
"""

from __future__ import annotations

import numpy as np

from motion_env.generation.feet import HINT_WEIGHT, TOE_HINT_LENGTH, two_bone_ik
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.mass import COM_WEIGHTS, centre_of_mass
from motion_env.motion.rotations import vector_norm
from motion_env.motion.skeleton import LEGS

__all__ = [
    "FLAT_ANKLE_HEIGHT",
    "FLAT_ANKLE_RANGE",
    "FLIGHT_CLEARANCE",
    "MAX_STRETCH",
    "PLANT_REACH",
    "SWING_CLEARANCE",
    "SWING_LANDING",
    "SWING_RISE",
    "SWING_SPEEDS",
    "SWING_STRAIGHT",
    "deepest_reach",
    "flight_frames",
    "ground_feet",
    "place_body",
    "sole_heights",
    "support_gap",
    "swing_clearance",
]

# The ankle's height above the sole of a flat foot (m) until the clip shows flat feet (it is 5 to
# 10 cm, by the mocap source).
FLAT_ANKLE_HEIGHT = 0.09
FLAT_ANKLE_RANGE = (0.03, 0.12)
# The sole, as the replay's humanoid has it (:mod:`motion_env.replay.humanoid`): a capsule of
# this radius (m) from HEEL_BACK behind the ankle to TOE_FRONT ahead of the toe joint.
HEEL_BACK, TOE_FRONT, SOLE_RADIUS = 0.05, 0.02, 0.02
# A foot whose sole is this close to the floor (m) touches it, whatever its contact flags.
FLIGHT_CLEARANCE = 0.015
# A foot marked planted but farther above the floor than this (m), with the other foot free, is
# not stood on. The contact channels are HumanML3D's: a foot joint slower than about 0.9 m/s,
# whatever its height (:mod:`motion_env.motion.features`), so a slow foot in the air has them too.
PLANT_REACH = 0.05
# A planted foot is pulled down no farther than its leg reaches without stretching beyond this
# share of its length (or as far as it already was): a straight leg's knee would swing far to
# gain the last centimetres.
MAX_STRETCH = 0.99
# A free foot that moves clears the floor: its sole rises to SWING_CLEARANCE (m) as its
# horizontal speed grows over SWING_SPEEDS (m/s); a foot that drags along the floor slides on it.
# The clearance rises by at most SWING_RISE (m) a frame after the foot leaves the floor: the
# contact flags end as a foot speeds up, and the foot must not jump up at that frame.
SWING_CLEARANCE = 0.025
SWING_SPEEDS = (0.2, 0.6)
SWING_RISE = 0.01
# A free foot whose sole went down more than this (m) since the last frame is landing, and so is
# one on a leg stretched beyond SWING_STRAIGHT of its length (a heel reaching for the floor):
# lifting it would swing the knee far.
SWING_LANDING, SWING_STRAIGHT = 0.005, 0.97
# Shift-then-ground passes: grounding a planted leg moves its knee, and so the centre of mass a
# little; each pass removes most of what is left, until it is within _PLACE_TOLERANCE (m).
_PASSES, _PLACE_TOLERANCE = 8, 2e-5


def sole_heights(joints: np.ndarray, flat_ankle: float | np.ndarray = FLAT_ANKLE_HEIGHT) -> np.ndarray:
    """Height of each foot's lowest sole point: (..., 22, 3) -> (..., 2) (left, right); `flat_ankle`
    is one height or one per frame (...).

    The sole is a capsule of radius :data:`SOLE_RADIUS` from the heel, :data:`HEEL_BACK` behind
    the ankle, to the toes, :data:`TOE_FRONT` ahead of the toe joint (the ball of the foot), its
    bottom level with the toe joint when the foot is flat (the ankle `flat_ankle` m above it); it
    turns with the foot as the foot pitches (pointed toes reach below the toe joint).
    """
    out = []
    for _, _, ankle, toe in LEGS:
        bone = joints[..., toe, :] - joints[..., ankle, :]
        length = vector_norm(bone)
        reach = np.sqrt(np.maximum(length**2 - flat_ankle**2, 1e-6))  # toe joint ahead of the ankle, flat
        turn = np.arctan2(bone[..., 1], np.hypot(bone[..., 0], bone[..., 2])) - np.arctan2(-flat_ankle, reach)
        up = SOLE_RADIUS - flat_ankle  # the sole's axis above the ankle when flat
        ends = [(-HEEL_BACK, up), (reach + TOE_FRONT, up)]  # (ahead, above) the ankle, flat
        lowest = np.minimum(*[ahead * np.sin(turn) + above * np.cos(turn) for ahead, above in ends])
        out.append(joints[..., ankle, 1] + lowest - SOLE_RADIUS)
    return np.stack(out, axis=-1)


def swing_clearance(speed: np.ndarray, free_frames: np.ndarray, descent: np.ndarray) -> np.ndarray:
    """Lowest sole height (m) of a free foot moving at horizontal `speed` (m/s) for `free_frames`
    frames (1 on the first frame off the floor) whose sole went down by `descent` (m) since the
    last frame; any shape, the three broadcast. A foot coming down to land gets none: the contact
    flags start only as it slows, and lifting a landing leg would swing its knee."""
    ramp = (np.asarray(speed) - SWING_SPEEDS[0]) / (SWING_SPEEDS[1] - SWING_SPEEDS[0])
    rise = np.minimum(SWING_CLEARANCE * np.clip(ramp, 0.0, 1.0), SWING_RISE * np.asarray(free_frames))
    return np.where(np.asarray(descent) > SWING_LANDING, 0.0, rise)


def ground_feet(
    joints: np.ndarray,
    down: np.ndarray,
    clearance: np.ndarray | None = None,
    flat_ankle: float | np.ndarray = FLAT_ANKLE_HEIGHT,
    pull: np.ndarray | None = None,
) -> np.ndarray:
    """Feet onto the floor, free feet out of it: (N, 22, 3) joints, (N, 2) bool `down` (left,
    right: the feet to stand on the floor, as the caller decided; the physics stage stands a
    planted foot on it when its sole is within :data:`PLANT_REACH`), (N, 2) lowest sole height of a
    free foot (default 0; see :func:`swing_clearance`) and (N, 2) how far down a free foot is still
    pulled (default none) -> (N, 22, 3).

    A foot moves vertically only (its horizontal place is the feet stage's pin) and rigidly with
    its ankle; the knee is re-solved (:func:`~motion_env.generation.feet.two_bone_ik`). A foot
    its leg reaches only stretched beyond :data:`MAX_STRETCH` stays as low as that reaches.
    """
    out = np.array(joints, dtype=np.float64)
    sole = sole_heights(out, flat_ankle)  # (N, 2)
    low = np.zeros_like(sole) if clearance is None else np.asarray(clearance)
    # Each leg's frames that move, then one IK call for the two legs' (a leg's move reads and
    # writes only its own joints, and the IK is per frame).
    legs, frames, lifts = [], [], []
    for leg, (hip, knee, ankle, _) in enumerate(LEGS):
        on = down[:, leg]
        lift = np.where(on, -sole[:, leg], np.maximum(low[:, leg] - sole[:, leg], 0.0))
        if pull is not None:  # a foot just let go of the floor: down by what is left of its pull
            lift = np.where(
                on | (pull[:, leg] <= 0.0), lift, np.maximum(-pull[:, leg], low[:, leg] - sole[:, leg])
            )
        lift = np.maximum(lift, deepest_reach(out[:, hip], out[:, knee], out[:, ankle]))
        moved = np.nonzero(np.abs(lift) > 1e-6)[0]
        legs.append(np.full(len(moved), leg))
        frames.append(moved)
        lifts.append(lift[moved])
    frame, leg_of = np.concatenate(frames), np.concatenate(legs)
    if not len(frame):
        return out
    chain = np.asarray(LEGS)[leg_of]  # (M, 4) hip, knee, ankle, toe of each moved leg
    hip, knee, ankle, toe = (out[frame, chain[:, j]] for j in range(4))
    goal = ankle.copy()
    goal[:, 1] += np.concatenate(lifts)
    toes = toe - ankle
    toes[:, 1] = 0.0  # a straight knee bends the way the foot points
    new_knee, new_ankle = two_bone_ik(hip, knee, ankle, goal, toes, hint_length=TOE_HINT_LENGTH)
    out[frame, chain[:, 3]] = toe + (new_ankle - ankle)
    out[frame, chain[:, 1]], out[frame, chain[:, 2]] = new_knee, new_ankle
    return out


def deepest_reach(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray) -> np.ndarray:
    """(N,) the lowest vertical move of the ankle (<= 0, m) that stretches the leg (hip, knee,
    ankle: (N, 3)) no farther than MAX_STRETCH of its length, or than it already is."""
    leg = ankle - hip
    length = vector_norm(knee - hip) + vector_norm(ankle - knee)
    reach = np.maximum(MAX_STRETCH * length, vector_norm(leg))
    # |leg + lift * up| = reach, the root below the ankle.
    down = -leg[:, 1]
    return down - np.sqrt(np.maximum(leg[:, 1] ** 2 + reach**2 - (leg**2).sum(-1), 0.0))


def flight_frames(contacts: np.ndarray, soles: np.ndarray) -> np.ndarray:
    """Frames in the air: (..., 4) contact channels and (..., 2) sole heights
    (:func:`sole_heights`) -> (...) bool.

    A frame is in the air when no contact channel is on (> 0.5) and both soles are clear of the
    floor by :data:`FLIGHT_CLEARANCE`: a decoder that misses the contact of a foot standing on the
    floor does not make the body fall.
    """
    return ~(np.asarray(contacts) > 0.5).any(axis=-1) & (soles.min(axis=-1) > FLIGHT_CLEARANCE)


def support_gap(sole: np.ndarray, planted: np.ndarray) -> np.ndarray:
    """How far (m) the body floats above the floor it stands on, per frame: the lowest planted
    sole's height (negative: sunk); NaN where no foot is planted, or the only planted foot is
    farther than PLANT_REACH from the floor. sole, planted: (n, 2) -> (n,)."""
    lowest = np.where(planted, sole, np.inf).min(axis=1)
    trusted = planted.any(axis=1) & ((np.abs(lowest) <= PLANT_REACH) | planted.all(axis=1))
    return np.where(trusted, lowest, np.nan)


def place_body(
    joints: np.ndarray,
    heights: np.ndarray,
    down: np.ndarray,
    clearance: np.ndarray,
    flat_ankle: np.ndarray,
    pull: np.ndarray | None = None,
) -> np.ndarray:
    """The body (n, 22, 3) shifted vertically so that its centre of mass is at `heights` (n,), its
    feet grounded (:func:`ground_feet`; `down`, `clearance`, `pull`: (n, 2), `flat_ankle`: (n,)), no
    joint below the floor. Compiled (:mod:`motion_env.generation.ground_jit`) where numba runs."""
    if jit_enabled():
        from motion_env.generation.ground_jit import place_frames

        note_first_compile(place_frames, "the body's placement on the floor")
        n = len(joints)
        f64 = np.float64  # contiguous arrays of one layout: numba compiles one version
        return place_frames(
            np.ascontiguousarray(joints, dtype=f64),
            np.ascontiguousarray(heights, dtype=f64),
            np.ascontiguousarray(down, dtype=bool),
            np.ascontiguousarray(clearance, dtype=f64),
            np.ascontiguousarray(np.broadcast_to(np.asarray(flat_ankle, dtype=f64), (n,))),
            np.zeros((n, 2)) if pull is None else np.ascontiguousarray(pull, dtype=f64),
            pull is not None,
            COM_WEIGHTS,
            np.asarray(LEGS),
            _PASSES,
            _PLACE_TOLERANCE,
            np.array([HEEL_BACK, TOE_FRONT, SOLE_RADIUS]),
            MAX_STRETCH,
            HINT_WEIGHT,
            TOE_HINT_LENGTH,
        )
    shift = heights - centre_of_mass(joints)[:, 1]
    out = np.array(joints, dtype=np.float64)
    todo = np.arange(len(joints))  # frames not placed within _PLACE_TOLERANCE yet: each on its own
    for _ in range(_PASSES):
        moved = joints[todo].copy()
        moved[..., 1] += shift[todo, None]
        out[todo] = ground_feet(
            moved, down[todo], clearance[todo], flat_ankle[todo], None if pull is None else pull[todo]
        )
        error = heights[todo] - centre_of_mass(out[todo])[:, 1]
        off = np.abs(error) >= _PLACE_TOLERANCE
        shift[todo[off]] += error[off]
        todo = todo[off]
        if not len(todo):
            break
    sunk = np.minimum(out[..., 1].min(axis=1), 0.0)  # a knee or a hand through the floor
    out[..., 1] -= sunk[:, None]
    return out
