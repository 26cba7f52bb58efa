"""Foot cleanup: feet the decoder says are planted stay planted (whole clips and the stream alike).

:class:`FootPinner` is causal (frame by frame, no future frames), so the stream and whole clips
share it; :func:`two_bone_ik` re-solves a leg for a moved ankle.
"""

from __future__ import annotations

import numpy as np

from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.rotations import qbetween, qrot, vector_norm
from motion_env.motion.skeleton import LEGS

__all__ = [
    "ANKLE_BISECTIONS",
    "ANKLE_MIN_ANGLE",
    "ANKLE_TOLERANCE",
    "FOOT_BLEND",
    "FOOT_CREEP",
    "FOOT_CREEP_RATE",
    "FOOT_GLIDE",
    "FOOT_GLIDE_STEP",
    "FOOT_MAX_OFFSET",
    "FOOT_SOFTNESS",
    "FOOT_STRETCH",
    "HINT_WEIGHT",
    "TOE_HINT_LENGTH",
    "FootPinner",
    "ankle_room",
    "release_fade",
    "soft_limit",
    "soft_reach",
    "two_bone_ik",
]

# Frames over which a released foot's correction fades out (:func:`release_fade`).
FOOT_BLEND = 6
# The largest correction (m) a pinned foot gets; a foot the body drags farther (its stride does
# not match the path's speed) slides along with it, so the leg never snaps back from afar. (0.25
# until the leg's reach was made soft: decoded sidesteps and backward walks drag their planted
# feet farther, and held 35 cm they slide less, with no more pops.)
FOOT_MAX_OFFSET = 0.35
# A held pin creeps towards where the decoder shows its foot: by FOOT_CREEP_RATE of the gap a
# frame, at most FOOT_CREEP metres. The decoded foot wobbles by centimetres about where it stands,
# so a pin fixed on the contact's first frame froze that frame's error for the whole contact (a
# standing foot held 4-5 cm off the decoded stance for seconds), which doubled the error of the
# legs' classifier features against the real takes: the Fréchet distance of VQ-VAE clips on val
# rose 175 -> 220 in the feet stage. Real planted feet slide as much as FOOT_CREEP (the val takes'
# flagged feet: 90th percentile 0.42 cm a frame; the skating criterion is 2.5 cm); the share makes
# the creep slow down smoothly as it arrives (at a constant speed, it followed the decoded foot's
# wobble back and forth: standing clips' jerk p99 1.26 -> 1.46x the real takes').
FOOT_CREEP, FOOT_CREEP_RATE = 0.004, 0.3
# A new pin glides on with the foot's last step before the contact: FOOT_GLIDE of it on the
# contact's second frame, FOOT_GLIDE squared on the third, and so on, and at most FOOT_GLIDE_STEP
# (m) on the first of them. Held at once, a landing foot's speed fell to the creep's in one frame:
# most of the walks' ankle and knee accelerations over the real takes' 99th percentile were
# there (walk-left's 8 -> 30 frames at a contact's onset after the feet stage). The cap keeps the
# glide under the skating criterion's 2.5 cm a frame (uncapped, a run's landing foot, 6-10 cm a
# frame, slid: runs' skating 1.14 -> 1.77x).
FOOT_GLIDE = 0.5
FOOT_GLIDE_STEP = 0.012
# A pinned leg straightens no farther than this share of its length (or than the decoded leg
# already is), approached softly over the last FOOT_SOFTNESS of it (:func:`soft_reach`): a pin the
# body has left behind used to pull the leg straight, and where the contact ended the knee snapped
# back to its bend in one frame (the knees' pops of generated walks, up to 100 m/s^2).
FOOT_STRETCH = 0.99
FOOT_SOFTNESS = 0.02
# Metres of horizontal ankle-to-toe length (a flat foot's is about 14 cm) from which the toes
# bend a re-solved knee with their whole weight (two_bone_ik's hint_length).
TOE_HINT_LENGTH = 0.1
# Metres of bias a bend hint gives a re-solved knee (two_bone_ik's hint_weight).
HINT_WEIGHT = 0.05
# The narrowest shin-foot angle (degrees) a pinned leg is re-solved to, unless the decoded pose is
# narrower (ankle_room); real takes' angles: 1st percentile 58, 5th 78, median 114 (the naturalness
# takes). 70 also passed the train split's jumps but failed a val climb; 60 neither.
ANKLE_MIN_ANGLE = 60.0
# Halvings of the share of a pin's correction that a leg bent too far takes (ankle_room), and
# the angle (degrees) by which a re-solved leg may miss ANKLE_MIN_ANGLE before the pins of its
# clip (or token) are checked frame by frame.
ANKLE_BISECTIONS, ANKLE_TOLERANCE = 6, 0.5
_ANKLE_PASSES = 4  # passes of the pins over a leg's frames at most (FootPinner.apply_rows)
_LEGS = np.asarray(LEGS, np.int64)  # (legs, 4) hip, knee, ankle, toe, for the compiled passes


