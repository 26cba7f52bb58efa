"""The feet stage's leg: soft reach, smooth release, no knee snap; the arms' rebuild on bone lengths."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from motion_env.evaluation.metrics import joint_acceleration
from motion_env.generation.feet import (
    ANKLE_MIN_ANGLE,
    FOOT_BLEND,
    FOOT_CREEP,
    FOOT_GLIDE,
    LEGS,
    TOE_HINT_LENGTH,
    FootPinner,
    ankle_room,
    release_fade,
    soft_reach,
    two_bone_ik,
)
from motion_env.generation.recompose import (
    ARMS,
    ELBOW_DOWN,
    ELBOW_SAGITTAL,
    bend_elbows_one_way,
    on_bone_lengths,
)
from motion_env.motion.kinematics import bone_lengths, with_bone_lengths
from motion_env.motion.skeleton import BONE_LENGTHS, PARENTS, RAW_OFFSETS


def _pose() -> np.ndarray:
    """A standing pose on the skeleton's bones, knees a little bent, arms hanging: (22, 3)."""
    dirs = RAW_OFFSETS.astype(np.float64)
    for thigh, shin in ((4, 7), (5, 8)):
        dirs[thigh], dirs[shin] = (0.0, -1.0, 0.25), (0.0, -1.0, -0.25)
    for upper, fore in ((18, 20), (19, 21)):
        dirs[upper], dirs[fore] = (0.0, -1.0, 0.05), (0.0, -1.0, 0.3)
    dirs[1:] /= np.linalg.norm(dirs[1:], axis=1, keepdims=True)
    pose = np.zeros((22, 3))
    pose[0, 1] = 0.95
    for j in range(1, 22):
        pose[j] = pose[PARENTS[j]] + dirs[j] * BONE_LENGTHS[j]
    return pose


def test_release_fade_goes_smoothly_from_one_to_zero() -> None:
    since = np.arange(0, FOOT_BLEND + 3)
    fade = release_fade(since)
    assert fade[0] == 1.0 and np.all(fade[FOOT_BLEND + 1 :] == 0.0)
    assert np.all(np.diff(fade) <= 0)
    # No step in the correction's speed where the fade starts and ends: its first and last steps
    # are smaller than a linear fade's.
    step = -np.diff(fade)
    assert step[0] < 1.0 / (FOOT_BLEND + 1) and step[FOOT_BLEND] < 1.0 / (FOOT_BLEND + 1)


def test_soft_reach_leaves_reachable_goals_and_never_locks_the_knee() -> None:
    pose = _pose()
    hip, knee, ankle, _ = LEGS[0]
    n = 60
    rows = np.repeat(pose[None], n, axis=0)
    # Goals from the ankle itself to far beyond the leg, straight down and behind.
    away = ankle_dir = pose[ankle] - pose[hip]
    ankle_dir = away / np.linalg.norm(away)
    goals = pose[hip] + ankle_dir * np.linspace(np.linalg.norm(away), 1.2, n)[:, None]
    goals[:, 2] -= np.linspace(0.0, 0.3, n)
    out = soft_reach(rows[:, hip], rows[:, knee], rows[:, ankle], goals)
    np.testing.assert_allclose(out[0], pose[ankle], atol=1e-9)  # the decoded ankle stays
    length = BONE_LENGTHS[knee] + BONE_LENGTHS[ankle]
    reach = np.linalg.norm(out - pose[hip], axis=-1)
    assert reach.max() < length * (1 - 1e-3)  # never straight
    assert np.all(np.diff(reach) >= -1e-12)  # farther goals, farther ankles
    # Continuous: no step larger than the goals' own.
    assert np.abs(np.diff(out, axis=0)).max() <= np.abs(np.diff(goals, axis=0)).max() + 1e-9


