"""The physics stage: grounding, ballistic flights, smooth contacts; whole clips and the stream."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from motion_env.generation.feet import two_bone_ik
from motion_env.generation.ground import (
    FLAT_ANKLE_HEIGHT,
    PLANT_REACH,
    SWING_CLEARANCE,
    SWING_RISE,
    sole_heights,
    swing_clearance,
)
from motion_env.generation.physics import (
    GRAVITY,
    MAX_FLIGHT_FRAMES,
    MAX_HOP_FRAMES,
    RELEASE_AT_ONCE,
    RELEASE_FADE,
    SINK_TOLERANCE,
    STANCE_ACCELERATION,
    PhysicsFilter,
    _cap_flights,
    _lifting_off,
    apply_physics,
    plan_heights,
)
from motion_env.motion.mass import centre_of_mass
from motion_env.motion.skeleton import BONE_LENGTHS, FOOT_CONTACT, FPS, LEGS, PARENTS, RAW_OFFSETS

DT2 = 1.0 / FPS**2


def _same_numbers(got: np.ndarray, want: np.ndarray) -> None:
    """A compiled loop's output against the numpy operations it replaces: the same operations in
    the same order, so the same to the bit where numpy's kernels round as scalar code does. On a
    CPU with AVX-512, numpy's dispatched kernels round a few of them one last bit apart (5e-15 m at
    most here; with ``NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR"`` the bits agree)."""
    if np.asarray(want).dtype.kind in "biu":
        np.testing.assert_array_equal(got, want)
    else:
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def _standing(frames: int) -> np.ndarray:
    """A person standing still on flat feet, knees a little bent, soles on the floor: (T, 22, 3)."""
    dirs = RAW_OFFSETS.astype(np.float64)
    for thigh, shin, foot in ((4, 7, 10), (5, 8, 11)):
        dirs[thigh], dirs[shin] = (0.0, -1.0, 0.3), (0.0, -1.0, -0.3)
        dirs[foot] = (0.0, -FLAT_ANKLE_HEIGHT, np.sqrt(BONE_LENGTHS[foot] ** 2 - FLAT_ANKLE_HEIGHT**2))
    dirs[1:] /= np.linalg.norm(dirs[1:], axis=1, keepdims=True)
    pose = np.zeros((22, 3))
    for j in range(1, 22):
        pose[j] = pose[PARENTS[j]] + dirs[j] * BONE_LENGTHS[j]
    # The legs differ in length: the longer one bends more, so both soles touch the floor.
    hip, knee, ankle, toe = LEGS[0]
    new_knee, new_ankle = two_bone_ik(
        pose[[hip]], pose[[knee]], pose[[ankle]], pose[[ankle]] + [0.0, np.diff(sole_heights(pose))[0], 0.0]
    )
    pose[toe] += new_ankle[0] - pose[ankle]
    pose[knee], pose[ankle] = new_knee[0], new_ankle[0]
    pose[:, 1] -= sole_heights(pose).min()
    return np.repeat(pose[None], frames, axis=0).astype(np.float32)


def _bones(joints: np.ndarray) -> np.ndarray:
    return np.linalg.norm(joints[:, 1:] - joints[:, list(PARENTS[1:])], axis=-1)


def _left_foot_raised(rise: np.ndarray) -> np.ndarray:
    """A standing body (:func:`_standing`, one frame per entry of `rise`) with its left foot raised
    by `rise` (m), the knee re-solved: (T, 22, 3) float64."""
    joints = _standing(len(rise)).astype(np.float64)
    hip, knee, ankle, toe = LEGS[0]
    goal = joints[:, ankle] + np.asarray(rise)[:, None] * [0.0, 1.0, 0.0]
    new_knee, new_ankle = two_bone_ik(joints[:, hip], joints[:, knee], joints[:, ankle], goal)
    joints[:, toe] += new_ankle - joints[:, ankle]
    joints[:, knee], joints[:, ankle] = new_knee, new_ankle
    return joints


def _jump(frames: int = 60, take_off: int = 20, landing: int = 32, peak: float = 0.3) -> tuple:
    """A standing clip whose body rises and falls along a triangle (no free fall) between
    `take_off` and `landing`, flagged in the air there: (T, 22, 3) joints, (T, 4) contacts."""
    joints = _standing(frames)
    t = np.arange(frames)
    mid = 0.5 * (take_off + landing - 1)
    bump = np.clip(peak * (1 - np.abs(t - mid) / (mid - take_off + 1)), 0, None)
    bump[(t < take_off) | (t >= landing)] = 0.0
    joints[..., 1] += bump[:, None].astype(np.float32)
    contacts = np.ones((frames, 4), np.float32)
    contacts[take_off:landing] = 0.0
    return joints, contacts