def release_fade(since: np.ndarray) -> np.ndarray:
    """Share of a released foot's correction kept `since` frames after its contact ended (1 on
    the first free frame): a smoothstep from 1 down to 0 over FOOT_BLEND frames, so the foot
    changes its speed gradually where the correction starts and stops fading (a linear fade
    changed it at once by the whole correction / FOOT_BLEND per frame)."""
    s = np.clip(np.asarray(since, dtype=np.float64) / (FOOT_BLEND + 1), 0.0, 1.0)
    return 1.0 - s * s * (3.0 - 2.0 * s)


def soft_limit(d: np.ndarray, start: np.ndarray | float, room: np.ndarray | float) -> np.ndarray:
    """Distances `d` beyond `start` eased towards ``start + room`` on an exponential that meets it
    only at infinity ("soft IK": a chain reaching for them never locks straight); those within stay."""
    excess = np.clip((d - start) / np.maximum(room, 1e-9), 0.0, 50.0)
    return np.where(d > start, start + room * (1.0 - np.exp(-excess)), d)


def soft_reach(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Ankle goals brought within the soft reach of their legs: (N, 3) hip, knee, ankle (the
    decoded leg) and goal -> (N, 3) goal.

    A leg reaches FOOT_STRETCH of its length, or FOOT_SOFTNESS of it farther than the decoded
    ankle is, at most its whole length. A goal farther than that less FOOT_SOFTNESS is pulled
    towards the hip on an exponential that meets the reach only at infinity ("soft IK"): the knee
    never locks straight, so it bends again smoothly where the goal comes back within reach. A
    goal within reach, and the decoded ankle itself, stay where they are.
    """
    length = vector_norm(knee - hip) + vector_norm(ankle - knee)
    band = FOOT_SOFTNESS * length
    reach = np.minimum(np.maximum(FOOT_STRETCH * length, vector_norm(ankle - hip) + band), length)
    start = reach - band
    v = goal - hip
    d = vector_norm(v)
    return hip + v * (soft_limit(d, start, band) / np.maximum(d, 1e-9))[:, None]


def _shin_foot_angle(knee: np.ndarray, ankle: np.ndarray, toe: np.ndarray) -> np.ndarray:
    """Angle (degrees) between shin and foot at the ankle: (N, 3) each -> (N,); it narrows as the
    ankle flexes toes-up (dorsiflexion)."""
    u, v = knee - ankle, toe - ankle
    cos = (u * v).sum(-1) / np.maximum(vector_norm(u) * vector_norm(v), 1e-12)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def ankle_room(joints: np.ndarray, leg: int, offset: np.ndarray) -> np.ndarray:
    """(N,) share (0 to 1) of a pinned foot's horizontal correction `offset` (N, 2) its leg takes:
    the largest (to 1/2**ANKLE_BISECTIONS) that keeps the shin-foot angle of the re-solved leg at
    least ANKLE_MIN_ANGLE, or as wide as in the decoded pose `joints` (N, 22, 3) where that is
    narrower.

    A pin held behind a body that moves on (a decoded jump's crouch and landing drift forwards)
    pulled the ankle back under a knee that stays ahead: the shin leant over a flat foot 40-50
    degrees further than in the decoded pose and the real takes (the MuJoCo replay: ankles flexed
    toes-up 27-31 degrees beyond a human range, in every generated jump that failed its ankles)."""
    hip, knee, ankle, toe = (joints[:, j] for j in LEGS[leg])
    floor = np.minimum(_shin_foot_angle(knee, ankle, toe), ANKLE_MIN_ANGLE)
    toes = toe - ankle
    toes[:, 1] = 0.0

    def fits(rows: np.ndarray, share: np.ndarray) -> np.ndarray:
        goal = ankle[rows].copy()
        goal[:, [0, 2]] += share[:, None] * offset[rows]
        goal = soft_reach(hip[rows], knee[rows], ankle[rows], goal)
        new_knee, new_ankle = two_bone_ik(
            hip[rows], knee[rows], ankle[rows], goal, toes[rows], hint_length=TOE_HINT_LENGTH
        )
        return _shin_foot_angle(new_knee, new_ankle, toe[rows] + new_ankle - ankle[rows]) >= floor[rows]

    share = np.ones(len(joints))
    rows = np.nonzero(~fits(np.arange(len(joints)), share))[0]
    low, high = np.zeros(len(rows)), np.ones(len(rows))
    for _ in range(ANKLE_BISECTIONS if len(rows) else 0):
        mid = 0.5 * (low + high)
        ok = fits(rows, mid)
        low, high = np.where(ok, mid, low), np.where(ok, high, mid)
    share[rows] = low
    return share


def two_bone_ik(
    hip: np.ndarray,
    knee: np.ndarray,
    ankle: np.ndarray,
    target: np.ndarray,
    bend_hint: np.ndarray | None = None,
    hint_weight: float = HINT_WEIGHT,
    hint_length: float = 0.0,
    hint_fill: float = 0.0,
) -> tuple:
    """Analytic two-bone IK per frame: hip fixed, bone lengths kept, the ankle moved to the target.

    The knee keeps the side it bent to, measured against the leg's *original* hip-ankle axis:
    measured against the new axis, a nearly straight leg's bend direction is noise, and the knee
    can flip backwards or sideways (hip twists of 90 degrees on runs). That side turns with the
    leg, by the rotation that takes the original axis to the new one (projected on the new axis
    instead, a target far from the ankle, such as a pin the body dragged 30 cm behind, left
    little of it and the knee jumped sideways for a frame). An optional `bend_hint` (e.g. the
    direction the toes point) adds a bias of `hint_weight` m (5 cm), so a straight leg bends
    that way; a hint shorter than `hint_length` m adds as much less (a foot pointing down has
    a short, noisy horizontal toe direction: given its whole weight, it swung the knee 4 cm
    sideways for a frame at toe-off). With `hint_fill`, the bias grows by `hint_fill` times the bend
    the target needs, in the measure that the limb does not show it (squared share): a limb held
    straight but short, which must bend far to reach the target, bends the hint's way instead of
    the way a few millimetres of noise put its middle joint.

    All (N, 3); returns (new knee, new ankle). Compiled (:mod:`motion_env.generation.ik_jit`)
    where numba runs and every array is float64.
    """
    arrays = (hip, knee, ankle, target) + (() if bend_hint is None else (bend_hint,))
    if jit_enabled() and all(a.dtype == np.float64 and a.ndim == 2 for a in arrays):
        from motion_env.generation.ik_jit import solve_rows

        note_first_compile(solve_rows, "the two-bone IK")
        hint = target if bend_hint is None else bend_hint  # (not read without a hint)
        limbs = (np.ascontiguousarray(a) for a in (hip, knee, ankle, target, hint))  # one layout compiled
        return solve_rows(*limbs, bend_hint is not None, hint_weight, hint_length, hint_fill)
    l1 = vector_norm(knee - hip)
    l2 = vector_norm(ankle - knee)
    to = target - hip
    d = vector_norm(to)
    d_clamped = np.clip(d, np.abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4)
    u = to / np.maximum(d, 1e-9)[:, None]
    leg = ankle - hip
    axis0 = leg / np.maximum(vector_norm(leg, keepdims=True), 1e-9)
    bend = (knee - hip) - ((knee - hip) * axis0).sum(-1, keepdims=True) * axis0
    a = (l1**2 - l2**2 + d_clamped**2) / (2 * d_clamped)
    h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))  # how far the knee stands off the hip-target line
    if bend_hint is not None:
        hint_n = vector_norm(bend_hint, keepdims=True)
        weight = hint_weight
        if hint_fill:
            missing = np.clip(1.0 - vector_norm(bend) / np.maximum(h, 1e-9), 0.0, 1.0)
            weight = hint_weight + (hint_fill * h * missing**2)[:, None]
        bend = bend + weight * bend_hint / np.maximum(hint_n, max(hint_length, 1e-9))
    pole = qrot(qbetween(axis0, u), bend)
    pole = pole - (pole * u).sum(-1, keepdims=True) * u
    pole_n = vector_norm(pole, keepdims=True)
    # A straight leg with no hint has no bend plane: bend the knee along the original shin.
    fallback = (ankle - knee) - ((ankle - knee) * u).sum(-1, keepdims=True) * u
    pole = np.where(pole_n > 1e-6, pole / np.maximum(pole_n, 1e-9), fallback)
    pole = pole / np.maximum(vector_norm(pole, keepdims=True), 1e-9)
    new_knee = hip + a[:, None] * u + h[:, None] * pole
    new_ankle = hip + d_clamped[:, None] * u
    return new_knee, new_ankle


class FootPinner:
    """Causal foot cleanup for B characters, frame by frame (whole clips and streaming alike).

    A foot flagged in contact by the decoder is pinned where it is shown when the contact starts
    (its ankle, or its toe while only the toe touches, as the heel lifts; gliding on for a few
    frames with the foot's last step, FOOT_GLIDE, so that a landing foot does not stop dead) and
    the leg is re-solved with :func:`two_bone_ik`, within the leg's soft reach
    (:func:`soft_reach`). A held pin creeps towards where the foot is shown, FOOT_CREEP_RATE of
    the way a frame and FOOT_CREEP at most (as slowly as real planted feet slide), so one frame's
    error of the decoded foot is not frozen for the whole contact. The pin follows the foot when
    the body drags it more than FOOT_MAX_OFFSET away, or so far that the shin would lean over the
    foot beyond ANKLE_MIN_ANGLE (:func:`ankle_room`), and after the contact the correction fades
    out over FOOT_BLEND frames (:func:`release_fade`). It never needs future frames, and it keeps
    every joint within FOOT_MAX_OFFSET of the decoded pose: pins the leg cannot reach make no pops.

    Args:
        batch: B characters; the state of each carries over from one :meth:`apply` to the next.
    """

    def __init__(self, batch: int) -> None:
        self.pins = np.full((batch, len(LEGS), 2, 2), np.nan)  # pinned ankle / toe XZ, NaN: free
        self.offset = np.zeros((batch, len(LEGS), 2))  # correction of the last frame
        self.released = np.zeros((batch, len(LEGS), 2))  # correction when the contact ended
        self.since = np.full((batch, len(LEGS)), FOOT_BLEND + 1)  # frames since then
        self.glide = np.zeros((batch, len(LEGS), 2))  # how far a new pin moves on next frame
        self.shown = np.full((batch, len(LEGS), 2, 2), np.nan)  # ankle / toe XZ in the last frame

    def reset(self, i: int) -> None:
        """Forget character i's feet (a new episode)."""
        self.pins[i] = self.shown[i] = np.nan
        self.offset[i] = self.released[i] = self.glide[i] = 0.0
        self.since[i] = FOOT_BLEND + 1

    def apply(self, i: int, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """Character i's next frames: (n, 22, 3) joints and (n, 4) contact channels -> (n, 22, 3).

        contacts: the decoded features' foot contacts (left ankle, left toe, right ankle, right
        toe; > 0.5 = in contact).
        """
        return self.apply_rows(np.array([i]), np.asarray(joints)[None], np.asarray(contacts)[None])[0]

    def apply_rows(self, rows: np.ndarray, joints: np.ndarray, contacts: np.ndarray) -> np.ndarray:
        """The next frames of characters `rows` at once: (R, n, 22, 3) joints and (R, n, 4)
        contacts -> (R, n, 22, 3); the same as :meth:`apply` row by row."""
        rows = np.asarray(rows, dtype=np.int64)
        decoded = np.asarray(joints).astype(np.float64)
        flags = np.asarray(contacts) > 0.5
        out = decoded.copy()
        fields = (self.pins, self.offset, self.released, self.since, self.glide, self.shown)
        saved = [a[rows].copy() for a in fields]
        check = np.zeros(flags.shape[:2] + (len(LEGS),), dtype=bool)
        # Frames whose leg bends too far at the ankle (rare: a jump's crouch) are done again, each
        # pin giving way there as far as ankle_room asks, until no new ones appear. The legs go
        # together, yet each leg's passes are its own: a leg done again from the saved state with
        # the checks it had gives what it gave.
        for attempt in range(_ANKLE_PASSES):
            if attempt:
                for a, state in zip(fields, saved, strict=True):
                    a[rows] = state
            offsets = self._pin(rows, decoded, flags, check)  # (R, n, legs, 2)
            bent = _re_solve(out, decoded, offsets)  # (R, n, legs)
            new = (bent & ~check).any(axis=(0, 1))  # (legs,)
            if not new.any():
                break
            check |= bent
            if attempt == _ANKLE_PASSES - 1:  # out of passes: a leg still bending keeps its state from before
                for a, state in zip(fields, saved, strict=True):
                    a[rows[:, None], np.nonzero(new)[0]] = state[:, new]
        return out.astype(np.float32)

    def _pin(self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray, check: np.ndarray) -> np.ndarray:
        """(R, n, legs, 2) horizontal corrections of each leg's ankle in the new frames `joints`
        (R, n, 22, 3) of characters `rows`, flags (R, n, 4) > 0.5; updates the pins. In the frames
        and legs of `check` (R, n, legs) the correction is cut to its ankle_room (and the pin slides
        with it)."""
        if not check.any() and jit_enabled():  # no pin is cut: compiled (feet_jit)
            return self._pin_compiled(rows, joints, flags)
        ankles, toes = [leg[2] for leg in LEGS], [leg[3] for leg in LEGS]
        # What each frame asks of each leg, before the frame loop: the ankle's flag wins; the toe
        # alone is pinned while the heel lifts; the pinned joint's place.
        kinds = np.where(flags[..., 0::2], 0, np.where(flags[..., 1::2], 1, -1))  # (R, n, legs)
        held = kinds >= 0
        both = np.stack([joints[:, :, ankles], joints[:, :, toes]], axis=3)[..., [0, 2]]  # (R, n, legs, 2, 2)
        is_ankle = (kinds == 0)[..., None]
        shown = np.where(is_ankle, both[..., 0, :], both[..., 1, :])  # (R, n, legs, 2)
        # A pin is fresh where its joint was not held the frame before (a pin lasts while its kind
        # does), so the frame loop only carries one pin a leg. A fresh pin glides on with the foot's
        # last step: that step, capped, is known before the loop too.
        pins = self.pins[rows]  # (R, legs, 2 kinds, 2)
        first = np.take_along_axis(pins, np.maximum(kinds[:, 0], 0)[..., None, None], axis=2)[:, :, 0]
        fresh = held.copy()
        fresh[:, 0] &= np.isnan(first[..., 0])
        fresh[:, 1:] &= kinds[:, 1:] != kinds[:, :-1]
        before = np.concatenate([self.shown[rows][:, None], both[:, :-1]], axis=1)  # (R, n, legs, 2, 2)
        step = FOOT_GLIDE * np.nan_to_num(shown - np.where(is_ankle, before[..., 0, :], before[..., 1, :]))
        size = vector_norm(step)
        fresh_glide = step * (np.minimum(size, FOOT_GLIDE_STEP) / np.maximum(size, 1e-12))[..., None]
        # The carried state, as the frames leave it.
        pin = np.where(held[:, 0, :, None], first, np.nan)  # (R, legs, 2)
        glide, offset = self.glide[rows], self.offset[rows]
        released, since = self.released[rows], self.since[rows]
        offsets = np.zeros(kinds.shape + (2,))
        for t in range(joints.shape[1]):
            h, f, xz = held[:, t], fresh[:, t], shown[:, t]  # (R, legs), (R, legs), (R, legs, 2)
            since = np.where(h, 0, since + 1)
            # A held pin glides on by the glide it has (which then halves), a fresh one starts
            # where its foot is shown now, with the correction the leg had.
            target = np.where(f[..., None], xz + offset, pin + glide)
            held_glide = np.where(f[..., None], fresh_glide[:, t], glide * FOOT_GLIDE)
            glide = np.where(h[..., None], held_glide, glide)  # (a free leg's glide is never read)
            moved = target - xz
            dist = vector_norm(moved)
            creep = np.where(f, 0.0, np.minimum(FOOT_CREEP_RATE * dist, FOOT_CREEP))
            moved = moved * (1.0 - creep / np.maximum(dist, 1e-12))[..., None]
            norm = vector_norm(moved)
            far = np.where(norm > FOOT_MAX_OFFSET, FOOT_MAX_OFFSET / np.maximum(norm, 1e-12), 1.0)
            moved = moved * far[..., None]
            cut = h & check[:, t]
            for leg in np.nonzero(cut.any(axis=0))[0]:
                at = np.nonzero(cut[:, leg])[0]
                moved[at, leg] *= ankle_room(joints[at, t], leg, moved[at, leg])[:, None]
            # The pin slides with the foot where it is cut.
            pin = np.where(h[..., None], xz + moved, np.nan)
            released = np.where(h[..., None], moved, released)
            offset = offsets[:, t] = np.where(h[..., None], moved, released * release_fade(since)[..., None])
        last = kinds[:, -1]  # the pin of the last frame's kind is kept, the other is none
        for kind in (0, 1):
            pins[:, :, kind] = np.where((last == kind)[..., None], pin, np.nan)
        self.pins[rows], self.glide[rows], self.offset[rows] = pins, glide, offset
        self.released[rows], self.since[rows] = released, since
        self.shown[rows] = both[:, -1]
        return offsets

    def _pin_compiled(self, rows: np.ndarray, joints: np.ndarray, flags: np.ndarray) -> np.ndarray:
        """:meth:`_pin` where no pin is cut, as one compiled pass (:mod:`~motion_env.generation.feet_jit`)."""
        from motion_env.generation.feet_jit import pin_rows

        note_first_compile(pin_rows, "the foot pinner")
        fields = (self.pins, self.shown, self.glide, self.offset, self.released, self.since)
        state = [a[rows] for a in fields]  # updated in place, then put back
        constants = (FOOT_GLIDE, FOOT_GLIDE_STEP, FOOT_CREEP_RATE, FOOT_CREEP, FOOT_MAX_OFFSET, FOOT_BLEND)
        offsets = pin_rows(
            np.ascontiguousarray(joints), np.ascontiguousarray(flags), *state, _LEGS, *constants
        )
        for a, value in zip(fields, state, strict=True):
            a[rows] = value
        return offsets


def _re_solve(out: np.ndarray, decoded: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The legs of the frames `out` (R, n, 22, 3) re-solved for their ankles moved horizontally by
    `offsets` (R, n, legs, 2) (in place; `decoded`: the frames as they came; one IK call for every
    leg, which reads and writes only its own joints); returns (R, n, legs) the frames whose
    shin-foot angle ended narrower than ankle_room allows, and the frame on each side."""
    if jit_enabled():
        from motion_env.generation.feet_jit import re_solve_rows

        note_first_compile(re_solve_rows, "the foot pinner's leg re-solve")
        constants = (
            FOOT_STRETCH,
            FOOT_SOFTNESS,
            HINT_WEIGHT,
            TOE_HINT_LENGTH,
            ANKLE_MIN_ANGLE,
            ANKLE_TOLERANCE,
        )
        return re_solve_rows(out, decoded, np.ascontiguousarray(offsets), _LEGS, *constants)
    chains = np.asarray(LEGS)  # (legs, 4) hip, knee, ankle, toe
    out[..., chains.reshape(-1), :] = decoded[..., chains.reshape(-1), :]  # frames left alone: exact
    bent = np.zeros(offsets.shape[:3], dtype=bool)
    r, t, leg = np.nonzero(offsets.any(axis=-1))
    if not len(r):
        return bent
    chain = chains[leg]  # (M, 4)
    hip, knee, ankle, toe = (decoded[r, t, chain[:, j]] for j in range(4))
    goal = ankle.copy()
    goal[:, [0, 2]] += offsets[r, t, leg]
    goal = soft_reach(hip, knee, ankle, goal)
    toes = toe - ankle
    toes[:, 1] = 0.0  # a knee points the way the foot does
    new_knee, new_ankle = two_bone_ik(hip, knee, ankle, goal, toes, hint_length=TOE_HINT_LENGTH)
    new_toe = toe + new_ankle - ankle
    out[r, t, chain[:, 1]], out[r, t, chain[:, 2]], out[r, t, chain[:, 3]] = new_knee, new_ankle, new_toe
    floor = np.minimum(_shin_foot_angle(knee, ankle, toe), ANKLE_MIN_ANGLE)
    bent[r, t, leg] = _shin_foot_angle(new_knee, new_ankle, new_toe) < floor - ANKLE_TOLERANCE
    bent[:, 1:] |= bent[:, :-1].copy()
    bent[:, :-1] |= bent[:, 1:].copy()
    return bent
