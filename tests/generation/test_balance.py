"""The balance (generation/balance.py): the root path shifted so that the floor's push passes
through the centre of mass, over whole clips and, causally, token by token for the stream."""

from __future__ import annotations

import numpy as np

from motion_env.generation.balance import BALANCE_WEIGHT, StreamBalance, _pressure_point, balance_shift
from motion_env.generation.height_plan import GRAVITY
from motion_env.motion.mass import COM_WEIGHTS, centre_of_mass
from motion_env.motion.skeleton import FPS, LEGS


def _body(frames: int, lean: float) -> np.ndarray:
    """A rigid stick body standing on its left foot, its centre of mass `lean` metres ahead of
    the foot (+z), not accelerating: (T, 22, 3)."""
    rng = np.random.default_rng(0)
    pose = rng.normal(size=(22, 3)) * 0.05 + [0.0, 0.9, 0.0]
    feet = [j for leg in LEGS for j in leg[2:]]
    for _, _, ankle, toe in LEGS:  # both feet's middles at the origin
        pose[ankle], pose[toe] = [0.0, 0.08, 0.04], [0.0, 0.0, -0.04]
    off = centre_of_mass(pose)[[0, 2]] - [0.0, lean]
    rest = [j for j in range(22) if j not in feet]
    pose[rest] -= [off[0], 0.0, off[1]] / np.float64(sum(COM_WEIGHTS[rest]))
    return np.repeat(pose[None], frames, axis=0)


def _miss(joints: np.ndarray, shift: np.ndarray, stance: np.ndarray) -> np.ndarray:
    """How far the horizontal (z) acceleration of the centre of mass, with the body moved by
    `shift` and the standing foot left where it is, is from any push the foot can give: one
    through the centre of mass from a point between its heel (ankle) and its toe."""
    c = centre_of_mass(joints)
    z = c[:, 2] + shift[:, 1]
    acc = (z[2:] - 2 * z[1:-1] + z[:-2]) * FPS**2
    sole = joints[:, [LEGS[0][2], LEGS[0][3]], 2]
    k = GRAVITY / c[:, 1]
    low, high = k * (z - sole.max(axis=1)), k * (z - sole.min(axis=1))
    return np.maximum(np.maximum(low[1:-1] - acc, acc - high[1:-1]), 0.0)[stance]