def _streamed(joints: np.ndarray, contacts: np.ndarray, rate: int = 4) -> np.ndarray:
    stage = PhysicsFilter(1)
    return np.concatenate(
        [stage.apply(0, joints[f : f + rate], contacts[f : f + rate]) for f in range(0, len(joints), rate)]
    )


def test_a_body_standing_on_the_floor_is_left_as_it_is() -> None:
    joints = _standing(30)
    np.testing.assert_allclose(apply_physics(joints, np.ones((30, 4))), joints, atol=1e-5)


@pytest.mark.parametrize("height", [0.05, 0.3])
def test_a_floating_body_is_lowered_onto_its_planted_feet(height: float) -> None:
    joints = _standing(30)
    joints[..., 1] += height
    out = apply_physics(joints, np.ones((30, 4)))
    np.testing.assert_allclose(sole_heights(out.astype(np.float64)), 0.0, atol=2e-3)
    np.testing.assert_allclose(out - joints, np.broadcast_to([0.0, -height, 0.0], out.shape), atol=2e-3)


def test_a_shallow_sole_dip_is_taken_up_by_the_knee_not_the_body() -> None:
    # One foot jitters 1.5 cm below the floor every other frame (a decoded leg that straightens
    # and bends): the body is not raised for each dip, the grounding's knee takes it up.
    joints = _standing(40)
    _, _, ankle, toe = LEGS[0]
    joints[1::2, [ankle, toe], 1] -= SINK_TOLERANCE * 0.75
    out = apply_physics(joints, np.ones((40, 4)))
    assert np.abs(np.diff(out[:, 0, 1], n=2)).max() < 1e-3
    assert sole_heights(out.astype(np.float64)).min() > -1e-4
    # A deeper one, for a frame, raises the body (as fast as a stance can: over a few frames).
    deep = _standing(40)
    deep[20, [ankle, toe], 1] -= SINK_TOLERANCE + 0.03
    raised = (apply_physics(deep, np.ones((40, 4))) - deep)[:, 0, 1]
    assert raised.max() > 0.008 and np.abs(raised[:14]).max() < 1e-4


@pytest.mark.parametrize("planted", [True, False])
def test_nothing_stays_below_the_floor(planted: bool) -> None:
    joints = _standing(30)
    joints[..., 1] -= 0.04
    out = apply_physics(joints, np.full((30, 4), float(planted)))
    assert out[..., 1].min() > -1e-5
    assert sole_heights(out.astype(np.float64)).min() > -1e-5
    np.testing.assert_allclose(_bones(out), _bones(joints), atol=1e-5)


def test_a_jump_falls_freely_between_take_off_and_landing() -> None:
    joints, contacts = _jump()
    out = apply_physics(joints, contacts)
    com = centre_of_mass(out.astype(np.float64))[:, 1]
    accel = np.diff(com, 2)  # accel[k] is frame k + 1's
    np.testing.assert_allclose(accel[19:31], -GRAVITY * DT2, atol=1e-4)  # frames 20-31 in the air
    stance = np.r_[accel[:18], accel[32:]]  # frames 1-18 and 33-58: the feet on the floor
    assert stance.min() >= STANCE_ACCELERATION[0] * DT2 - 1e-4
    assert stance.max() <= STANCE_ACCELERATION[1] * DT2 + 1e-4
    assert com[20:32].max() > com[0] + 0.1  # it still jumps
    np.testing.assert_allclose(out[:, 0, [0, 2]], joints[:, 0, [0, 2]], atol=1e-6)  # only heights change
    np.testing.assert_allclose(_bones(out), _bones(joints), atol=1e-5)
    np.testing.assert_allclose(sole_heights(out[:12].astype(np.float64)), 0.0, atol=2e-3)


