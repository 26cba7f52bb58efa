"""The stream's batched shortcuts give the numbers of the row-by-row code they replace.

Batched height plans (:func:`plan_heights` of many characters), the next token's path features of a batch
(:func:`first_token_path_features`), detours sent to many characters at once
(:meth:`MotionStream.set_goals`) and a single character's next token worked out between tokens.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.generation.generator import MotionGenerator
from motion_env.generation.height_plan import plan_heights
from motion_env.generation.streaming import MotionStream
from motion_env.models.path_features import first_token_path_features, token_path_features

ROUTE = [[0.0, 2.0, 30], [2.0, 4.0, 70], [4.0, 4.0, np.nan]]


@pytest.mark.parametrize("h", [0, 1, 2, 3])
@pytest.mark.parametrize("n", [1, 2, 4, 9, 30])
def test_batched_height_plans_are_the_row_by_row_plans(h: int, n: int) -> None:
    rng = np.random.default_rng(10 * h + n)
    r = 40
    raw = 0.9 + 0.05 * rng.standard_normal((r, n)).cumsum(axis=1)
    raw[::5] += np.linspace(0.0, 0.3, n)  # some rows jump: their bounds are active
    flight = rng.random((r, h + n)) < 0.4
    past = 0.9 + 0.02 * rng.standard_normal((r, h)).cumsum(axis=1)
    past_raw = past + 0.01 * rng.standard_normal((r, h))
    rows = plan_heights(raw, flight, past, past_raw)
    one = np.stack([plan_heights(raw[k], flight[k], past[k], past_raw[k]) for k in range(r)])
    assert rows.shape == (r, n)
    np.testing.assert_allclose(rows, one, rtol=0.0, atol=1e-9)


def test_batched_height_plans_without_a_past() -> None:
    raw = np.linspace(0.9, 1.0, 8)[None].repeat(3, axis=0)
    flight = np.zeros((3, 8), bool)
    flight[1, 2:6] = True
    out = plan_heights(raw, flight)
    one = np.stack([plan_heights(raw[k], flight[k]) for k in range(3)])
    np.testing.assert_allclose(out, one, rtol=0.0, atol=1e-9)
    # In the air the centre of mass falls with gravity: constant second differences.
    acc = np.diff(out[1], 2)[1:4]
    np.testing.assert_allclose(acc, acc[0], atol=1e-9)


def test_first_token_features_are_token_path_features() -> None:
    rng = np.random.default_rng(3)
    paths = rng.standard_normal((7, 21, 3)).cumsum(axis=1).astype(np.float32)
    paths[2, :, 2] += np.linspace(0.0, 9.0, 21, dtype=np.float32)  # headings that wrap
    for rate in (1, 4, 25):
        want = np.stack([token_path_features(p, rate)[0] for p in paths])
        np.testing.assert_array_equal(first_token_path_features(paths, rate), want)


def test_set_goals_queues_what_set_waypoints_queues(random_generator: MotionGenerator) -> None:
    stream = random_generator.stream(["a person walks"] * 3, waypoints=[ROUTE, None, ROUTE], seed=0)
    for _ in range(5):
        stream.step()
    points = np.array([[1.0, 2.0], [-3.0, 0.5]], np.float32)
    stream.set_goals(points, [2, 0])
    goals = dict(stream._pending)
    stream._pending.clear()
    for point, i in zip(points, [2, 0]):
        stream.set_waypoints(point[None], index=i)
    assert goals.keys() == stream._pending.keys()
    for i, (route, where, frame) in goals.items():
        ref_route, ref_where, ref_frame = stream._pending[i]
        np.testing.assert_array_equal(route, ref_route)
        assert route.dtype == ref_route.dtype
        np.testing.assert_array_equal(where, ref_where)
        assert frame == ref_frame
    with pytest.raises(ValueError, match="within"):
        stream.set_goals(np.array([[0.0, 1.0], [1e9, 0.0]]), [0, 1])
    with pytest.raises(ValueError, match="NaN"):
        stream.set_goals(np.array([[np.nan, 1.0]]), [1])
    with pytest.raises(IndexError, match="distinct"):
        stream.set_goals(np.zeros((2, 2)), [1, 1])
    with pytest.raises(ValueError, match="shape"):
        stream.set_goals(np.zeros((2, 3)), [0, 1])


def _frames(gen: MotionGenerator, steer: bool) -> np.ndarray:
    stream = gen.stream("a person walks", waypoints=[ROUTE], seed=4)
    hand = np.full((30, 22, 3), np.nan, np.float32)
    hand[20, 21] = [0.4, 1.5, 1.5]
    out = []
    for t in range(53):
        # Changes after a token's step, after the roll-out, after the path and token, after the
        # decoding (the step before the next token): each undoes what was worked out ahead.
        if steer and t == 17:
            stream.set_waypoints([[3.0, 1.0]])
        if steer and t == 30:
            stream.set_text("a person jogs")
        if steer and t == 35:
            stream.set_joint_targets(hand)
        if steer and t == 40:
            stream.set_waypoints([[-1.0, 3.0], [0.0, 6.0]])
        if steer and t == 47:
            stream.reset(0, "a person waves", start=[1.0, 1.0, 0.5])
        out.append(stream.step())
    return np.stack(out)


@pytest.mark.parametrize("steer", [False, True])
def test_working_ahead_between_tokens_changes_no_frame(
    random_generator: MotionGenerator, monkeypatch: pytest.MonkeyPatch, steer: bool
) -> None:
    worked: list[bool] = []
    work_ahead = MotionStream._work_ahead

    def spy(self: MotionStream) -> None:
        work_ahead(self)
        worked.append(self._early is not None and self._early.body is not None)

    monkeypatch.setattr(MotionStream, "_work_ahead", spy)
    ahead = _frames(random_generator, steer)
    assert any(worked)  # whole tokens were decoded ahead of their step
    calls = []
    monkeypatch.setattr(MotionStream, "_work_ahead", lambda self: calls.append(1))
    at_tokens = _frames(random_generator, steer)
    assert calls  # the stream does ask to work ahead between tokens
    np.testing.assert_array_equal(ahead, at_tokens)
