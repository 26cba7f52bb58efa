"""A forward walk turns round on an arc to a waypoint behind it (route_planning.turn_round): the
arc's geometry, which captions and routes get one, and where the pipeline and the stream use it."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from motion_env.generation.route_planning import (
    BACKWARD,
    TURN_MIN_DISTANCE,
    TURN_RADIUS,
    WALKS,
    turn_round,
    walks_forward,
)

ACTIONS = (*WALKS, *BACKWARD, "run", "walk-left", "(unlabelled)")


def _route(*points: tuple[float, ...]) -> np.ndarray:
    return np.array([[*p, np.nan][:3] for p in points], np.float32)


def _probs(**p: float) -> np.ndarray:
    out = np.array([p.get(a.replace("-", "_").strip("()"), 0.0) for a in ACTIONS])
    return out / out.sum()


@pytest.mark.parametrize(
    ("probs", "walks"),
    [
        (_probs(walk=0.26, unlabelled=0.72, walk_turn_right=0.02), True),  # "a person walks", as read
        (_probs(walk_turn_left=0.97, unlabelled=0.03), True),
        (_probs(run=0.7, unlabelled=0.3), False),
        (_probs(walk_back=0.99, walk_left=0.01), False),
        (_probs(walk=0.4, walk_back=0.3, walk_left=0.3), False),
        (_probs(walk=0.05, unlabelled=0.95), False),  # too little read to go on
    ],
)
def test_which_captions_read_as_a_forward_walk(probs: np.ndarray, walks: bool) -> None:
    assert walks_forward(probs, ACTIONS, "(unlabelled)") is walks


@pytest.mark.parametrize(
    "route",
    [
        _route((0.0, 4.0)),  # ahead
        _route((4.0, 0.0)),  # to the side
        _route((-3.0, -1.0)),  # 108 degrees round: still walked to
        _route((0.0, -0.8 * TURN_MIN_DISTANCE)),  # near behind: a step back
        np.array([[0.0, -4.0, 60.0]], np.float32),  # timed: its timing stays the controller's
    ],
)
def test_routes_that_need_no_turn_are_left_alone(route: np.ndarray) -> None:
    assert turn_round(route, np.zeros(3)) is route
    assert turn_round(None, np.zeros(3)) is None


def _arc(route: np.ndarray, start: np.ndarray) -> np.ndarray:
    out = turn_round(route, start)
    assert out is not None and len(out) > len(route)
    np.testing.assert_array_equal(out[-len(route) :], route)  # the route itself follows, as it was
    return out[: len(out) - len(route)]


@pytest.mark.parametrize("target", [(0.0, -4.0), (2.0, -3.0), (-2.0, -3.0), (0.5, -8.0)])
def test_a_waypoint_behind_is_reached_on_a_u_turn_towards_its_side(target: tuple[float, float]) -> None:
    arc = _arc(_route(target), np.zeros(3))
    assert np.isnan(arc[:, 2]).all()  # untimed: the controller walks it at the caption's pace
    side = 1.0 if target[0] >= 0 else -1.0  # +X is the left of a body facing +Z
    centre = np.array([side * TURN_RADIUS, 0.0])
    np.testing.assert_allclose(np.linalg.norm(arc[:, :2] - centre, axis=1), TURN_RADIUS, atol=1e-5)
    assert (np.sign(arc[:, 0]) == side).all()
    # the arc ends going within 60 degrees of the waypoint, and no sooner;
    # each point's angle round the arc (x = side R (1 - cos), z = R sin)
    turned = np.arctan2(arc[:, 1], TURN_RADIUS - side * arc[:, 0])
    going = np.stack([side * np.sin(turned), np.cos(turned)], 1)
    to = np.asarray(target) - arc[:, :2]
    cos = (going * to).sum(1) / np.linalg.norm(to, axis=1)
    assert cos[-1] > 0.5 and (cos[:-1] <= 0.5).all()


def test_the_arc_turns_with_the_start() -> None:
    route = _route((0.0, -4.0))
    at_origin = _arc(route, np.zeros(3))
    heading, where = math.pi / 2, np.array([3.0, -1.0])  # facing +X
    c, s = math.cos(heading), math.sin(heading)
    rotate = np.array([[c, -s], [s, c]])  # (lateral, forward) @ rotate: the left and ahead of a heading
    moved = _route(tuple(where + route[0, :2] @ rotate))
    np.testing.assert_allclose(
        _arc(moved, np.array([*where, heading]))[:, :2], where + at_origin[:, :2] @ rotate, atol=1e-5
    )


def test_a_route_that_doubles_back_turns_round_at_the_waypoint_it_came_to() -> None:
    route = _route((0.0, 4.0), (0.2, 0.0))  # out 4 m and back
    out = turn_round(route, np.zeros(3))
    assert out is not None and len(out) > 2
    np.testing.assert_array_equal(out[0], route[0])
    np.testing.assert_array_equal(out[-1], route[1])
    arc = out[1:-1, :2]
    assert arc[0, 1] > 4.0 and (arc[:, 1] > 4.0 - 1e-5).all()  # on past the waypoint it came to, then round
    np.testing.assert_allclose(np.linalg.norm(arc - [TURN_RADIUS, 4.0], axis=1), TURN_RADIUS, atol=1e-5)
    zigzag = _route((0.0, 4.0), (3.0, 6.0), (6.0, 4.0), (9.0, 6.0))  # turns of 90 degrees at most
    assert turn_round(zigzag, np.zeros(3)) is zigzag


def test_the_pipeline_gives_the_arc_to_the_controller_only(monkeypatch: pytest.MonkeyPatch) -> None:
    from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator
    from motion_env.generation.request import check_batch_request

    gen = MotionGenerator.from_pretrained(RANDOM_MODEL)
    pipe = gen.pipeline
    assert not pipe.walks_forward(["a person walks"]).any()  # no caption adapter: nothing read
    seen = []
    rollout = pipe.rollout
    monkeypatch.setattr(pipe, "rollout", lambda emb, req, n: seen.append(req.routes) or rollout(emb, req, n))
    monkeypatch.setattr(pipe, "walks_forward", lambda texts: np.array([t.endswith("walks") for t in texts]))
    behind = [[[0.0, -4.0]], [[0.0, -4.0]]]
    assert gen.root_paths(["a person walks", "a person jogs"], behind, num_frames=40, seed=0).shape[0] == 2
    walked, jogged = seen[-1]
    assert len(walked) > 1 and np.isnan(walked[:-1, 2]).all()
    assert len(jogged) == 1
    req = check_batch_request(["a person walks"], behind[:1], 40, 0, None)
    with torch.no_grad():
        routes, _ = pipe.plan_paths(pipe.encode_text(req.texts), req)
    assert len(seen[-1][0]) > 1 and len(routes[0]) == 1  # the path is bent through the route alone


def test_the_stream_turns_round_from_where_a_new_route_finds_it(monkeypatch: pytest.MonkeyPatch) -> None:
    from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator

    stream = MotionGenerator.from_pretrained(RANDOM_MODEL).stream(["a person walks"], waypoints=[[0.0, -4.0]])
    assert len(stream._routes[0]) == 1  # the untrained model reads no caption: no arc
    pipe = stream._pipe
    monkeypatch.setattr(pipe, "walks_forward", lambda texts: np.array([t.endswith("walks") for t in texts]))

    def route_behind() -> tuple[np.ndarray, np.ndarray]:  # a waypoint 4 m behind, planned at the next token
        for _ in range(5):
            stream.step()
        where = stream.root_state[0].astype(np.float64)
        behind = where[:2] - 4.0 * np.array([math.sin(where[2]), math.cos(where[2])])
        stream.set_waypoints([behind], index=0)
        for _ in range(4):  # the route is planned when the next token needs it, from where it was given
            stream.step()
        return where, behind

    where, behind = route_behind()
    expected = turn_round(_route(tuple(behind)), where)
    assert expected is not None and len(expected) > 1
    np.testing.assert_allclose(stream._routes[0], expected, atol=1e-5)
    stream.set_text("a person walks slowly")  # read again: the next route is a slow walk's, not turned
    route_behind()
    assert len(stream._routes[0]) == 1
    monkeypatch.undo()
    stream.reset(0, "a person walks", waypoints=[[0.0, -4.0]])  # read again: no walk without an adapter
    assert len(stream._routes[0]) == 1