def test_a_hop_with_its_feet_still_flagged_falls_freely_where_no_foot_is_stood_on() -> None:
    # A decoder's contact channels mark slow feet, whatever their height: a small hop keeps them on.
    joints, _ = _jump(frames=40, take_off=15, landing=23, peak=0.14)
    out = apply_physics(joints, np.ones((40, 4), np.float32)).astype(np.float64)
    com = centre_of_mass(out)[:, 1]
    aloft = np.flatnonzero(sole_heights(out).min(axis=1)[1:-1] >= PLANT_REACH) + 1  # no foot to stand on
    assert len(aloft) >= 4  # it still hops
    np.testing.assert_allclose(np.diff(com, 2)[aloft - 1], -GRAVITY * DT2, atol=1e-4)


def test_feet_held_up_longer_than_a_hop_are_stood_on_not_flown() -> None:
    """Flagged feet 15 cm above the floor for 0.7 s (a decoded crouch that lifts its feet): no
    hop is that long, so the whole clip's body is lowered onto its feet instead of being launched
    into a 0.7 s flight (planned as one, it crouched 10 cm and rose 25 cm; a generated jump's knees
    folded flat on landing). The stream, which cannot see that far ahead, hops for MAX_HOP_FRAMES
    at most."""
    frames, start, stop = 60, 20, 20 + MAX_HOP_FRAMES + 6
    joints = _standing(frames)
    t = np.arange(frames)
    lift = 0.15 * np.clip(np.minimum(t - start + 1, stop - t) / 4.0, 0.0, 1.0)  # eased up and down
    joints[..., 1] += lift[:, None].astype(np.float32)
    contacts = np.ones((frames, 4), np.float32)
    out = apply_physics(joints, contacts).astype(np.float64)
    com = centre_of_mass(out)[:, 1]
    assert com.max() < centre_of_mass(joints.astype(np.float64))[:, 1].max() + 0.02  # not launched
    assert com.min() > centre_of_mass(joints.astype(np.float64))[0, 1] - 0.05  # nor dropped to the floor
    assert sole_heights(out)[start + 6 : stop - 6].min(axis=1).max() < PLANT_REACH  # stood on its feet
    # Feet dragged along all the while (a run's flagged feet, 6 cm a frame) are not stood on.
    dragged = joints.copy()
    dragged[..., 2] += 0.06 * t[:, None].astype(np.float32)
    flown = centre_of_mass(apply_physics(dragged, contacts).astype(np.float64))[:, 1]
    assert flown.max() > centre_of_mass(joints.astype(np.float64))[:, 1].max() + 0.02
    # A short lift (a hop the flags keep) still falls freely.
    short = _standing(40)
    short[15 : 15 + MAX_HOP_FRAMES - 2, :, 1] += 0.1
    hop = centre_of_mass(apply_physics(short, np.ones((40, 4), np.float32)).astype(np.float64))[:, 1]
    assert (np.abs(np.diff(hop, 2) + GRAVITY * DT2) < 1e-4).sum() >= 2


def test_a_flagged_foot_let_go_of_the_floor_rises_gradually() -> None:
    # One foot, still flagged, rises 1.5 cm a frame while the body stands on the other: pulled
    # onto the floor up to PLANT_REACH, then let go. It rose by the whole pull at once (a 6 cm
    # step; a streamed jump's knee at 72 m/s^2); the pull now fades by RELEASE_FADE a frame.
    frames = 40
    joints = _left_foot_raised(0.015 * np.clip(np.arange(frames) - 10, 0, 8))
    flags = np.ones((frames, 4), np.float32)
    for run in (apply_physics, _streamed):
        left = sole_heights(run(joints.astype(np.float32), flags).astype(np.float64))[:, 0]
        assert np.abs(np.diff(left)).max() < 0.045
        assert left[-1] > 0.11  # and it rises all the way
    with pytest.MonkeyPatch.context() as m:
        m.setattr("motion_env.generation.physics.RELEASE_FADE", 0.0)
        left = sole_heights(apply_physics(joints.astype(np.float32), flags).astype(np.float64))[:, 0]
    assert np.abs(np.diff(left)).max() > 0.055
    # A contact that ends lets a foot nearly on the floor go at once (a toe-off: its last frame
    # stood on the floor is pulled down by 1.5 cm) ...
    ended = flags.copy()
    ended[13:, :2] = 0.0
    at_once = apply_physics(joints.astype(np.float32), ended)
    with pytest.MonkeyPatch.context() as m:
        m.setattr("motion_env.generation.physics.RELEASE_FADE", 0.0)
        np.testing.assert_array_equal(at_once, apply_physics(joints.astype(np.float32), ended))
    # ... and fades the pull of one held down farther (3 cm: the body raised above a foot that
    # hovered while flagged), as it does for a foot still flagged.
    ended[13:15, :2] = 1.0
    left = sole_heights(apply_physics(joints.astype(np.float32), ended).astype(np.float64))[:, 0]
    assert np.abs(np.diff(left)).max() < 0.04
    with pytest.MonkeyPatch.context() as m:
        m.setattr("motion_env.generation.physics.RELEASE_AT_ONCE", 1.0)
        left = sole_heights(apply_physics(joints.astype(np.float32), ended).astype(np.float64))[:, 0]
    assert np.abs(np.diff(left)).max() > 0.045
    assert 0.0 < RELEASE_FADE < 1.0 and 0.0 < RELEASE_AT_ONCE < PLANT_REACH


