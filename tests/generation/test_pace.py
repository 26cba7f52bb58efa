"""Untimed routes at the caption's pace: the pace regressor in the pipeline, the stream and the
weights folder (models/pace.py, route_planning.pace_route)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from motion_env.generation.generator import MotionGenerator
from motion_env.models.pace import PaceConfig, PaceRegressor
from motion_env.motion.trajectory import validate_waypoints

UNTIMED = validate_waypoints([[0.0, 4.0 * k] for k in range(1, 6)])
TIMED = validate_waypoints([[0.0, 2.0, 40], [1.0, 4.0, 80], [1.0, 6.0, 120]])


def _pace(dim: int, value: float) -> PaceRegressor:
    model = PaceRegressor(PaceConfig(text_dim=dim))
    model.set_weights(np.zeros(dim), value)
    return model


@pytest.fixture
def paced() -> MotionGenerator:
    gen = MotionGenerator.random(seed=0)
    gen.pipeline.pace = _pace(gen.controller.config.text_dim, 2.0)
    return gen


def test_the_controller_follows_untimed_routes_at_the_pace_and_timed_ones_as_given(
    paced: MotionGenerator,
) -> None:
    emb = paced.pipeline.encode_text(["a person runs", "a person runs"])
    routes = paced.pipeline.paced_routes(emb, [UNTIMED, TIMED], np.zeros((2, 3), np.float32))
    assert not np.isnan(routes[0][:-1, 2]).any() and np.isnan(routes[0][-1, 2])
    np.testing.assert_array_equal(routes[1], TIMED)
    plain = MotionGenerator.random(seed=0)
    # Timed routes: the same path with or without the pace; untimed ones: the controller is paced.
    for route, same in ((TIMED, True), (UNTIMED, False)):
        a = paced.root_paths(["a person runs"], route, 130, seed=0, snap=False)
        b = plain.root_paths(["a person runs"], route, 130, seed=0, snap=False)
        assert np.array_equal(a, b) == same
    m = paced.generate("a person runs", waypoints=UNTIMED[:2], num_frames=200, seed=0)
    np.testing.assert_array_equal(m.waypoints, UNTIMED[:2])  # the user's route, untimed


def test_the_stream_leaves_untimed_routes_untimed(paced: MotionGenerator) -> None:
    # A timed waypoint is passed when its frame comes, reached or not, and the stream's causal
    # bend only snaps the waypoints its path comes near: paced, a late character cut the corner
    # and never reached a waypoint (the studio's browser test). The stream follows untimed routes
    # at the controller's own pace.
    stream = paced.stream(["a person runs", "a person waves"], waypoints=[UNTIMED, None], seed=0)
    assert np.isnan(stream._front.waypoints[0, : len(UNTIMED), 2].numpy()).all()
    stream.set_text("a person walks", index=0)
    stream.set_waypoints(UNTIMED + 1.0, index=1)
    frames = [stream.step() for _ in range(20)]
    assert np.isfinite(np.stack(frames)).all()
    assert np.isnan(stream._front.waypoints[:, :, 2].numpy()).all()


def test_the_pace_regressor_travels_with_the_weights(paced: MotionGenerator, tmp_path) -> None:
    paced.save(tmp_path / "w")
    loaded = MotionGenerator.from_pretrained(tmp_path / "w")
    assert loaded.pipeline.pace is not None
    torch.testing.assert_close(loaded.pipeline.pace.linear.bias, paced.pipeline.pace.linear.bias)
    loaded.pipeline.pace = None
    loaded.save(tmp_path / "w")
    assert not (tmp_path / "w" / "pace.pt").exists()  # a stale one would pace these models


def test_the_shipped_model_runs_untimed_routes_at_a_runs_pace(pretrained_generator: MotionGenerator) -> None:
    gen = pretrained_generator
    if gen.pipeline.pace is None:
        pytest.skip("the shipped model has no pace regressor")
    route = np.array([[0.0, 4.0 * k] for k in range(1, 11)], np.float32)
    texts = ["a person runs forward", "someone jogs straight ahead", "a person walks forward"]
    paths = gen.root_paths(texts, route, 100, seed=0)
    speed = np.linalg.norm(np.diff(paths[:, 20:, :2], axis=1), axis=2).mean(1) * 20
    assert speed[0] >= 2.3 and speed[1] >= 2.3, speed  # it was 2.1 m/s before the pace (real: 2.8)
    assert 0.9 < speed[2] < 1.6, speed  # and walks walk (real takes: 1.2 m/s)