def test_a_pin_the_body_leaves_behind_does_not_snap_the_knee() -> None:
    """The body glides on 3 cm a frame over a planted foot for 12 frames, then the foot lets go:
    the leg stretches towards the pin, softly, and bends back without a jolt of the knee."""
    n = 40
    joints = np.repeat(_pose()[None], n, axis=0)
    joints[..., 2] += 0.03 * np.arange(n)[:, None]
    contacts = np.zeros((n, 4))
    contacts[5:17, :2] = 1.0  # the left foot is planted for 12 frames
    out = FootPinner(1).apply(0, joints, contacts)
    hip, knee, ankle, _ = LEGS[0]
    stretch = np.linalg.norm(out[:, ankle] - out[:, hip], axis=-1) / (
        BONE_LENGTHS[knee] + BONE_LENGTHS[ankle]
    )
    assert stretch.max() < 0.999
    assert joint_acceleration(out)[:, knee].max() < 30.0  # m/s^2 (a locked knee snapping back: ~100)
    np.testing.assert_allclose(out[17 + FOOT_BLEND :], joints[17 + FOOT_BLEND :], atol=1e-6)  # released
    # Bones keep their lengths.
    np.testing.assert_allclose(
        bone_lengths(out)[:, [knee, ankle]], bone_lengths(joints)[:, [knee, ankle]], atol=1e-5
    )