def test_a_foot_the_plan_stands_on_the_floor_is_stood_on_it() -> None:
    # One foot, flagged throughout, hovers just under PLANT_REACH above the floor (4.5 cm, 4.8 cm
    # every third frame). Grounding it lowers the knee and the centre of mass, so the body is
    # raised a few millimetres to keep its planned height; the grounding used to decide again on
    # that body, found the sole over the reach on the higher frames and left the foot 5 cm up for
    # them (a jump's knee at 64-71 m/s^2). One decision, made on the plan, stands it on the floor.
    frames = 30
    rise = np.full(frames, 0.045)
    rise[::3] += 0.003
    joints = _left_foot_raised(rise)
    flags = np.ones((frames, 4), np.float32)
    for run in (apply_physics, _streamed):
        soles = sole_heights(run(joints.astype(np.float32), flags).astype(np.float64))
        np.testing.assert_allclose(soles, 0.0, atol=1e-3)


def test_a_contacts_last_frame_is_not_stood_on() -> None:
    planted = np.array([[1, 1, 1, 0, 1, 0, 0, 1]], bool)[..., None]
    expected = np.array([[1, 1, 0, 0, 0, 0, 0, 1]], bool)[..., None]  # the call's last frame: unseen next
    np.testing.assert_array_equal(_lifting_off(planted), expected)

    # A toe-off: the left foot rises 2 cm on its last flagged frame, then 5 cm, free.
    joints, contacts = _standing(30), np.ones((30, 4), np.float32)
    for f, rise in ((15, 0.02), *((f, 0.05) for f in range(16, 30))):
        joints[f, [7, 10], 1] += rise
    contacts[16:, :2] = 0.0
    soles = sole_heights(apply_physics(joints, contacts).astype(np.float64))
    np.testing.assert_allclose(soles[:15], 0.0, atol=2e-3)  # stood on the floor
    assert soles[15, 0] == pytest.approx(0.02, abs=2e-3)  # lifting off, not pushed down for a frame


def test_plan_heights_keeps_what_obeys_gravity() -> None:
    t = np.arange(12)
    parabola = 1.0 + 0.2 * t * DT2 * FPS - 0.5 * GRAVITY * (t / FPS) ** 2
    np.testing.assert_allclose(plan_heights(parabola, np.ones(12, bool)), parabola, atol=1e-9)
    slow = 1.0 + 0.01 * np.sin(t / 3.0)  # gentle enough for a foot on the floor
    np.testing.assert_allclose(plan_heights(slow, np.zeros(12, bool)), slow, atol=1e-9)


def test_a_moving_free_foot_clears_the_floor_unless_it_lands() -> None:
    speed = np.array([0.0, 0.4, 1.0, 1.0, 1.0, 1.0])
    free = np.array([5, 5, 1, 2, 5, 5])
    descent = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.02])  # the last one comes down to land
    expected = [0.0, 0.5 * SWING_CLEARANCE, SWING_RISE, 2 * SWING_RISE, SWING_CLEARANCE, 0.0]
    np.testing.assert_allclose(swing_clearance(speed, free, descent), expected)


def test_the_stream_given_the_whole_clip_at_once_is_apply_physics() -> None:
    joints, contacts = _jump()
    np.testing.assert_array_equal(
        PhysicsFilter(1).apply(0, joints, contacts), apply_physics(joints, contacts)
    )