def _run(frames: int = 60, speed: float = 3.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A rigid body carried forward (+z) at a constant `speed` (m/s), standing for 6 frames on a
    foot put down under the middle of each stance, then 3 frames in the air, as a runner does:
    (T, 22, 3) joints, (T, 4) contacts, (T,) bool stance."""
    t = np.arange(frames)
    body = _body(frames, lean=0.0)
    body[..., 2] += (speed / FPS * t)[:, None]
    stance = (t % 9) < 6
    contacts = np.zeros((frames, 4))
    contacts[stance, :2] = 1.0
    _, _, ankle, toe = LEGS[0]
    middle = t - t % 9 + 2.5  # each stance's middle frame
    for j, dz in ((ankle, 0.04), (toe, -0.04)):
        body[:, j, 2] = speed / FPS * middle + dz  # the planted foot stays under the stance's middle
        body[~stance, j, 1] += 0.2  # lifted in the air
    return body, contacts, stance


def test_a_run_at_constant_speed_is_moved_so_the_push_passes_through_it() -> None:
    joints, contacts, stance = _run()
    shift = balance_shift(joints, contacts, np.array([0]))
    assert shift[0].tolist() == [0.0, 0.0]
    frames = np.flatnonzero(stance[1:-1]) + 1
    # The foot stays where it was put down while the body moves by the shift.
    before = _miss(joints, np.zeros_like(shift), frames - 1)
    after = _miss(joints, shift, frames - 1)
    assert after.mean() < 0.7 * before.mean()
    assert np.abs(shift[:, 0]).max() < 1e-9  # nothing asks for a sideways move
    assert np.abs(shift[:, 1]).max() < 0.1


def test_waypoint_frames_keep_their_place_and_a_balanced_body_is_left_alone() -> None:
    frames = 60
    contacts = np.ones((frames, 4))
    upright = _body(frames, lean=0.0)
    assert np.abs(balance_shift(upright, contacts, np.array([0]))).max() < 1e-6
    shift = balance_shift(_body(frames, lean=0.08), contacts, np.array([0, 20, 40]))
    np.testing.assert_array_equal(shift[[0, 20, 40]], 0.0)
    assert np.abs(shift).max() > 1e-3
    # In flight (no contact) the centre of mass keeps its horizontal speed: a body that jerks
    # forward and back in the air is moved against it.
    flying = _body(frames, lean=0.0)
    flying[:, :, 2] += 0.01 * np.sin(np.arange(frames) / 1.0)[:, None]  # 4 m/s^2 to and fro
    free = balance_shift(flying, np.zeros((frames, 4)), np.array([0]))
    z = centre_of_mass(flying)[:, 2]
    before = np.abs(z[2:] - 2 * z[1:-1] + z[:-2]).mean()
    z = z + free[:, 1]
    assert np.abs(z[2:] - 2 * z[1:-1] + z[:-2]).mean() < 0.5 * before
    assert BALANCE_WEIGHT > 0


def _standing_apart(frames: int, com_x: float) -> np.ndarray:
    """A still stick body on both feet 0.3 m apart (left at x = -0.15, right at x = +0.15), its
    centre of mass at x = `com_x`, z = 0: (T, 22, 3)."""
    pose = _body(1, lean=0.0)[0]
    feet = [j for leg in LEGS for j in leg[2:]]
    for side, (_, _, ankle, toe) in zip((-0.15, 0.15), LEGS, strict=True):
        pose[[ankle, toe], 0] = side
    rest = [j for j in range(22) if j not in feet]
    off = centre_of_mass(pose)[[0, 2]] - [com_x, 0.0]
    pose[rest] -= [off[0], 0.0, off[1]] / np.float64(sum(COM_WEIGHTS[rest]))
    return np.repeat(pose[None], frames, axis=0)


def test_the_push_may_start_anywhere_under_the_feet() -> None:
    # Standing on both feet, the floor can push from any point between them: a still body whose
    # centre of mass is between its feet (over neither foot's middle) needs no shift, one whose
    # centre of mass is outside them is moved back towards them.
    frames, contacts = 40, np.ones((40, 4))
    between = balance_shift(_standing_apart(frames, com_x=0.1), contacts, np.array([0]))
    assert np.abs(between).max() < 1e-6
    outside = balance_shift(_standing_apart(frames, com_x=0.25), contacts, np.array([0]))
    assert np.median(outside[1:, 0]) < -1e-3  # towards the feet (-x), the first frame held
    assert np.abs(_streamed(_standing_apart(frames, com_x=0.1), contacts)).max() < 1e-6


def test_the_pressure_point_is_the_nearest_point_of_the_support() -> None:
    square = np.array([[0.0, 0.0], [0.0, 0.2], [0.1, 0.0], [0.1, 0.2]])  # two feet side by side
    wanted = np.array([[0.05, 0.1], [0.3, 0.1], [0.05, -0.1], [0.2, 0.3]])
    both = np.ones((4, 4), bool)
    np.testing.assert_allclose(
        _pressure_point(wanted, np.repeat(square[None], 4, 0), both),
        [[0.05, 0.1], [0.1, 0.1], [0.05, 0.0], [0.1, 0.2]],
    )
    left_only = np.array([[True, True, False, False]] * 4)  # a line: the left foot, heel to toe
    np.testing.assert_allclose(
        _pressure_point(wanted, np.repeat(square[None], 4, 0), left_only),
        [[0.0, 0.1], [0.0, 0.1], [0.0, 0.0], [0.0, 0.2]],
    )


def _streamed(
    joints: np.ndarray, contacts: np.ndarray, anchors: tuple[int, ...] = (), rate: int = 4
) -> np.ndarray:
    """StreamBalance's shift of one character, fed `rate` frames at a time: (T, 2)."""
    balance = StreamBalance(1)
    out = []
    for f in range(0, len(joints), rate):
        ahead = np.array([a - f for a in anchors if a >= f], np.int64)
        out.append(
            balance.shift_rows(
                np.array([0]), joints[None, f : f + rate], contacts[None, f : f + rate], [ahead]
            )[0]
        )
    return np.concatenate(out)


def test_the_stream_balances_token_by_token_without_running_away() -> None:
    # Causal: each token's shift from the frames emitted and its own, none after. It makes up
    # less than the whole clip's (which sees each stance's end) but still most of the miss, and
    # the shift does not grow over a long run (a lean left alone grows in stance).
    joints, contacts, stance = _run(frames=240)
    shift = _streamed(joints, contacts)
    assert shift[0].tolist() == [0.0, 0.0]
    frames = np.flatnonzero(stance[1:-1]) + 1
    before = _miss(joints, np.zeros_like(shift), frames - 1)
    assert np.abs(shift[:, 0]).max() < 1e-9
    assert np.abs(shift[:, 1]).max() < 0.1
    assert np.abs(shift[120:, 1]).max() < 1.5 * np.abs(shift[:120, 1]).max()
    # A token's first frame continues the last one emitted: no jump between tokens, no step
    # larger than the whole clip's (whose shift turns at each take-off too).
    whole = balance_shift(joints, contacts, np.array([0]))
    assert np.abs(np.diff(shift[:, 1])).max() < 1.2 * np.abs(np.diff(whole[:, 1])).max()
    assert _miss(joints, shift, frames - 1).mean() < 0.3 * before.mean()


def test_the_stream_keeps_waypoint_frames_in_place_and_leaves_a_held_row_alone() -> None:
    joints, contacts, _ = _run(frames=60)
    shift = _streamed(joints, contacts, anchors=(13, 30, 47))
    np.testing.assert_array_equal(shift[[0, 13, 30, 47]], 0.0)
    assert np.abs(shift).max() > 1e-3
    balance = StreamBalance(2)
    both = np.stack([joints[:4], joints[:4]])
    out = balance.shift_rows(
        np.array([0, 1]),
        both,
        np.stack([contacts[:4]] * 2),
        [np.zeros(0, np.int64)] * 2,
        np.array([False, True]),
    )
    assert np.abs(out[1]).max() == 0.0 and np.abs(out[0]).max() > 0.0
    balance.reset(0)
    again = balance.shift_rows(np.array([0]), joints[None, :4], contacts[None, :4], [np.zeros(0, np.int64)])
    np.testing.assert_array_equal(again[0], out[0])  # a character started again starts as new


def test_the_compiled_push_gives_what_numpy_gives(both_ways) -> None:
    """balance_jit.wanted_push against _wanted_push's numpy operations, to the bit: random feet
    with every subset bearing weight (none, one point, a line, a triangle, all four), points on a
    line and on one spot, wanted points inside and outside, flight (k = 0) and NaN (a stream's
    first token reads frames not emitted yet)."""
    from motion_env.generation import balance, balance_jit

    rng = np.random.default_rng(12)
    m = 400
    c = rng.normal(0.0, 0.3, (m, 3)) + [0.0, 0.9, 0.0]
    accel = rng.normal(0.0, 3.0, (m, 3))
    k = np.where(rng.random(m) < 0.8, rng.uniform(5.0, 40.0, m), 0.0)
    points = rng.normal(0.0, 0.15, (m, 4, 2))
    points[:40, 1] = points[:40, 0] + [0.1, 0.0]  # toes beside the ankle: on a line
    points[:40, 2] = points[:40, 0] + [0.2, 0.0]
    points[40:60] = points[40:60, :1]  # every point on one spot
    bearing = rng.random((m, 4)) < 0.5
    c[60:70, 0] = np.nan
    accel[70:75] = np.nan
    k[75:80] = np.nan
    run = lambda: balance._wanted_push(c, accel, k, points, bearing)  # noqa: E731
    outputs = both_ways(balance_jit, "wanted_push", run)
    np.testing.assert_array_equal(outputs[True], outputs[False])  # NaN where numpy gives NaN
    assert np.isfinite(outputs[True][80:]).all() and (outputs[True][80:] != 0).any()
    batched = both_ways(balance_jit, "wanted_push", lambda: balance._wanted_push(
        c[:80].reshape(4, 20, 3), accel[:80].reshape(4, 20, 3), k[:80].reshape(4, 20),
        points[:80].reshape(4, 20, 4, 2), bearing[:80].reshape(4, 20, 4),
    ))  # fmt: skip
    np.testing.assert_array_equal(batched[True], batched[False])
    assert batched[True].shape == (4, 20, 2)


def test_the_compiled_stream_balance_gives_what_numpy_gives(both_ways) -> None:
    """balance_jit.stream_equations against StreamBalance's numpy operations, to the bit: runs
    with noise, random contacts (none, some, all) and flights, a crouch, streamed for 3 and for 6 characters
    at once (banded solves one by one, and the batched dense one), first tokens, a restart, anchors
    ahead and in the token, a held row; every shift and every carried state equal."""
    from motion_env.generation import balance_jit

    rng = np.random.default_rng(4)
    runs = [_run(frames=48, speed=s) for s in (1.0, 2.5, 4.0, 3.0, 2.0, 5.0)]
    joints = np.stack([r[0] for r in runs]) + rng.normal(0.0, 0.01, (6, 48, 22, 3))
    contacts = np.stack([r[1] for r in runs])
    contacts[3:] = (rng.random((3, 48, 4)) < 0.5).astype(np.float64)
    joints[2, 20:, :, 1] -= 0.7  # a crouch: the centre of mass below the stiffness's floor height

    def run(count: int) -> list[np.ndarray]:
        balance, out = StreamBalance(count), []
        for start in range(0, 48, 4):
            if start == 24:
                balance.reset(1)
            anchors = [
                np.array([2, 9]) if (start // 4 + r) % 3 == 0 else np.zeros(0, np.int64) for r in range(count)
            ]
            held = np.arange(count) == (start // 4) % count
            token = slice(start, start + 4)
            out.append(
                balance.shift_rows(
                    np.arange(count), joints[:count, token], contacts[:count, token], anchors, held
                )
            )
        return [np.concatenate(out, axis=1), balance._shift, balance._com, balance._points, balance._bearing]

    for count in (3, 6):
        outputs = both_ways(balance_jit, "stream_equations", lambda count=count: run(count), min_calls=12)
        for got, want in zip(outputs[True], outputs[False], strict=True):
            np.testing.assert_array_equal(got, want)
        assert np.abs(outputs[True][0]).max() > 1e-3  # the bodies were moved: the test means something
