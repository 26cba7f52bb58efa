"""Grid A* over an occupancy map, path smoothing, re-planning and carrot waypoints.

The planner works on the floor plane (x, z). Obstacles are the environments' own
(:mod:`motion_env.envs.arena`): circles ``(x, z, radius)`` or polygons ``[(x, z), ...]``; they
are inflated by a clearance so that the pelvis path keeps the body out of them. The policy
re-plans when the goal or the map changes, or when the character has drifted off its plan, and
emits a "carrot": the point a fixed distance ahead along the plan.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence

import numpy as np

from motion_env.envs.arena import Obstacle, is_circle, obstacle_distance, validate_obstacles

_SQRT2 = float(np.sqrt(2.0))
_MOVES = [(-1, 0, 1.0), (1, 0, 1.0), (0, -1, 1.0), (0, 1, 1.0),
          (-1, -1, _SQRT2), (-1, 1, _SQRT2), (1, -1, _SQRT2), (1, 1, _SQRT2)]  # fmt: skip


class OccupancyGrid:
    """A boolean grid over ``bounds = (x_min, x_max, z_min, z_max)``; True cells are blocked.

    Cells closer than `clearance` to an obstacle count as blocked, so a plan through free cells
    keeps the pelvis at least `clearance` away from every obstacle.
    """

    def __init__(
        self,
        bounds: tuple[float, float, float, float],
        obstacles: Sequence[Obstacle] = (),
        resolution: float = 0.1,
        clearance: float = 0.4,
    ) -> None:
        x_min, x_max, z_min, z_max = (float(b) for b in bounds)
        if not (x_max > x_min and z_max > z_min):
            raise ValueError(f"bounds must be (x_min, x_max, z_min, z_max) with min < max, got {bounds}")
        if resolution <= 0 or clearance < 0:
            raise ValueError(f"need resolution > 0 and clearance >= 0, got {resolution}, {clearance}")
        self.bounds = (x_min, x_max, z_min, z_max)
        self.resolution = float(resolution)
        self.clearance = float(clearance)
        self.obstacles = validate_obstacles(obstacles)
        self.shape = (
            int(np.ceil((x_max - x_min) / resolution)) + 1,
            int(np.ceil((z_max - z_min) / resolution)) + 1,
        )
        ix, iz = np.meshgrid(np.arange(self.shape[0]), np.arange(self.shape[1]), indexing="ij")
        centres = np.stack([x_min + ix * resolution, z_min + iz * resolution], axis=-1).reshape(-1, 2)
        self.blocked = (obstacle_distance(centres, self.obstacles) < self.clearance).reshape(self.shape)

    def to_cell(self, point: np.ndarray) -> tuple[int, int]:
        x_min, _, z_min, _ = self.bounds
        i = int(round((float(point[0]) - x_min) / self.resolution))
        j = int(round((float(point[1]) - z_min) / self.resolution))
        return min(max(i, 0), self.shape[0] - 1), min(max(j, 0), self.shape[1] - 1)

    def to_point(self, cell: tuple[int, int]) -> np.ndarray:
        x_min, _, z_min, _ = self.bounds
        return np.array([x_min + cell[0] * self.resolution, z_min + cell[1] * self.resolution])

    def segment_free(self, a: np.ndarray, b: np.ndarray) -> bool:
        """True when every cell along the straight segment a -> b is free."""
        steps = int(np.ceil(np.linalg.norm(b - a) / (0.5 * self.resolution))) + 1
        for t in np.linspace(0.0, 1.0, steps):
            if self.blocked[self.to_cell(a + t * (b - a))]:
                return False
        return True

    def nearest_free(self, cell: tuple[int, int]) -> tuple[int, int]:
        """The free cell closest to `cell` (itself when free); lets a plan start inside a margin."""
        if not self.blocked[cell]:
            return cell
        free = np.argwhere(~self.blocked)
        if len(free) == 0:
            raise ValueError("the occupancy map has no free cell: obstacles cover the whole area")
        k = np.argmin(((free - np.array(cell)) ** 2).sum(axis=1))
        return int(free[k, 0]), int(free[k, 1])


def astar(grid: OccupancyGrid, start: np.ndarray, goal: np.ndarray) -> np.ndarray | None:
    """8-connected A* from start to goal (world (x, z)); returns (N, 2) cell centres, or None."""
    s = grid.nearest_free(grid.to_cell(start))
    g = grid.nearest_free(grid.to_cell(goal))

    def heuristic(c: tuple[int, int]) -> float:  # octile distance: admissible on 8-connected grids
        dx, dz = abs(c[0] - g[0]), abs(c[1] - g[1])
        return max(dx, dz) + (_SQRT2 - 1.0) * min(dx, dz)

    cost = {s: 0.0}
    parent: dict[tuple[int, int], tuple[int, int]] = {}
    frontier = [(heuristic(s), 0.0, s)]
    closed = set()
    nx, nz = grid.shape
    while frontier:
        _, c_cost, cell = heapq.heappop(frontier)
        if cell == g:
            path = [cell]
            while path[-1] in parent:
                path.append(parent[path[-1]])
            return np.array([grid.to_point(c) for c in reversed(path)])
        if cell in closed:
            continue
        closed.add(cell)
        for di, dj, step in _MOVES:
            n = (cell[0] + di, cell[1] + dj)
            if not (0 <= n[0] < nx and 0 <= n[1] < nz) or grid.blocked[n]:
                continue
            # No diagonal squeeze between two blocked cells.
            if di and dj and (grid.blocked[cell[0] + di, cell[1]] or grid.blocked[cell[0], cell[1] + dj]):
                continue
            n_cost = c_cost + step
            if n_cost < cost.get(n, np.inf):
                cost[n] = n_cost
                parent[n] = cell
                heapq.heappush(frontier, (n_cost + heuristic(n), n_cost, n))
    return None


def smooth_path(grid: OccupancyGrid, path: np.ndarray) -> np.ndarray:
    """Shortcut a grid path by line of sight: keep only the corners a walker needs."""
    if len(path) <= 2:
        return path
    kept = [path[0]]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not grid.segment_free(path[i], path[j]):
            j -= 1
        kept.append(path[j])
        i = j
    return np.array(kept)


class AStarPolicy:
    """Walk to `goal` around obstacles: plan with A*, smooth, and emit carrot waypoints.

    Args:
        goal: world (x, z) to reach.
        obstacles: circles (x, z, r) and/or polygons [(x, z), ...].
        bounds: planning area (x_min, x_max, z_min, z_max); default: around start, goal and obstacles.
        resolution: grid cell size (m).
        clearance: how far the planned pelvis path stays from obstacles (m).
        lookahead: distance along the plan of the emitted carrot (m).
        replan_distance: re-plan when the character is further than this from its plan (m).
    """

    def __init__(
        self,
        goal: Sequence[float],
        obstacles: Sequence[Obstacle] = (),
        bounds: tuple[float, float, float, float] | None = None,
        resolution: float = 0.1,
        clearance: float = 0.5,
        lookahead: float = 1.0,
        replan_distance: float = 0.75,
    ) -> None:
        self.resolution = float(resolution)
        self.clearance = float(clearance)
        self.lookahead = float(lookahead)
        self.replan_distance = float(replan_distance)
        self._bounds = bounds
        self.obstacles = validate_obstacles(obstacles)
        self.set_goal(goal)

    def set_goal(self, goal: Sequence[float]) -> None:
        goal_arr = np.asarray(goal, dtype=np.float64).reshape(-1)
        if goal_arr.shape != (2,) or not np.isfinite(goal_arr).all():
            raise ValueError(f"goal must be a finite (x, z) pair, got {goal!r}")
        self.goal = goal_arr
        self.plan: np.ndarray | None = None

    def set_obstacles(self, obstacles: Sequence[Obstacle]) -> None:
        self.obstacles = validate_obstacles(obstacles)
        self.plan = None

    def reset(self) -> None:
        self.plan = None

    def _grid_around(self, position: np.ndarray) -> OccupancyGrid:
        if self._bounds is not None:
            bounds = self._bounds
        else:
            pts = [position, self.goal]
            for o in self.obstacles:
                if is_circle(o):
                    pts += [np.array(o[:2]) - o[2], np.array(o[:2]) + o[2]]
                else:
                    pts += list(np.asarray(o))
            pts_arr = np.array(pts)
            margin = 2.0 + self.clearance
            lo, hi = pts_arr.min(axis=0) - margin, pts_arr.max(axis=0) + margin
            bounds = (lo[0], hi[0], lo[1], hi[1])
        return OccupancyGrid(bounds, self.obstacles, self.resolution, self.clearance)

    def replan(self, position: np.ndarray) -> np.ndarray:
        grid = self._grid_around(position)
        path = astar(grid, position, self.goal)
        if path is None:
            raise ValueError(f"no path from {position.round(2).tolist()} to {self.goal.round(2).tolist()}")
        path = smooth_path(grid, path)
        # The grid snaps the ends to cell centres; use the exact goal as the final point.
        path[0], path[-1] = position, self.goal
        self.plan = path
        return path

    def _distance_to_plan(self, position: np.ndarray) -> tuple[float, int, float]:
        """(distance, segment index, fraction along it) of the closest point of the plan."""
        a, b = self.plan[:-1], self.plan[1:]
        ab = b - a
        t = np.clip(((position - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0.0, 1.0)
        d = np.linalg.norm(a + t[:, None] * ab - position, axis=1)
        k = int(np.argmin(d))
        return float(d[k]), k, float(t[k])

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        position = np.asarray(obs["root"][:2], dtype=np.float64)
        if (
            self.plan is None
            or len(self.plan) < 2
            or self._distance_to_plan(position)[0] > self.replan_distance
        ):
            self.replan(position)
        if len(self.plan) < 2:
            return self.goal.astype(np.float32)
        _, k, t = self._distance_to_plan(position)
        # Walk `lookahead` metres along the plan from the closest point.
        point = self.plan[k] + t * (self.plan[k + 1] - self.plan[k])
        remaining = self.lookahead
        for nxt in self.plan[k + 1 :]:
            seg = np.linalg.norm(nxt - point)
            if seg >= remaining:
                return (point + (nxt - point) * (remaining / max(seg, 1e-12))).astype(np.float32)
            remaining -= seg
            point = nxt
        return self.goal.astype(np.float32)