def test_the_stream_never_changes_what_it_put_out() -> None:
    joints, contacts = _jump(frames=64)
    streamed = _streamed(joints, contacts)
    other_joints, other_contacts = joints.copy(), contacts.copy()
    other_joints[40:, :, 1] += 0.2  # the future changes: the body floats, then jumps again
    other_contacts[48:56] = 0.0
    np.testing.assert_array_equal(_streamed(other_joints, other_contacts)[:40], streamed[:40])
    np.testing.assert_allclose(_bones(streamed), _bones(joints), atol=1e-5)
    assert np.isfinite(_streamed(joints, contacts, rate=1)).all()


def test_the_stream_falls_freely_until_it_lands() -> None:
    """Tokens of 4 frames: the take-off's speed is chosen before the flight is seen whole (and
    this take-off, from standing still to rising in one frame, leaves the legs little time), so
    the body lands before the flags say; until then it falls freely, never through the floor."""
    joints, contacts = _jump()
    streamed = _streamed(joints, contacts).astype(np.float64)
    accel = np.diff(centre_of_mass(streamed)[:, 1], 2)  # accel[k] is frame k + 1's
    touch = 20 + int(np.argmax(sole_heights(streamed[20:]).min(axis=1) < 1e-3))  # the landing
    assert touch >= 23
    np.testing.assert_allclose(accel[19 : touch - 2], -GRAVITY * DT2, atol=1e-4)  # frames 20 to touch - 2
    assert streamed[..., 1].min() > -1e-5
    assert accel.max() <= STANCE_ACCELERATION[1] * DT2 + 1e-4


def test_rows_are_independent_and_reset_forgets() -> None:
    (a, ca), (b, cb) = _jump(), _jump(take_off=10, landing=18, peak=0.1)
    stage = PhysicsFilter(2)
    both = np.concatenate(
        [
            stage.apply_rows(
                np.array([0, 1]), np.stack([a, b])[:, f : f + 4], np.stack([ca, cb])[:, f : f + 4]
            )
            for f in range(0, 60, 4)
        ],
        axis=1,
    )
    # Rows are planned in one batched solve: the same heights as alone, within float rounding.
    np.testing.assert_allclose(both[0], _streamed(a, ca), rtol=0.0, atol=1e-9)
    np.testing.assert_allclose(both[1], _streamed(b, cb), rtol=0.0, atol=1e-9)
    stage.reset(1)
    np.testing.assert_array_equal(stage.apply(1, b, cb), apply_physics(b, cb))


def test_outputs_are_finite_for_any_input() -> None:
    rng = np.random.default_rng(0)
    joints = _standing(41) + rng.normal(0.0, 0.05, (41, 22, 3)).astype(np.float32)
    contacts = rng.random((41, 4)).astype(np.float32)
    out = apply_physics(joints, contacts)
    assert out.shape == joints.shape and out.dtype == np.float32 and np.isfinite(out).all()
    assert np.isfinite(_streamed(joints, contacts, rate=3)).all()
    assert PhysicsFilter(1).apply(0, joints[:0], contacts[:0]).shape == (0, 22, 3)


def test_real_motion_moves_little(humanml3d_sample) -> None:
    joints, features = humanml3d_sample
    n = min(len(joints), len(features))
    out = apply_physics(joints[:n], features[:n, FOOT_CONTACT])
    np.testing.assert_allclose(out[:, 0, [0, 2]], joints[:n, 0, [0, 2]], atol=1e-6)
    assert np.abs(out - joints[:n])[:, 0, 1].max() < 0.05  # the pelvis
    assert np.abs(out - joints[:n]).mean() < 0.01
    np.testing.assert_allclose(_bones(out), _bones(joints[:n]), atol=1e-4)


