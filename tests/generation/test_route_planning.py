"""Route planning: times for untimed waypoints before a timed one, long untimed legs split, untimed
routes timed at the caption's pace."""

from __future__ import annotations

import numpy as np

from motion_env.generation.route_planning import (
    MAX_UNTIMED_LEG,
    MIN_PACE,
    SPLIT_LEG,
    START_ACCELERATION,
    pace_route,
    plan_route,
)
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_waypoints


def test_routes_like_the_training_ones_are_unchanged() -> None:
    for route in ([[0, 3], [3, 6]], [[0, 2, 40], [2, 4, 100]], [[0, 3, 60], [3, 6, np.nan]]):
        checked = validate_waypoints(route)
        np.testing.assert_array_equal(plan_route(checked, np.zeros(2)), checked)
    assert plan_route(None, np.zeros(2)) is None


def test_untimed_waypoints_before_a_timed_one_get_times_at_one_pace() -> None:
    planned = plan_route(validate_waypoints([[0, 3, np.nan], [0, 4, np.nan], [0, 6, 120]]), np.zeros(2))
    np.testing.assert_allclose(planned[:, 2], [60, 80, 120])  # 3 m, 1 m, 2 m at 1 m per 20 frames
    later = plan_route(validate_waypoints([[0, 2, 40], [0, 4, np.nan], [0, 8, 120]]), np.zeros(2))
    np.testing.assert_allclose(later[:, 2], [40, 66.666664, 120], rtol=1e-6)
    # From the middle of an episode: only what lies ahead of the current frame.
    ahead = plan_route(validate_waypoints([[0, 1, 10], [0, 3, np.nan], [0, 5, 100]]), np.array([0, 1]), 50)
    np.testing.assert_allclose(ahead[:, 2], [10, 75, 100])


def test_long_untimed_legs_are_split_where_they_were() -> None:
    planned = plan_route(validate_waypoints([[0, 50]]), np.zeros(2))
    assert len(planned) == 13 and np.isnan(planned[:, 2]).all()
    np.testing.assert_allclose(planned[-1, :2], [0, 50])
    legs = np.linalg.norm(np.diff(np.concatenate([[[0, 0]], planned[:, :2]]), axis=0), axis=1)
    assert legs.max() <= SPLIT_LEG + 1e-5 and np.allclose(planned[:, 0], 0)
    short = validate_waypoints([[0, MAX_UNTIMED_LEG - 0.1], [0, 2 * MAX_UNTIMED_LEG - 0.2]])
    np.testing.assert_array_equal(plan_route(short, np.zeros(2)), short)


def test_the_shipped_model_walks_to_a_far_waypoint_at_walking_pace(pretrained_generator) -> None:
    m = pretrained_generator.generate("a person walks", waypoints=[[0, 50]], num_frames=200, seed=0)
    speed = np.linalg.norm(np.diff(m.joints[20:, 0, [0, 2]], axis=0), axis=1) * 20
    assert 0.8 < speed.mean() < 1.7, speed.mean()  # it jogged at 2.9 m/s before the legs were split
    np.testing.assert_array_equal(m.waypoints, [[0, 50, np.nan]])  # the user's route is kept


def test_untimed_waypoints_after_the_last_timed_one_are_timed_at_the_pace() -> None:
    route = validate_waypoints([[0, 4], [0, 8], [0, 12]])
    paced = pace_route(route, np.zeros(2), 0, 2.0)
    lead = FPS * 2.0 / (2 * START_ACCELERATION)  # the time to get going from rest
    np.testing.assert_allclose(paced[:2, 2], [lead + 40, lead + 80])  # 4 m, 8 m at 2 m/s
    assert np.isnan(paced[-1, 2])  # the last waypoint: arrive and stop at the caption's own pace
    np.testing.assert_array_equal(paced[:, :2], route[:, :2])
    # The same through plan_route; without a pace, or at a standing caption's, nothing changes.
    np.testing.assert_array_equal(plan_route(route, np.zeros(2), pace=2.0), paced)
    for pace in (None, float("nan"), MIN_PACE - 0.1):
        np.testing.assert_array_equal(plan_route(route, np.zeros(2), pace=pace), route)
    single = validate_waypoints([[0, 3]])
    np.testing.assert_array_equal(pace_route(single, np.zeros(2), 0, 3.0), single)


def test_pacing_starts_at_the_last_timed_waypoint_ahead_or_where_the_character_is() -> None:
    route = validate_waypoints([[0, 2, 40], [0, 5, np.nan], [0, 6, np.nan]])
    np.testing.assert_allclose(pace_route(route, np.zeros(2), 0, 1.5)[:, 2], [40, 80, np.nan])
    # Mid-episode (the stream): no time to get going; a timed waypoint behind is neither an
    # anchor nor re-timed.
    later = pace_route(route, np.array([0.0, 3.0]), 60, 1.0)
    np.testing.assert_allclose(later[:, 2], [40, 100, np.nan])
    # A long leg is split first, then every piece is timed.
    planned = plan_route(validate_waypoints([[0, 20], [0, 21]]), np.zeros(2), pace=4.0)
    assert len(planned) == 6 and not np.isnan(planned[:-1, 2]).any()
    assert np.all(np.diff(planned[:-1, 2]) > 0)
