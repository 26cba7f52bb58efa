"""Physics cleanup: flight and contact made consistent, in closed form (no simulator in the loop).

The decoded body moves its centre of mass in ways no body can: it falls faster than gravity at
the top of a running stride, lands with spikes the legs cannot give, floats or sinks into the
floor. This stage, run on the feet stage's output, fixes the vertical motion of the whole body:

- **ground**: the body stands on its planted feet (a body that floats above or sinks below the
  lowest foot the decoder marks planted is lowered or raised to it, the estimate followed over
  about half a second, and raised where a foot would still be more than
  :data:`SINK_TOLERANCE` below the floor); a foot the
  decoder marks planted while the body drags it faster than its flags allow is a free foot
  (:data:`DRAG_STEP`); a planted foot's lowest sole point is on the floor (except on the last
  frame of its contact, where it lifts off: :func:`_lifting_off`), a free foot none below it and,
  while it moves, clear of it
  (:func:`~motion_env.generation.ground.ground_feet`; legs are re-solved with
  :func:`~motion_env.generation.feet.two_bone_ik`, so bones keep their lengths and feet the
  horizontal place the feet stage pinned);
- **flight**: while no foot touches the floor (no contact flag and both soles clear of it; or,
  flagged or not, no foot the grounding would stand on: out of a stretched leg's reach, or more
  than ``ground.PLANT_REACH`` above the floor, for :data:`MAX_HOP_FRAMES` at most: longer, the
  body is stood on its lowest flagged foot), the centre of mass falls freely: a parabola of
  gravity :data:`GRAVITY` through the take-off and landing heights (:func:`plan_heights`);
- **contact**: with a foot on the floor the vertical acceleration of the centre of mass stays
  within what floor and legs can give (:data:`STANCE_ACCELERATION`), so take-offs and landings
  have no spikes.

Only vertical positions change, by a shift of the whole body plus the legs' re-solve: the pelvis
keeps its horizontal path, so timed waypoints are met as before. :class:`PhysicsFilter` is the
causal version for the stream (past frames and the current token's frames only; it delays
nothing and never changes a frame it has put out); :func:`apply_physics`, for whole clips, is the
same filter given the whole clip at once.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from motion_env.generation.ground import (
    FLAT_ANKLE_HEIGHT,
    FLAT_ANKLE_RANGE,
    FLIGHT_CLEARANCE,
    HEEL_BACK,
    MAX_STRETCH,
    PLANT_REACH,
    SOLE_RADIUS,
    SWING_CLEARANCE,
    SWING_LANDING,
    SWING_RISE,
    SWING_SPEEDS,
    SWING_STRAIGHT,
    TOE_FRONT,
    deepest_reach,
    flight_frames,
    place_body,
    sole_heights,
    support_gap,
    swing_clearance,
)
from motion_env.generation.height_plan import GRAVITY, STANCE_ACCELERATION, plan_heights
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.mass import COM_WEIGHTS, centre_of_mass
from motion_env.motion.rotations import vector_norm
from motion_env.motion.skeleton import FOOT_JOINTS, FPS, LEGS, NUM_JOINTS

__all__ = [
    "GRAVITY",
    "STANCE_ACCELERATION",
    "PhysicsFilter",
    "apply_physics",
    "plan_heights",
]

# How fast the estimate of how far the body floats above its planted feet follows each frame's
# (a share per frame: about half a second).
FLOAT_RATE = 0.1
# A foot the plan leaves this far (m) above the floor, its leg stretched (ground.MAX_STRETCH),
# does not reach it: with no foot that does, the body is in the air (the stream's plan carries a
# take-off's speed on before it sees the landing).
UNREACHABLE = 0.04
# The longest flight (frames); a longer stretch without contacts is no jump (a decoder that marks
# no contacts at all), and the body is not made to fall.
MAX_FLIGHT_FRAMES = 16
# The longest stretch (frames) in the air that the plan finds where the flags say a foot is
# planted (a hop whose slow feet keep their flags: the CMU hops' feet are 6-12 cm up for 5
# frames); longer, the body is stood on its feet instead.
MAX_HOP_FRAMES = 8
# A flagged foot the floor lets go of (its sole rises past ground.PLANT_REACH) keeps this share of
# the pull down it had, each frame, instead of rising by it at once (chosen on val: climbs' pops 56
# -> 31 %, walks unchanged; 0.9 leaves a lifted foot 1-2 cm low for a second).
RELEASE_FADE = 0.7
# A contact that ends with its foot pulled down by no more than this (m) lets it go at once: a
# toe-off's foot is nearly on the floor. Fading every toe-off's pull kept walks' swing feet low
# (test, seeds 0-3: skating 0.87 -> 0.89x real, a sidestep more with a pop); a foot held down
# farther (the body raised above a foot that hovered while flagged) fades, as one still flagged does.
RELEASE_AT_ONCE = 0.02
# Frames of the usual flat-foot ankle height (ground.FLAT_ANKLE_HEIGHT) the learnt one starts from
# (PhysicsFilter._flat_ankle): learnt from a stream's first token alone (a greeting's, both feet
# flat in its 4 frames: 5.1 cm against 9.7 later), the soles were put 4-6 cm too high and the
# feet sank that far into the floor (the replay's penetration).
FLAT_ANKLE_PRIOR = 16
# A foot flagged in contact whose ankle and toe both move farther than this (m) a frame, two
# frames running, is dragged, not planted (PhysicsFilter._planted): HumanML3D's contact flags
# mark feet slower than about 4.5 cm a frame (motion.features.FOOT_CONTACT_THRESHOLD).
DRAG_STEP = 0.045
# How far (m) a sole may dip below the floor before the body is raised for it. The grounding
# re-solves the legs anyway and its knees take up a shallow dip; raising the body at once for
# each one made a standing body bob with its decoded legs' jitter (raised by up to 0.8 cm on a
# third of a calm clip's frames: 1.1-1.6 m/s^2 of vertical acceleration, a real one 0.4).
SINK_TOLERANCE = 0.02
# Height plans per call at most: each finds landings and take-offs the flags missed.
_REPLANS = 4


# measure_frames' numbers (physics_jit), in its order.
_MEASURE_CONSTANTS = (
    FLAT_ANKLE_PRIOR * FLAT_ANKLE_HEIGHT,
    float(FLAT_ANKLE_PRIOR),
    *FLAT_ANKLE_RANGE,
    HEEL_BACK,
    TOE_FRONT,
    SOLE_RADIUS,
    DRAG_STEP,
    MAX_STRETCH,
    FLIGHT_CLEARANCE,
    SWING_STRAIGHT,
    SWING_SPEEDS[0],
    SWING_SPEEDS[1] - SWING_SPEEDS[0],
    SWING_CLEARANCE,
    SWING_RISE,
    SWING_LANDING,
    float(FPS),
    PLANT_REACH,
    FLOAT_RATE,
    SINK_TOLERANCE,
    float(MAX_FLIGHT_FRAMES),
)
_LEGS = np.asarray(LEGS, np.int64)
_FOOT_JOINTS = np.asarray(FOOT_JOINTS, np.int64)


class _Measured(NamedTuple):
    """What :meth:`PhysicsFilter._measure` reads from the new frames of R characters (n each)."""

    flat_ankle: np.ndarray  # (R,) a flat foot's ankle height above its sole
    soles: np.ndarray  # (R, n, 2) sole heights, left and right
    com: np.ndarray  # (R, n) decoded heights of the centre of mass
    lowest: np.ndarray  # (R, n, 2) sole heights with the legs stretched
    still: np.ndarray  # (R, n, 2) flagged feet not dragged
    planted: np.ndarray  # (R, n, 2) feet stood on the floor (let down, lifting off excepted)
    clearance: np.ndarray  # (R, n, 2) lowest sole height of the free feet
    flights: np.ndarray  # (R, n) in the air, flights no longer than MAX_FLIGHT_FRAMES
    raw: np.ndarray  # (R, n) wanted heights of the centre of mass
    support: np.ndarray  # (R, n, 2) feet the body may stand on


def _cap_flights(flight: np.ndarray, airborne: np.ndarray, longest: int = MAX_FLIGHT_FRAMES) -> np.ndarray:
    """Flight flags (R, n) of R characters without stretches longer than `longest` frames, as far
    as they are seen (`airborne` (R,): frames in the air just before these, which the first
    stretch continues)."""
    n = flight.shape[1]
    t = np.arange(n)
    # The frames each stretch lies between: the last frame on the ground before it (-1: none
    # seen) and the first after it (n: none seen).
    before = np.maximum.accumulate(np.where(flight, -1, t), axis=1)
    after = np.minimum.accumulate(np.where(flight, n, t)[:, ::-1], axis=1)[:, ::-1]
    length = after - before - 1 + np.where(before < 0, np.asarray(airborne)[:, None], 0)
    return flight & (length <= longest)


class PhysicsFilter:
    """Causal physics cleanup for B characters (the module's stage, one token at a time).

    Each call plans the new frames' heights (:func:`plan_heights`) on from the last three frames
    it put out, which stay as they were: it needs no future frames and never changes a frame it
    has returned. Given a whole clip in one call it is :func:`apply_physics`. The height of a
    flat foot's ankle is learnt from the frames seen so far (both contacts of a foot on).

    Args:
        batch: B characters; the state of each carries over from one call to the next.
    """

    HISTORY = 3  # frames of the past the plan continues (position, velocity, acceleration)

    def __init__(self, batch: int) -> None:
        self.past = np.zeros((batch, self.HISTORY))  # heights of the centre of mass put out
        self.past_raw = np.zeros((batch, self.HISTORY))  # and as they were wanted
        self.past_flight = np.zeros((batch, self.HISTORY), dtype=bool)
        self.seen = np.zeros(batch, dtype=np.int64)  # frames put out, up to HISTORY
        self.airborne = np.zeros(batch, dtype=np.int64)  # frames in the air just before
        self.feet = np.zeros((batch, len(FOOT_JOINTS), 2))  # foot joints' x, z in the last frame
        self.soles = np.zeros((batch, 2))  # and the soles' heights (as decoded)
        self.flat = np.zeros((batch, 2))  # sum and count of flat feet's ankle heights
        self.free = np.zeros((batch, 2))  # frames each foot has been free, up to the last frame
        self.floating = np.full(batch, np.nan)  # how far the body floats (m), NaN: not known yet
        self.moving = np.zeros((batch, 2), dtype=bool)  # feet flagged yet moving in the last frame
        self.lift = np.zeros((batch, 2))  # clearance a dragged foot had in the last frame (m)
        self.pull = np.zeros((batch, 2))  # how far each foot was pulled down in the last frame (m)

    def reset(self, i: int) -> None:
        """Forget character i's past (a new episode)."""
        self.past[i] = self.past_raw[i] = self.feet[i] = self.soles[i] = 0.0
        self.flat[i] = self.free[i] = 0.0
        self.past_flight[i] = False
        self.moving[i] = False
        self.lift[i] = self.pull[i] = 0.0
        self.seen[i] = self.airborne[i] = 0
        self.floating[i] = np.nan

    def apply(self, i: int, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """Character i's next frames: (n, 22, 3) joints and (n, 4) contact channels -> (n, 22, 3)."""
        return self.apply_rows(np.array([i]), np.asarray(joints)[None], np.asarray(contacts)[None])[0]

    def apply_rows(self, rows: np.ndarray, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """The next frames of characters `rows`: (R, n, 22, 3) joints and (R, n, 4) contact channels
        (left ankle, left toe, right ankle, right toe; > 0.5 = in contact) -> (R, n, 22, 3) float32;
        the same as :meth:`apply` row by row."""
        joints = np.asarray(joints, dtype=np.float64)
        flags = np.asarray(contacts) > 0.5
        rows = np.asarray(rows, dtype=np.int64)
        n, frames = joints.shape[1], joints.reshape(-1, NUM_JOINTS, 3)
        if not n:
            return joints.astype(np.float32)
        if jit_enabled():
            measured = self._measure_compiled(rows, joints, flags)
        else:
            measured = self._measure(rows, joints, flags)
        flat_ankle, soles, com, lowest, still, planted, clearance, flights, raw, support = measured
        heights = self._plan_rows(rows, soles, com, lowest, still, flights, raw, support)
        down, pull = self._release(rows, soles + (heights - com)[..., None], planted)
        # The legs' re-solve is the costly part: every row's frames at once.
        out = place_body(
            frames,
            heights.ravel(),
            down.reshape(-1, 2),
            clearance.reshape(-1, 2),
            np.repeat(flat_ankle, n),
            pull.reshape(-1, 2),
        ).reshape(joints.shape)
        last = min(n, self.HISTORY)  # the next plan continues what was put out
        self.past[rows, -last:] = centre_of_mass(out[:, -last:])[..., 1]
        return out.astype(np.float32)

    def _measure(self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray) -> _Measured:
        """What the new frames of characters `rows` ((R, n, 22, 3) float64 `joints`, (R, n, 4) bool
        contact `flags`) show before their heights are planned, for every row at once; updates
        their state. Compiled twin: :func:`motion_env.generation.physics_jit.measure_frames`."""
        r, n = joints.shape[:2]
        frames = joints.reshape(-1, NUM_JOINTS, 3)
        flat_ankle = self._flat_ankle(rows, joints, flags)  # (R,)
        soles = sole_heights(joints, flat_ankle[:, None])  # (R, n, 2)
        steps, descent = self._steps(rows, joints, soles)
        flagged = flags.reshape(r, n, 2, 2).any(axis=-1)  # (R, n, 2) left, right
        still = self._planted(rows, flagged, steps)  # flagged and not dragged
        reach = [
            -deepest_reach(frames[:, hip], frames[:, knee], frames[:, ankle]) for hip, knee, ankle, _ in LEGS
        ]
        lowest = soles - np.stack(reach, axis=-1).reshape(r, n, 2)  # soles with the legs stretched
        com = centre_of_mass(joints)[..., 1]
        flight = flight_frames(flags, soles)
        clearance = self._clearance(rows, joints, still, steps, descent)
        planted, clearance = self._settle(rows, flagged, still, clearance)
        planted = _lifting_off(planted)
        raw, flights, support = self._wanted(rows, soles, com, flagged, flight)
        return _Measured(flat_ankle, soles, com, lowest, still, planted, clearance, flights, raw, support)

    def _measure_compiled(self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray) -> _Measured:
        """:meth:`_measure` as one compiled pass (:mod:`~motion_env.generation.physics_jit`)."""
        return _Measured(
            *_loops().measure_frames(
                rows, np.ascontiguousarray(joints), np.ascontiguousarray(flags), self.flat, self.feet,
                self.soles, self.seen, self.moving, self.free, self.lift, self.floating, self.airborne,
                _LEGS, _FOOT_JOINTS, COM_WEIGHTS, _MEASURE_CONSTANTS,
            )
        )  # fmt: skip

    def _release(
        self, rows: np.ndarray, soles: np.ndarray, planted: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Which feet of characters `rows` stand on the floor in new frames, and how far down the
        others are still pulled: (R, n, 2) bool and (R, n, 2) m. A planted foot stands on the floor
        when its sole, with the planned heights (`soles`: the decoded soles moved by the plan's
        shift, an estimate of the placed body's), is under PLANT_REACH. The grounding takes this
        decision as it is (deciding again on the placed body, whose sole can be a few millimetres
        higher than the estimate, it left a foot flagged throughout 5 cm up for such a frame: a
        jump's knee at 64-71 m/s^2, half of the test jumps' pops). A foot the floor lets go of
        (one still flagged that rises past PLANT_REACH, or a contact that ends while the foot was
        pulled down by more than RELEASE_AT_ONCE) would jump up by the whole pull at once (a hop on
        flagged feet: a streamed jump's knee at 72 m/s^2): the pull fades by RELEASE_FADE a frame
        instead. A toe-off whose foot was nearly on the floor lets it go at once."""
        down = planted & (soles < PLANT_REACH)
        last = self.pull[rows]
        if jit_enabled():
            out = _loops().release_frames(down, planted, soles, last, RELEASE_FADE, RELEASE_AT_ONCE)
        else:
            out = np.zeros(soles.shape)
            for t in range(soles.shape[1]):
                fade = np.where(planted[:, t] | (last > RELEASE_AT_ONCE), RELEASE_FADE * last, 0.0)
                out[:, t] = last = np.where(down[:, t], np.maximum(soles[:, t], 0.0), fade)
        self.pull[rows] = last
        return down, np.where(down, 0.0, out)

    def _flat_ankle(self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray) -> np.ndarray:
        """(R,) flat-foot ankle height of characters `rows`, learnt from their frames so far and
        `joints` (R, n, 22, 3), `flags` (R, n, 4): frames with both contacts of a foot on, after
        FLAT_ANKLE_PRIOR frames of the usual height."""
        for leg, (_, _, ankle, toe) in enumerate(LEGS):
            flat = flags[..., 2 * leg] & flags[..., 2 * leg + 1]
            self.flat[rows, 0] += np.where(flat, joints[..., ankle, 1] - joints[..., toe, 1], 0.0).sum(axis=1)
            self.flat[rows, 1] += flat.sum(axis=1)
        # The mean of the flat frames seen, drawn towards the usual height by FLAT_ANKLE_PRIOR frames
        # of it: a stream's first token, alone, can be far off.
        total = self.flat[rows, 0] + FLAT_ANKLE_PRIOR * FLAT_ANKLE_HEIGHT
        mean = total / (self.flat[rows, 1] + FLAT_ANKLE_PRIOR)
        return np.clip(mean, *FLAT_ANKLE_RANGE)

    def _wanted(
        self, rows: np.ndarray, soles: np.ndarray, com: np.ndarray, flagged: np.ndarray, flight: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the plan of characters `rows` starts from, given (R, n, 2) sole heights, (R, n)
        decoded heights of the centre of mass, (R, n, 2) flagged feet and (R, n) frames in the air
        by the flags: (R, n) wanted heights, (R, n) flights no longer than MAX_FLIGHT_FRAMES and
        (R, n, 2) the feet the body may stand on (the flagged ones; with none, both); updates
        the floating estimate."""
        r, n = com.shape
        floating = self._float(rows, support_gap(soles.reshape(-1, 2), flagged.reshape(-1, 2)).reshape(r, n))
        # The body is wanted standing on its planted feet, and raised where a foot would still be
        # more than SINK_TOLERANCE below the floor (a landing the flags have not seen: a straight
        # leg cannot shorten).
        raw = com - floating + np.maximum(floating - soles.min(axis=2) - SINK_TOLERANCE, 0.0)
        flights = _cap_flights(flight, self.airborne[rows])
        support = np.where(flagged.any(axis=2, keepdims=True), flagged, True)
        return raw, flights, support

    def _plan_rows(  # noqa: PLR0913 (the measured arrays the plan reads)
        self,
        rows: np.ndarray,
        soles: np.ndarray,
        com: np.ndarray,
        lowest: np.ndarray,
        still: np.ndarray,
        flights: np.ndarray,
        raw: np.ndarray,
        support: np.ndarray,
    ) -> np.ndarray:
        """The new frames of characters `rows`: (R, n) heights of the centre of mass, from
        (R, n, 2) sole heights, (R, n) decoded heights of the centre of mass, (R, n, 2) sole
        heights with the legs stretched, (R, n, 2) the flagged feet that are not dragged and
        :meth:`_wanted`'s three arrays; updates their state. The plans of rows with the same
        history length are one batched solve (:func:`plan_heights` of the rows), replanned
        together while some row finds a landing or a take-off; each row keeps its own state
        (flight caps, history)."""
        r, n = com.shape
        settled = np.zeros((r, n), dtype=bool)  # frames found on the floor: they stay there
        planned, todo, seen = np.empty((r, n)), np.ones(r, dtype=bool), self.seen[rows]
        for _ in range(_REPLANS):
            for h in np.unique(seen[todo]):
                sel = np.nonzero(todo & (seen == h))[0]
                at, keep = rows[sel], slice(self.HISTORY - int(h), self.HISTORY)
                planned[sel] = plan_heights(
                    raw[sel],
                    np.concatenate([self.past_flight[at, keep], flights[sel]], axis=1),
                    self.past[at, keep],
                    self.past_raw[at, keep],
                )
            todo = self._replan(
                rows, planned, com, soles, lowest, still, support, todo, flights, settled, raw
            )
            if not todo.any():
                break
        self._remember(rows, planned, raw, flights)
        return planned

    def _replan(  # noqa: PLR0913 (the plan's arrays)
        self,
        rows: np.ndarray,
        planned: np.ndarray,
        com: np.ndarray,
        soles: np.ndarray,
        lowest: np.ndarray,
        still: np.ndarray,
        support: np.ndarray,
        todo: np.ndarray,
        flights: np.ndarray,
        settled: np.ndarray,
        raw: np.ndarray,
    ) -> np.ndarray:
        """What the plans (R, n) of the rows still to plan (`todo` (R,)) show: landings the flags
        missed, take-offs, feet held up longer than a hop; `flights`, `settled` and `raw` updated
        in place for the next plan; returns (R,) the rows to plan again. Compiled twin:
        :func:`motion_env.generation.physics_jit.replan_frames`."""
        if jit_enabled():
            return _loops().replan_frames(
                planned, com, soles, lowest, still, support, self.airborne[rows], todo, flights, settled,
                raw, UNREACHABLE, PLANT_REACH, MAX_HOP_FRAMES,
            )  # fmt: skip
        shift = (planned - com)[:, :, None]
        # A fall that brings a foot to the floor is a landing, whatever the flags say; a body
        # whose feet cannot reach the floor is in the air, and so is one whose feet the
        # grounding leaves alone (ground.PLANT_REACH above the floor: a small hop whose slow
        # feet keep their contact flags; in the air for the replay, it must fall freely).
        landed = flights & ((soles + shift).min(axis=2) < 0.0) & todo[:, None]
        away = (lowest + shift > UNREACHABLE) | (soles + shift >= PLANT_REACH)
        aloft = ~flights & ~settled & np.where(support, away, True).all(axis=2) & todo[:, None]
        # Feet flagged planted, not dragged, yet off the floor for longer than a hop are no
        # flight: the body is stood on the lowest of them there instead (a decoded crouch
        # that lifts its feet for 0.7 s, planned as a flight, was launched 40 cm up and
        # landed with a knee folded through the body). Dragged feet (a run's) stay as they were.
        long = aloft & ~_cap_flights(flights | aloft, self.airborne[rows], MAX_HOP_FRAMES)
        stand = long & still.any(axis=2)
        aloft &= ~stand
        raw[...] = np.where(stand, com - np.where(still, soles, np.inf).min(axis=2), raw)
        settled |= stand
        for k in np.nonzero(landed.any(axis=1))[0]:  # the flight a landing ends is on the floor
            first = int(np.argmax(landed[k]))
            end = first + _run_length(flights[k, first:])
            flights[k, first:end], settled[k, first:end] = False, True
        flights |= aloft
        return landed.any(axis=1) | aloft.any(axis=1) | stand.any(axis=1)

    def _float(self, rows: np.ndarray, gap: np.ndarray) -> np.ndarray:
        """(R, n) how far the bodies of characters `rows` float above the floor in new frames: the
        support gap (R, n) (NaN: unknown) followed slowly from its first value, so a body that
        floats or sinks throughout is moved, while a foot that lifts early or lands late (whose
        gap is noise between frames) moves no more than itself."""
        last = self.floating[rows]
        out = np.zeros(gap.shape)
        for t in range(gap.shape[1]):
            g = gap[:, t]
            followed = np.where(np.isnan(last), g, last + FLOAT_RATE * (g - last))
            last = out[:, t] = np.where(np.isnan(g), last, followed)
        self.floating[rows] = last
        return np.where(np.isnan(out), 0.0, out)

    def _steps(
        self, rows: np.ndarray, joints: np.ndarray, soles: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(R, n, 4) horizontal steps (m) of the foot joints of characters `rows` into each new
        frame (R, n, 22, 3) and (R, n, 2) how far each sole (`soles`) went down; updates the feet's
        state."""
        feet = joints[:, :, list(FOOT_JOINTS)][..., [0, 2]]  # (R, n, 4, 2)
        steps = np.linalg.norm(
            np.diff(np.concatenate([self.feet[rows][:, None], feet], axis=1), axis=1), axis=-1
        )
        descent = -np.diff(np.concatenate([self.soles[rows][:, None], soles], axis=1), axis=1)
        steps[self.seen[rows] == 0, 0] = descent[self.seen[rows] == 0, 0] = 0.0  # nothing before
        self.feet[rows], self.soles[rows] = feet[:, -1], soles[:, -1]
        return steps, descent

    def _planted(self, rows: np.ndarray, flagged: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """(R, n, 2) feet of characters `rows` standing on the floor in new frames: flagged
        (`flagged` (R, n, 2): a contact channel on), but not dragged: flagged with both its joints
        moving farther than DRAG_STEP a frame (`steps` (R, n, 4)) in this frame and the one before.

        The feet stage holds a planted foot still, up to FOOT_MAX_OFFSET from where the body puts
        it; a foot the body drags farther (a decoder that flags a foot moving at 2 m/s for a
        second) slides along, and on the floor it skated (the replay's foot-skating check). A foot
        that lands fast moves so for its landing frame only: it stays planted."""
        moving = flagged & (steps.reshape(steps.shape[:2] + (2, 2)).min(axis=-1) > DRAG_STEP)
        dragged = moving & np.concatenate([self.moving[rows][:, None], moving[:, :-1]], axis=1)
        self.moving[rows] = moving[:, -1]
        return flagged & ~dragged

    def _clearance(
        self,
        rows: np.ndarray,
        joints: np.ndarray,
        planted: np.ndarray,
        steps: np.ndarray,
        descent: np.ndarray,
    ) -> np.ndarray:
        """(R, n, 2) lowest sole height of the free feet of characters `rows` in new frames (R, n,
        22, 3), given `planted` (R, n, 2), the foot joints' `steps` (R, n, 4) and the soles'
        `descent` (R, n, 2) (:meth:`_steps`; :func:`swing_clearance`)."""
        legs = [(joints[..., h, :], joints[..., k, :], joints[..., a, :]) for h, k, a, _ in LEGS]
        stretch = np.stack(
            [vector_norm(a - h) / (vector_norm(k - h) + vector_norm(a - k)) for h, k, a in legs], axis=-1
        )
        descent = np.where(stretch > SWING_STRAIGHT, np.inf, descent)
        speed = steps.reshape(steps.shape[:2] + (2, 2)).max(axis=-1) * FPS  # (R, n, 2): ankle or toe
        last = self.free[rows]
        free = np.zeros_like(speed)
        for t in range(joints.shape[1]):
            last = free[:, t] = np.where(planted[:, t], 0.0, np.minimum(last + 1, 100))
        self.free[rows] = last
        return swing_clearance(speed, free, descent)

    def _settle(
        self, rows: np.ndarray, flagged: np.ndarray, planted: np.ndarray, clearance: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """`planted` and `clearance` (R, n, 2) of characters `rows` with each dragged foot that
        stops being dragged while still flagged (`flagged`) let down as it was lifted, by SWING_RISE
        a frame, before it is stood on: put down at once, its knee jolted (backward walks, whose
        flagged feet are dragged for a few frames every step: their jerk 1.18 -> 1.55x)."""
        planted, clearance = planted.copy(), clearance.copy()
        if not self.lift[rows].any() and not (flagged & ~planted).any():
            return planted, clearance  # nothing dragged: nothing to let down
        lift = self.lift[rows]
        for t in range(planted.shape[1]):
            dragged = flagged[:, t] & ~planted[:, t]
            settling = planted[:, t] & (lift > 0.0)
            clearance[:, t] = np.where(settling, np.maximum(lift - SWING_RISE, 0.0), clearance[:, t])
            planted[:, t] &= ~(settling & (clearance[:, t] > 0.0))
            lift = np.where(dragged | settling, clearance[:, t], 0.0)
        self.lift[rows] = lift
        return planted, clearance

    def _remember(self, rows: np.ndarray, heights: np.ndarray, raw: np.ndarray, flight: np.ndarray) -> None:
        """Keep the last frames of characters `rows`: the planned heights (R, n) (:meth:`apply_rows`
        puts in the placed ones), the wanted heights and flight. Compiled twin:
        :func:`motion_env.generation.physics_jit.remember_frames`."""
        if jit_enabled():
            state = (self.seen, self.past, self.past_raw, self.past_flight, self.airborne)
            _loops().remember_frames(rows, heights, raw, flight, *state)
            return
        m = heights.shape[1]
        seen = self.seen[rows]
        for h in np.unique(seen):  # rows with as many frames in the history go together
            sel = seen == h
            at, n = rows[sel], min(int(h) + m, self.HISTORY)
            keep = slice(self.HISTORY - int(h), self.HISTORY)
            self.past[at, -n:] = np.concatenate([self.past[at, keep], heights[sel]], axis=1)[:, -n:]
            self.past_raw[at, -n:] = np.concatenate([self.past_raw[at, keep], raw[sel]], axis=1)[:, -n:]
            self.past_flight[at, -n:] = np.concatenate([self.past_flight[at, keep], flight[sel]], axis=1)[
                :, -n:
            ]
            self.seen[at] = n
        # Frames in the air at the end: a stretch that fills the new frames continues the past's.
        trailing = np.where(flight.all(axis=1), m, np.argmin(flight[:, ::-1], axis=1))
        self.airborne[rows] = np.where(trailing == m, self.airborne[rows] + trailing, trailing)


def _loops() -> Any:
    """:mod:`motion_env.generation.physics_jit`, imported on first use (numba compiles it once per
    machine, and says so)."""
    from motion_env.generation import physics_jit as module

    note_first_compile(module.release_frames, "the physics stage's frame loops")
    return module


def _lifting_off(planted: np.ndarray) -> np.ndarray:
    """`planted` (R, n, 2) without the last frame of each contact, where these frames show the next
    one free: the foot is not stood on the floor there. At toe-off the decoded foot is already
    rising on the contact's last flagged frame; pushed down to the floor there and let go the next
    frame, its knee jolted (session 13: of the val walks' knee frames over 25 m/s² after this stage,
    83 more on a contact's last frame). The stream sees a token's frames only, so a contact that
    ends on a token's last frame is still stood on there."""
    out = planted.copy()
    out[:, :-1] &= planted[:, 1:]
    return out


def _run_length(flags: np.ndarray) -> int:
    """How many of `flags` (n,) are true before the first false one."""
    return int(np.argmin(flags)) if not flags.all() else len(flags)


def apply_physics(joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
    """A whole clip made physically consistent (see the module): (T, 22, 3) joints after the feet
    stage and (T, 4) decoded contact channels (left ankle, left toe, right ankle, right toe; > 0.5
    = in contact) -> (T, 22, 3) float32 joints. Only vertical positions change."""
    return PhysicsFilter(1).apply(0, joints, contacts)