def test_long_plans_are_solved_banded_to_the_same_heights() -> None:
    """Whole clips are planned in the heights (banded, O(m) a step); the stream's short plans over
    the second differences (dense): both find the one solution of the same problem, and a clip of
    400 frames takes milliseconds (the dense solve took a minute)."""
    import time

    from motion_env.generation import height_plan

    rng = np.random.default_rng(0)
    for m, h in ((40, 0), (90, 3)):
        raw = 0.9 + 0.05 * np.sin(np.arange(m) / 3) + 0.01 * rng.standard_normal(m)  # bounds bite
        flight = np.zeros(m, dtype=bool)
        flight[m // 3 : m // 3 + 6] = True
        past, past_raw = (raw[:h] + 0.002, raw[:h]) if h else (None, None)
        banded = plan_heights(raw[h:], flight, past, past_raw)
        saved = height_plan._DENSE_FRAMES
        try:
            height_plan._DENSE_FRAMES = 10**6
            dense = plan_heights(raw[h:], flight, past, past_raw)
        finally:
            height_plan._DENSE_FRAMES = saved
        np.testing.assert_allclose(banded, dense, atol=1e-9)
    m = 400
    raw = 0.9 + 0.05 * np.sin(np.arange(m) / 3) + 0.002 * rng.standard_normal(m)
    flight = np.zeros(m, dtype=bool)
    flight[100:110] = flight[250:262] = True
    t0 = time.perf_counter()
    heights = plan_heights(raw, flight)
    assert time.perf_counter() - t0 < 2.0
    acc = np.diff(heights, 2) * FPS**2
    assert np.all(acc[~flight[1:-1]] >= STANCE_ACCELERATION[0] - 1e-6)
    assert np.all(acc[~flight[1:-1]] <= STANCE_ACCELERATION[1] + 1e-6)
    np.testing.assert_allclose(acc[flight[1:-1]], -GRAVITY, atol=1e-6)


def test_a_foot_dragged_while_flagged_is_lifted_but_a_landing_stays_planted() -> None:
    """A decoder can flag a foot planted while it moves 8 cm a frame for many frames: on the floor
    it skated. From its second such frame it is a free foot, clear of the floor, and let down
    gently where it stops; a foot that moves so for one frame only (a fast landing) is stood on."""
    n = 30
    joints = _standing(n).astype(np.float64)
    hip, knee, ankle, toe = LEGS[0]
    drag = np.zeros(n)
    drag[10:20] = 0.08 * np.arange(1, 11)  # the left foot slides 8 cm a frame, frames 10-19
    drag[20:] = drag[19]
    for j in (knee, ankle, toe):
        joints[:, j, 2] += drag
    contacts = np.ones((n, 4), np.float32)
    out = apply_physics(joints.astype(np.float32), contacts).astype(np.float64)
    soles = sole_heights(out)
    assert soles[12:20, 0].min() > 0.01  # dragged: lifted off the floor
    np.testing.assert_allclose(soles[:10, 0], 0.0, atol=2e-3)  # planted before
    np.testing.assert_allclose(soles[23:, 0], 0.0, atol=2e-3)  # and after (still again),
    assert -np.diff(soles[18:24, 0]).max() <= SWING_RISE + 1e-6  # let down as it was lifted
    np.testing.assert_allclose(soles[:, 1], 0.0, atol=2e-3)  # the other foot stands
    one = joints.copy()
    for j in (knee, ankle, toe):
        one[:, j, 2] = joints[:, j, 2] - drag + np.where(np.arange(n) >= 10, 0.08, 0.0)
    np.testing.assert_allclose(
        sole_heights(apply_physics(one.astype(np.float32), contacts).astype(np.float64))[:, 0], 0.0, atol=2e-3
    )


def _capped_frame_by_frame(flight: np.ndarray, airborne: int) -> np.ndarray:
    """MAX_FLIGHT_FRAMES applied by walking the frames: a stretch in the air longer than it (the
    first one counting the `airborne` frames before it) is no flight."""
    out, count, start = flight.copy(), airborne, 0
    for t in range(len(flight) + 1):
        if t < len(flight) and flight[t]:
            count += 1
            continue
        if count > MAX_FLIGHT_FRAMES:
            out[start:t] = False
        count, start = 0, t + 1
    return out


def test_flights_are_capped_as_frame_by_frame() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 4, 17, 40):
        flight = rng.random((50, n)) < rng.uniform(0.3, 0.98, (50, 1))
        flight[:5] = True  # all in the air, with and without a long past in the air
        airborne = rng.integers(0, 2 * MAX_FLIGHT_FRAMES, 50)
        want = np.stack([_capped_frame_by_frame(f, int(a)) for f, a in zip(flight, airborne)])
        np.testing.assert_array_equal(_cap_flights(flight, airborne), want)
    assert not _cap_flights(np.ones((1, MAX_FLIGHT_FRAMES + 1), bool), np.zeros(1, np.int64)).any()
    assert _cap_flights(np.ones((1, MAX_FLIGHT_FRAMES), bool), np.zeros(1, np.int64)).all()


