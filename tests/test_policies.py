import gymnasium as gym
import numpy as np
import pytest

from motion_env.envs.arena import obstacle_distance
from policies import AStarPolicy, OccupancyGrid, RandomPolicy, WaypointPolicy, astar, smooth_path


def _obs(x: float, z: float) -> dict[str, np.ndarray]:
    return {"root": np.array([x, z, 1.0, 0.0], np.float32)}


def test_astar_goes_around_a_wall_and_smoothing_keeps_clearance():
    wall = [(-2.0, 2.0), (2.0, 2.0), (2.0, 2.5), (-2.0, 2.5)]
    grid = OccupancyGrid((-5, 5, -1, 6), [wall], resolution=0.1, clearance=0.3)
    path = astar(grid, np.array([0.0, 0.0]), np.array([0.0, 5.0]))
    assert path is not None
    smooth = smooth_path(grid, path)
    assert 2 < len(smooth) < len(path)
    # Dense samples along the smoothed path stay out of the inflated wall.
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(smooth[:-1], smooth[1:])])
    assert obstacle_distance(dense, [wall]).min() > 0.25
    assert np.linalg.norm(smooth[-1] - [0.0, 5.0]) < 0.11


def test_astar_reports_no_path_when_enclosed():
    ring = [(np.cos(a) * 2, np.sin(a) * 2, 0.6) for a in np.linspace(0, 2 * np.pi, 24, endpoint=False)]
    grid = OccupancyGrid((-4, 4, -4, 4), ring, resolution=0.1, clearance=0.1)
    assert astar(grid, np.array([0.0, 0.0]), np.array([3.5, 3.5])) is None


def test_astar_policy_carrot_walk_reaches_goal_without_entering_obstacles():
    obstacles = [(0.0, 3.0, 1.0), [(1.5, 5.5), (4.0, 5.5), (4.0, 6.0), (1.5, 6.0)]]
    policy = AStarPolicy(goal=(1.0, 8.0), obstacles=obstacles, clearance=0.4, lookahead=0.8)
    pos = np.zeros(2)
    trail = [pos.copy()]
    for _ in range(400):  # an ideal walker: 1.2 m/s toward the carrot at 20 fps
        carrot = policy.act(_obs(*pos))
        step = carrot - pos
        dist = np.linalg.norm(step)
        pos = pos + step / max(dist, 1e-9) * min(dist, 0.06)
        trail.append(pos.copy())
    trail = np.array(trail)
    assert np.linalg.norm(trail[-1] - [1.0, 8.0]) < 0.1
    assert obstacle_distance(trail, obstacles).min() > 0.2


def test_astar_policy_replans_when_goal_or_map_changes():
    policy = AStarPolicy(goal=(0.0, 5.0))
    policy.act(_obs(0, 0))
    first = policy.plan.copy()
    policy.set_goal((5.0, 0.0))
    assert policy.plan is None
    carrot = policy.act(_obs(0, 0))
    assert carrot[0] > 0.5 and not np.array_equal(first, policy.plan)
    policy.set_obstacles([(2.5, 0.0, 1.0)])
    policy.act(_obs(0, 0))
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(policy.plan[:-1], policy.plan[1:])])
    assert obstacle_distance(dense, policy.obstacles).min() > 0.3


def test_bad_inputs_raise_clear_errors():
    with pytest.raises(ValueError, match="goal"):
        AStarPolicy(goal=(np.nan, 1.0))
    with pytest.raises(ValueError, match="obstacles\\[0\\]"):
        AStarPolicy(goal=(1.0, 1.0), obstacles=[(0.0, 0.0, -1.0)])
    with pytest.raises(ValueError, match="bounds"):
        OccupancyGrid((1, 0, 0, 1))
    with pytest.raises(ValueError, match="waypoints"):
        WaypointPolicy(np.zeros((0, 2)))


def test_waypoint_policy_advances_and_random_policy_holds():
    policy = WaypointPolicy([[0, 1, 20], [0, 2, 40], [3, 3, 60]], radius=0.3)
    assert np.allclose(policy.act(_obs(0, 0)), [0, 1])
    assert np.allclose(policy.act(_obs(0, 0.9)), [0, 2])
    assert np.allclose(policy.act(_obs(0, 2.1)), [3, 3])
    policy.reset()
    assert np.allclose(policy.act(_obs(0, 0)), [0, 1])

    space = gym.spaces.Box(-5, 5, (2,), np.float32)
    rp = RandomPolicy(space, hold=3, seed=0)
    actions = [rp.act({}) for _ in range(6)]
    assert np.array_equal(actions[0], actions[2]) and not np.array_equal(actions[2], actions[3])
    rp.reset()
    assert np.array_equal(rp.act({}), actions[0])