def _leg(knee_out: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(1, 3) hip, knee, ankle of a leg hanging down, its knee 10 cm forward and `knee_out` m out."""
    hip = np.array([[0.1, 0.9, 0.0]])
    knee = np.array([[0.1 + knee_out, 0.5, 0.1]])
    ankle = np.array([[0.1, 0.1, 0.0]])
    return hip, knee, ankle


def test_the_knee_keeps_its_side_when_the_leg_swings_far() -> None:
    """A target far ahead of the ankle (a pin the body dragged far) turns the leg by 60 degrees:
    the knee's bend turns with it, so it stays mostly forward instead of going sideways."""
    hip, knee, ankle = _leg(0.02)
    target = hip + 0.75 * np.array([[0.0, -np.cos(np.radians(60)), np.sin(np.radians(60))]])
    new_knee, new_ankle = two_bone_ik(hip, knee, ankle, target)
    np.testing.assert_allclose(new_ankle, target, atol=1e-6)
    u = (target - hip) / np.linalg.norm(target - hip)
    side = (new_knee - hip) - ((new_knee - hip) * u).sum() * u
    assert abs(side[0, 0]) < 0.3 * np.linalg.norm(side)  # decoded: 2 cm out of a 10 cm bend
    assert side[0, 1] > 0.0  # forward of the turned leg is up and ahead


def test_a_short_toe_hint_barely_moves_the_knee() -> None:
    """A foot pointing down has a short horizontal toe direction: noise, which must not swing the
    knee sideways (given its whole weight it did, 4 cm in a frame at toe-off)."""
    hip, knee, ankle = _leg(0.0)
    target = ankle + np.array([[0.0, 0.02, 0.05]])
    plain, _ = two_bone_ik(hip, knee, ankle, target)
    short = np.array([[0.01, 0.0, 0.0]])  # 1 cm sideways
    hinted, _ = two_bone_ik(hip, knee, ankle, target, short, hint_length=TOE_HINT_LENGTH)
    loud, _ = two_bone_ik(hip, knee, ankle, target, short)
    assert np.linalg.norm(hinted - plain) < 0.25 * np.linalg.norm(loud - plain)
    # A flat foot's full-length hint still bends the knee its way.
    full, _ = two_bone_ik(hip, knee, ankle, target, 10 * short, hint_length=TOE_HINT_LENGTH)
    np.testing.assert_allclose(full, loud, atol=1e-9)


def test_a_held_pin_creeps_to_where_the_foot_stands_as_slowly_as_real_feet_slide() -> None:
    """The decoder shows a standing foot 4 cm aside on the contact's first frame only, then where
    it stands for good: the pin does not keep that first frame's error for the whole contact (it
    did, for seconds, on every standing clip), but creeps to the foot, FOOT_CREEP a frame at most,
    slowing down as it arrives."""
    n = 40
    decoded = np.repeat(_pose()[None], n, axis=0)
    decoded[0, :, 0] += 0.04  # the whole body aside on the first frame: the feet are shown there
    out = FootPinner(1).apply(0, decoded, np.ones((n, 4))).astype(np.float64)
    for leg in range(len(LEGS)):
        ankle = LEGS[leg][2]
        gap = np.linalg.norm(out[:, ankle, [0, 2]] - decoded[:, ankle, [0, 2]], axis=-1)
        assert gap[1] > 0.03  # held at first
        assert np.all(np.diff(gap[1:]) <= 1e-9)  # then ever closer
        step = np.linalg.norm(np.diff(out[1:, ankle, [0, 2]], axis=0), axis=-1)
        assert step.max() < FOOT_CREEP + 1e-4  # no faster than real planted feet slide
        assert np.all(np.diff(step[-20:]) <= 1e-9)  # slowing down as it arrives
    np.testing.assert_allclose(out[30:], decoded[30:], atol=1e-4)  # and it stands there
    # A foot the body drags steadily 1 cm a frame is held back: it slides FOOT_CREEP a frame
    # (until the leg's soft reach lets the ankle go further).
    dragged = np.repeat(_pose()[None], n, axis=0)
    dragged[..., 2] += 0.01 * np.arange(n)[:, None]
    held = FootPinner(1).apply(0, dragged, np.ones((n, 4)))
    step = np.linalg.norm(np.diff(held[:, LEGS[0][2]][:, [0, 2]], axis=0), axis=-1)
    np.testing.assert_allclose(step[3:15], FOOT_CREEP, atol=1e-4)


def test_a_landing_foot_glides_to_a_stop_instead_of_stopping_dead() -> None:
    """A foot that lands moving 3 cm a frame was held where it was shown on the contact's first
    frame: its speed fell to the creep's in one frame (the knees' and ankles' pops at a step's
    onset: walks' acceleration 1.18x the real takes'). The pin now glides on with the last step,
    FOOT_GLIDE of it and less each frame, and then holds."""
    n, onset = 30, 10
    decoded = np.repeat(_pose()[None], n, axis=0)
    decoded[..., 2] += 0.03 * np.arange(n)[:, None]  # the body, feet and all, moving on
    contacts = np.zeros((n, 4))
    contacts[onset:, :2] = 1.0  # the left foot lands and stays flagged
    ankle = LEGS[0][2]

    def steps(glide: float) -> np.ndarray:
        with pytest.MonkeyPatch.context() as m:
            m.setattr("motion_env.generation.feet.FOOT_GLIDE", glide)
            out = FootPinner(1).apply(0, decoded, contacts).astype(np.float64)
        return np.linalg.norm(np.diff(out[:, ankle, [0, 2]], axis=0), axis=-1)  # step into frame t + 1

    dead, glided = steps(0.0), steps(FOOT_GLIDE)
    np.testing.assert_allclose(glided[: onset - 1], 0.03, atol=1e-6)  # untouched before the contact
    landing = slice(onset - 2, onset + 8)  # (later the body drags the foot past FOOT_MAX_OFFSET)
    assert np.abs(np.diff(dead[landing])).max() > 0.025  # 3 cm to the creep's 4 mm at once
    assert np.abs(np.diff(glided[landing])).max() < 0.6 * np.abs(np.diff(dead[landing])).max()
    assert np.all(np.diff(glided[onset : onset + 4]) < 0)  # slowing down
    # It glides FOOT_GLIDE / (1 - FOOT_GLIDE) steps further at most, then is held as before.
    assert glided[onset : onset + 8].sum() - dead[onset : onset + 8].sum() < 0.03 * FOOT_GLIDE / (
        1 - FOOT_GLIDE
    )
    assert 0.0 < FOOT_GLIDE < 1.0


def test_the_pinner_given_tokens_equals_the_whole_clip() -> None:
    n = 40
    joints = np.repeat(_pose()[None], n, axis=0)
    joints[..., 2] += 0.03 * np.arange(n)[:, None]
    contacts = np.zeros((n, 4))
    contacts[5:17, :2] = contacts[20:33, 2:] = 1.0
    whole = FootPinner(1).apply(0, joints, contacts)
    pinner = FootPinner(1)
    parts = np.concatenate([pinner.apply(0, joints[f : f + 4], contacts[f : f + 4]) for f in range(0, n, 4)])
    np.testing.assert_allclose(parts, whole, atol=1e-6)


def test_arms_keep_the_decoded_wrists_where_a_forearm_collapses() -> None:
    pose = _pose()
    n = 9
    decoded = np.repeat(pose[None], n, axis=0)
    # The decoder shrinks the left forearm to a third for a few frames while the hand stays put:
    # the elbow moves towards the wrist and a little aside, so the short forearm turns.
    shoulder, elbow, wrist = ARMS[0]
    shrink = np.array([0, 0, 0.3, 0.6, 0.67, 0.6, 0.3, 0, 0])
    decoded[:, elbow] += shrink[:, None] * (pose[wrist] - pose[elbow] + np.array([0.12, 0.0, 0.0]))
    rebuilt = on_bone_lengths(decoded)
    np.testing.assert_allclose(bone_lengths(rebuilt), np.broadcast_to(BONE_LENGTHS, (n, 22)), atol=1e-5)
    # The wrist stays where it was decoded (relative to the shoulder); keeping bone directions
    # swings it far out.
    kept = np.linalg.norm(
        (rebuilt[:, wrist] - rebuilt[:, shoulder]) - (decoded[:, wrist] - decoded[:, shoulder]), axis=-1
    )
    swung = with_bone_lengths(decoded)
    moved = np.linalg.norm(
        (swung[:, wrist] - swung[:, shoulder]) - (decoded[:, wrist] - decoded[:, shoulder]), axis=-1
    )
    assert kept.max() < 0.03 and moved.max() > 0.08  # (ARM_SCALE of a 0.5 m arm: 2.5 cm)
    assert joint_acceleration(rebuilt)[:, wrist].max() < 0.3 * joint_acceleration(swung)[:, wrist].max()
    # A pose already on the skeleton's bones keeps its wrists; its elbows move by millimetres at most
    # (the bend bias, ARM_BEND_HINT, on arms as good as straight).
    same = on_bone_lengths(pose[None])[0]
    np.testing.assert_allclose(same[[20, 21]], pose[[20, 21]], atol=1e-5)
    np.testing.assert_allclose(same, pose, atol=5e-3)


@pytest.mark.parametrize(
    ("arm", "share", "noise", "back", "step"),
    [
        (1, 0.9, 0.002, 0.02, 0.1),  # 10 % short: it swung 20 cm a frame in a stream
        (0, 0.5, 0.003, 0.05, 0.05),  # half length as a hand is thrown up: it flipped at 250 m/s^2
    ],
)
def test_a_straight_but_short_decoded_arm_bends_its_elbow_one_way(
    arm: int, share: float, noise: float, back: float, step: float
) -> None:
    """The decoder holds an arm straight but short (`share` of its length); the wrist is kept
    near its decoded place, so the elbow must bend, and its elbow, off the line by noise alone,
    must not flip from side to side between frames."""
    pose = _pose()
    n = 30
    decoded = np.repeat(pose[None], n, axis=0)
    shoulder, elbow, wrist = ARMS[arm]
    reach = share * (BONE_LENGTHS[elbow] + BONE_LENGTHS[wrist])
    down = np.array([0.0, -1.0, 0.0])
    decoded[:, wrist] = pose[shoulder] + reach * down
    jitter = np.random.default_rng(arm).normal(0.0, noise, (n, 3))
    decoded[:, elbow] = pose[shoulder] + 0.5 * reach * down + jitter
    rebuilt = on_bone_lengths(decoded)
    side = rebuilt[:, elbow] - rebuilt[:, shoulder]
    # It bends back (-z for this pose), every frame; noise still wobbles it a few cm, no flip.
    assert np.all(side[:, 2] < -back)
    assert np.linalg.norm(np.diff(rebuilt[:, elbow], axis=0), axis=-1).max() < step


def _mirror_elbows(pose: np.ndarray) -> np.ndarray:
    """`pose` with each elbow mirrored across its shoulder-wrist line (a forearm bent the other way)."""
    out = pose.copy()
    for shoulder, elbow, wrist in ARMS:
        u = (pose[wrist] - pose[shoulder]) / np.linalg.norm(pose[wrist] - pose[shoulder])
        rel = pose[elbow] - pose[shoulder]
        out[elbow] = pose[shoulder] + 2 * (rel @ u) * u - rel
    return out


def _turn_arms(pose: np.ndarray, axis: int, degrees: float) -> np.ndarray:
    """`pose` with both arms turned about their shoulders by `degrees` about world `axis` (0: x)."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    i, j = [k for k in range(3) if k != axis]
    out = pose.copy()
    for shoulder, elbow, wrist in ARMS:
        rel = out[[elbow, wrist]] - out[shoulder]
        turned = rel.copy()
        turned[:, i], turned[:, j] = c * rel[:, i] - s * rel[:, j], s * rel[:, i] + c * rel[:, j]
        out[[elbow, wrist]] = out[shoulder] + turned
    return out


@pytest.mark.parametrize("swing", [0.0, 60.0, -50.0])  # hanging, swung back, held forward
def test_an_elbow_bent_backwards_is_mirrored_to_the_side_elbows_flex_to(swing: float) -> None:
    natural = _turn_arms(_pose(), 0, swing)  # a rotation about the left-right axis keeps the flexion
    same = natural[None].copy()
    bend_elbows_one_way(same)
    np.testing.assert_allclose(same[0], natural, atol=1e-9)
    backwards = _mirror_elbows(natural)[None]
    bend_elbows_one_way(backwards)
    np.testing.assert_allclose(backwards[0], natural, atol=1e-9)  # wrist and bone lengths kept


def test_an_arm_held_out_sideways_keeps_its_elbow_and_an_elbow_crossing_its_line_moves_smoothly() -> None:
    sideways = _mirror_elbows(_turn_arms(_pose(), 2, 85.0))  # the left arm out to the left, level
    out = sideways[None].copy()
    bend_elbows_one_way(out)
    shoulder, elbow, wrist = ARMS[0]
    np.testing.assert_allclose(out[0, elbow], sideways[elbow], atol=1e-9)
    # The elbow of a hanging arm passes from 2 cm behind its line to 2 cm in front of it.
    pose = _pose()
    n = 41
    frames = np.repeat(pose[None], n, axis=0)
    u = (pose[wrist] - pose[shoulder]) / np.linalg.norm(pose[wrist] - pose[shoulder])
    middle = pose[shoulder] + 0.5 * (pose[wrist] - pose[shoulder])
    back = np.cross([1.0, 0.0, 0.0], u)
    frames[:, elbow] = middle + np.linspace(0.02, -0.02, n)[:, None] * back
    out = frames.copy()
    bend_elbows_one_way(out)
    steps = np.linalg.norm(np.diff(out[:, elbow], axis=0), axis=-1)
    assert steps.max() <= 0.001 + 1e-9  # no jump where it crosses
    assert (((out[:, elbow] - middle) @ back) >= -1e-9).all()  # behind the line, every frame


def test_the_compiled_bone_lengths_give_what_numpy_gives(both_ways: Callable) -> None:
    """compose_jit's bone lengths, arms and elbows against on_bone_lengths' numpy operations, to
    the bit: noisy poses, arms straight but short, elbows bent backwards (each elbow rewritten),
    none moved (none rewritten), a bone of no length (its rest direction), and a batch."""
    from motion_env.generation import compose_jit

    rng = np.random.default_rng(11)
    pose = _pose()
    noisy = pose + rng.normal(0.0, 0.03, (40, 22, 3))
    short = np.repeat(pose[None], 6, axis=0)
    for shoulder, elbow, wrist in ARMS:
        short[:, wrist] = pose[shoulder] + [0.0, -0.3, 0.0]
        short[:, elbow] = pose[shoulder] + [0.0, -0.15, 0.0] + rng.normal(0.0, 0.003, (6, 3))
    backwards = np.stack([_mirror_elbows(_turn_arms(pose, 0, a)) for a in (0.0, 60.0, -50.0)])
    still = np.stack([_turn_arms(pose, 0, a) for a in (0.0, 60.0, -50.0)])
    collapsed = np.repeat(pose[None, :1], 22, axis=1).repeat(2, axis=0)  # no bone has a direction
    for joints in (noisy, short, backwards, still, collapsed, noisy.reshape(4, 10, 22, 3)):
        run = lambda j=joints: on_bone_lengths(j.astype(np.float32))  # noqa: E731
        outputs = both_ways(compose_jit, "arms_on_lengths", run)
        np.testing.assert_array_equal(outputs[True], outputs[False])
        assert outputs[True].shape == joints.shape and outputs[True].dtype == np.float32
    # The elbows alone: when none is moved, none is rewritten; when one is, all are (as numpy's).
    arms, constants = np.array(ARMS), (ELBOW_SAGITTAL, ELBOW_DOWN)
    hanging = np.stack([_turn_arms(pose, 0, a) for a in np.linspace(-50.0, 60.0, 30)])
    hanging += rng.normal(0.0, 0.002, hanging.shape)
    for joints in (hanging, np.concatenate([hanging, backwards])):
        want, got = joints.copy(), joints.copy()
        bend_elbows_one_way(want)
        compose_jit._bend_elbows(got, arms, *constants)
        np.testing.assert_array_equal(got, want)


def _shin_foot(out: np.ndarray, leg: int) -> np.ndarray:
    _, knee, ankle, toe = LEGS[leg]
    u, v = out[:, knee] - out[:, ankle], out[:, toe] - out[:, ankle]
    cos = (u * v).sum(-1) / np.linalg.norm(u, axis=-1) / np.linalg.norm(v, axis=-1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def test_a_pin_gives_way_before_the_ankle_bends_beyond_its_range() -> None:
    """The body drifts forwards on 3 cm a frame over planted feet (a decoded jump's crouch does):
    held where it landed, a foot would leave the shin leaning ever further over it; the pin holds
    while the shin-foot angle stays at least ANKLE_MIN_ANGLE, then gives way smoothly."""
    n = 30
    joints = np.repeat(_pose()[None], n, axis=0)
    joints[..., 2] += 0.03 * np.arange(n)[:, None]
    assert _shin_foot(joints, 0)[0] > ANKLE_MIN_ANGLE + 3.0
    out = FootPinner(1).apply(0, joints, np.ones((n, 4))).astype(np.float64)
    assert (_shin_foot(out, 0) >= ANKLE_MIN_ANGLE - 0.5).all()
    step = np.linalg.norm(np.diff(out[:, LEGS[0][2]][:, [0, 2]], axis=0), axis=-1)
    assert step[:2].max() < FOOT_CREEP + 1e-4  # it holds (creeping) while the leg allows
    assert step[-10:].min() > 0.02  # then the foot goes with the body
    assert joint_acceleration(out).max() < 15.0  # m/s^2: without a jolt
    pinner = FootPinner(1)  # the stream's tokens give the same
    tokens = [
        pinner.apply(0, joints[f : f + 4], np.ones((len(joints[f : f + 4]), 4))) for f in range(0, n, 4)
    ]
    np.testing.assert_allclose(np.concatenate(tokens), out, atol=1e-6)


def test_each_leg_is_pinned_as_if_alone() -> None:
    """The legs are pinned together: a leg's frames and pins do not depend on the other leg's
    contacts, nor on how many passes the other leg needs (here the body drifts over planted feet,
    so the left leg's pin gives way at the ankle while the right foot is free or planted)."""
    n = 24
    joints = np.repeat(_pose()[None], n, axis=0)
    joints[..., 2] += 0.03 * np.arange(n)[:, None]
    both, left_only = np.ones((n, 4)), np.ones((n, 4))
    left_only[:, 2:] = 0.0
    out_both, out_left = FootPinner(1), FootPinner(1)
    a = out_both.apply(0, joints, both)
    b = out_left.apply(0, joints, left_only)
    left = list(LEGS[0])
    np.testing.assert_array_equal(a[:, left], b[:, left])
    np.testing.assert_array_equal(out_both.pins[:, 0], out_left.pins[:, 0])
    assert not np.array_equal(a[:, list(LEGS[1])], b[:, list(LEGS[1])])  # the right leg did change


def test_ankle_room_takes_the_whole_correction_where_the_leg_allows() -> None:
    rows = np.repeat(_pose()[None], 3, axis=0)
    offset = np.array([[0.0, 0.02], [0.0, -0.02], [0.02, 0.0]])
    np.testing.assert_array_equal(ankle_room(rows, 0, offset), 1.0)


def test_the_compiled_pinner_pins_as_numpy_does(both_ways: Callable, monkeypatch: pytest.MonkeyPatch) -> None:
    """feet_jit's passes (the pins and the legs' re-solve) against numpy's operations, to the bit:
    frames of a walking pose with noise, contacts on and off (heels, toes, both feet), the body
    drifting over its planted feet until pins give way at the ankle, in tokens of 1, 3 and 8
    frames for 3 characters, every output and every carried state equal."""
    from motion_env.generation import feet, feet_jit

    solves, cuts = [], []
    re_solve = feet_jit.re_solve_rows
    monkeypatch.setattr(feet_jit, "re_solve_rows", lambda *a: solves.append(1) or re_solve(*a))
    monkeypatch.setattr(feet, "ankle_room", lambda *a: cuts.append(1) or ankle_room(*a))

    rng = np.random.default_rng(0)
    rows, n = 3, 48
    joints = np.repeat(_pose()[None, None], rows, axis=0).repeat(n, axis=1)
    joints[..., 2] += 0.04 * np.arange(n)[None, :, None]
    joints += rng.normal(scale=0.01, size=joints.shape)
    contacts = (rng.random((rows, n, 4)) < 0.6).astype(np.float32)
    contacts[:, 10:20] = 1.0  # long stances: the pins creep and glide

    def run() -> list[np.ndarray]:
        pinner, parts = FootPinner(rows), []
        for start, size in zip((0, 1, 4, 12, 20, 28, 36, 44), (1, 3, 8, 8, 8, 8, 8, 4), strict=True):
            frames = slice(start, start + size)
            parts.append(pinner.apply_rows(np.arange(rows), joints[:, frames], contacts[:, frames]))
        names = ("pins", "offset", "released", "since", "glide", "shown")
        return [np.concatenate(parts, axis=1), *(getattr(pinner, k) for k in names)]

    # Most tokens run the compiled pins (a pin cut to its ankle's room runs numpy's); every
    # token's legs are re-solved compiled.
    outputs = both_ways(feet_jit, "pin_rows", run, min_calls=6)
    assert len(solves) >= 8 and cuts  # and pins were cut at the ankle (numpy's pins, compiled legs)
    for got, want in zip(outputs[True], outputs[False], strict=True):  # the frames, then every state
        np.testing.assert_array_equal(got, want)
    assert np.abs(outputs[True][0] - joints).max() > 0.01  # the feet were moved: the test means something


def test_the_compiled_leg_re_solve_gives_what_numpy_gives(both_ways: Callable) -> None:
    """feet_jit.re_solve_rows against _re_solve's numpy operations, to the bit: noisy poses, some
    with toes flexed up past ANKLE_MIN_ANGLE already, ankles moved by nothing, a little or far
    (goals beyond the leg's soft reach, shins bent past the floor): the legs and the frames
    marked bent, with the frame on each side."""
    from motion_env.generation import feet, feet_jit

    rng = np.random.default_rng(5)
    rows, n = 3, 40
    decoded = np.repeat(_pose()[None, None], rows, axis=0).repeat(n, axis=1).astype(np.float64)
    decoded += rng.normal(scale=0.02, size=decoded.shape)
    for *_, toe in LEGS:  # toes pulled up towards the shin in a third of the frames
        flexed = rng.random((rows, n)) < 0.3
        decoded[flexed, toe, 1] += 0.12
    offsets = rng.normal(scale=0.12, size=(rows, n, len(LEGS), 2))
    offsets[rng.random((rows, n, len(LEGS))) < 0.3] = 0.0

    def run() -> tuple[np.ndarray, np.ndarray]:
        out = decoded.copy()
        return out, feet._re_solve(out, decoded, offsets)

    outputs = both_ways(feet_jit, "re_solve_rows", run)
    for got, want in zip(outputs[True], outputs[False], strict=True):
        np.testing.assert_array_equal(got, want)
    floors = np.stack([_shin_foot(decoded.reshape(-1, 22, 3), leg) for leg in range(len(LEGS))], -1)
    assert (floors < ANKLE_MIN_ANGLE).any() and 0.1 < outputs[False][1].mean() < 0.9  # both kinds