def test_the_flat_ankle_height_is_learnt_from_many_frames_not_a_first_token() -> None:
    """A stream's first token with its feet flagged flat but pitched (the ankle 5 cm over the toe
    joint instead of about 9) barely moves the height the soles are measured with; a long run of
    flat frames at another height is learnt (FLAT_ANKLE_PRIOR frames of the usual one to start)."""
    from motion_env.generation.physics import FLAT_ANKLE_PRIOR

    def token(frames: int, ankle_over_toe: float) -> np.ndarray:
        joints = np.zeros((1, frames, 22, 3))
        for _, _, ankle, _ in LEGS:
            joints[..., ankle, 1] = ankle_over_toe
        return joints

    f = PhysicsFilter(1)
    first = f._flat_ankle(np.array([0]), token(4, 0.05), np.ones((1, 4, 4), bool))[0]  # one token
    assert abs(first - FLAT_ANKLE_HEIGHT) < 0.4 * abs(0.05 - FLAT_ANKLE_HEIGHT)  # nearer the usual than 5 cm
    many = 10 * FLAT_ANKLE_PRIOR
    later = f._flat_ankle(np.array([0]), token(many, 0.10), np.ones((1, many, 4), bool))[0]
    assert abs(later - 0.10) < 0.1 * abs(0.10 - FLAT_ANKLE_HEIGHT) + 0.002


def test_the_compiled_loops_give_what_numpy_gives(monkeypatch: pytest.MonkeyPatch) -> None:
    """physics_jit's loops against the numpy operations, to the bit: seven characters (a jump, a
    drifting body with noisy contacts whose feet get dragged, a standing one floating up, bodies
    held up without contacts for longer than MAX_FLIGHT_FRAMES, for as long, and high enough to
    fall for longer, a foot flagged in the air while the other stands unflagged), streamed in
    tokens of 1-8 frames, then as whole clips (numpy's sums of 8 and more frames, and of more than
    128); every output frame and every carried state equal."""
    from motion_env.generation import physics, physics_jit
    from motion_env.models import jit_cache

    rng = np.random.default_rng(1)
    jump, jump_contacts = _jump()
    drift = _standing(60) + rng.normal(0.0, 0.02, (60, 22, 3)).astype(np.float32)
    drift[..., 2] += 0.05 * np.arange(60, dtype=np.float32)[:, None]  # flagged feet dragged along
    drift_contacts = (rng.random((60, 4)) < 0.7).astype(np.float32)
    floating = _standing(60)
    floating[..., 1] += np.linspace(0.0, 0.1, 60, dtype=np.float32)[:, None]
    floating_contacts = np.ones((60, 4), np.float32)
    floating_contacts[45:] = 0.0  # its feet free at the end: the counts carry on
    hovers, hover_contacts = [], []  # held up, no contact flagged: past the cap, at it, and high
    for lift, frames in ((0.3, MAX_FLIGHT_FRAMES + 6), (0.3, MAX_FLIGHT_FRAMES), (5.0, 30)):
        hover, flags = _standing(60), np.ones((60, 4), np.float32)
        hover[10 : 10 + frames, :, 1] += lift
        flags[10 : 10 + frames] = 0.0
        hovers.append(hover)
        hover_contacts.append(flags)
    rise = np.zeros(60)
    rise[20:32] = 0.12
    raised = _left_foot_raised(rise).astype(np.float32)  # flagged up in the air, the other not
    raised_contacts = np.ones((60, 4), np.float32)
    raised_contacts[20:32, 2:] = 0.0
    joints = np.stack([jump, drift, floating, *hovers, raised])
    contacts = np.stack([jump_contacts, drift_contacts, floating_contacts, *hover_contacts, raised_contacts])
    clip, clip_contacts = np.concatenate(joints), np.concatenate(contacts)  # 420 frames
    calls = []
    for name in physics_jit.__all__:
        loop = getattr(physics_jit, name)
        counted = lambda *a, _loop=loop, _name=name: calls.append(_name) or _loop(*a)  # noqa: E731
        monkeypatch.setattr(physics_jit, name, counted)
    capped = []  # flights the numpy path cut at MAX_FLIGHT_FRAMES, carried over from a token or not

    def cap(flight: np.ndarray, airborne: np.ndarray, longest: int = MAX_FLIGHT_FRAMES) -> np.ndarray:
        out = _cap_flights(flight, airborne, longest)
        capped.append(bool((flight & ~out).any()) if longest == MAX_FLIGHT_FRAMES else False)
        return out

    monkeypatch.setattr(physics, "_cap_flights", cap)
    outputs, states = {}, {}
    for compiled in (True, False):
        monkeypatch.setattr(jit_cache, "_enabled", compiled)
        stage, parts, start = PhysicsFilter(len(joints)), [], 0
        for size in (1, 3, 4, 6, 4, 2, 4, 4, 8, 4, 4, 4, 4, 4, 4):
            frames = slice(start, start + size)
            parts.append(stage.apply_rows(np.arange(len(joints)), joints[:, frames], contacts[:, frames]))
            start += size
        outputs[compiled] = [np.concatenate(parts, axis=1)]
        state = ("pull", "floating", "free", "lift", "past", "flat", "feet", "soles", "moving", "airborne")
        states[compiled] = [getattr(stage, k).copy() for k in state]
        for n in (9, 60, 420):  # whole clips
            whole = PhysicsFilter(1)
            outputs[compiled].append(whole.apply(0, clip[:n], clip_contacts[:n]))
            states[compiled].append(whole.flat.copy())
    assert set(calls) == set(physics_jit.__all__)  # every compiled loop ran
    for got, want in zip(outputs[True], outputs[False], strict=True):
        _same_numbers(got, want)
    for got, want in zip(states[True], states[False], strict=True):
        _same_numbers(got, want)
    assert any(capped)  # the case is not trivial: a flight past the cap


@pytest.mark.parametrize("with_pull", [True, False])
def test_the_compiled_placement_gives_what_numpy_gives(both_ways: Callable, with_pull: bool) -> None:
    """ground_jit.place_frames against place_body's numpy passes, to the bit: standing, jumping and
    noisy bodies asked to stand, float or sink (planted, free and pulled feet; straight legs with
    no bend plane, shins folded back along the thighs)."""
    from motion_env.generation import ground, ground_jit

    rng = np.random.default_rng(3)
    jump, _ = _jump()
    noisy = _standing(60) + rng.normal(0.0, 0.03, (60, 22, 3))
    joints = np.concatenate([_standing(20), jump, noisy]).astype(np.float64)
    straight = joints[:4].copy()  # straight legs, toes pointing down: no bend plane, no hint
    for hip, knee, ankle, toe in LEGS:
        straight[:, knee] = straight[:, hip] + [0.1, -0.4, 0.0]
        straight[:, ankle] = straight[:, hip] + [0.2, -0.8, 0.0]
        straight[:, toe] = straight[:, ankle] + [0.0, -0.05, 0.0]
    folded = joints[:4].copy()  # shins folded back up along the thighs
    for hip, knee, ankle, _ in LEGS:
        folded[:, ankle] = folded[:, hip] + 0.5 * (folded[:, knee] - folded[:, hip])
    joints = np.concatenate([joints, straight, folded])
    n = len(joints)
    heights = centre_of_mass(joints)[:, 1] + rng.uniform(-0.15, 0.15, n)
    down = rng.random((n, 2)) < 0.6
    clearance = rng.uniform(0.0, SWING_CLEARANCE, (n, 2))
    flat_ankle = rng.uniform(0.05, 0.11, n)
    pull = np.where(rng.random((n, 2)) < 0.5, rng.uniform(0.0, 0.05, (n, 2)), 0.0) if with_pull else None
    outputs = both_ways(
        ground_jit,
        "place_frames",
        lambda: ground.place_body(joints, heights, down, clearance, flat_ankle, pull),
    )
    moved = np.abs(outputs[False] - joints).max(axis=(1, 2))
    assert (moved > 1e-3).mean() > 0.5  # the case is not trivial: most frames were placed
    _same_numbers(outputs[True], outputs[False])


def test_the_compiled_sum_adds_as_numpy_does() -> None:
    """jit_math.pairwise_sum against numpy's sum, to the bit, at every length to 300 and beyond
    (numpy adds in eight running sums from 8 numbers, halves the line above 128), on numbers of
    many magnitudes, where the order of the sums shows."""
    from motion_env.models.jit_math import pairwise_sum

    rng = np.random.default_rng(0)
    for n in [*range(300), 513, 1000, 4001]:
        line = rng.normal(size=n) * 10.0 ** rng.integers(-6, 6, size=n)
        assert pairwise_sum(line, n) == line.sum(), n
        assert pairwise_sum(line, n // 2) == line[: n // 2].sum(), n
