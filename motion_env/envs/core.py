"""The batched bookkeeping shared by every motion_env environment.

One :class:`CharacterBatch` drives B characters through one generator stream: it turns actions
into the route the generator follows, emits frames, keeps each character's route progress, and
computes observations and reward terms for all B at once. The single environments use B = 1; the
vector environment uses B = num_envs, so N characters cost one batched generator call per frame.

Route semantics (the contract documented in :class:`motion_env.envs.WaypointsEnv`):

- the *route* is the waypoint list given at reset; ``route_index`` k points at the *route target*
  R[k], the waypoint the task asks for next (observation "target", the progress reward);
- R[k] is *passed* when the pelvis comes within ``arrive_radius`` of it (an arrival bonus), or,
  while the character follows the route, when R[k] is timed and its frame has been reached (as
  the generator's path controller does; no bonus); the last waypoint is never passed, reaching it
  ends the episode;
- an action is a *command*, the point the character walks to: a point within ``snap_radius`` of a
  route waypoint R[j], j >= k, means "follow the route from R[j]" (k jumps to j, the generator gets
  R[j:] with their times); any other point is a detour: the character walks to that point and
  stays there; the route waits (k only moves when the pelvis passes R[k]).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from motion_env.envs.arena import Obstacle, obstacle_distance
from motion_env.generation.request import check_text
from motion_env.motion.kinematics import from_heading_frame, to_heading_frame
from motion_env.motion.skeleton import FPS, NUM_JOINTS
from motion_env.motion.trajectory import MAX_COORDINATE, validate_waypoints, wrap_angle

DEFAULT_TEXT_POOL: tuple[str, ...] = (
    "a person walks forward",
    "a person walks slowly",
    "a person walks briskly",
    "a person jogs forward",
    "a person walks casually",
    "a person walks with long strides",
)

# Random routes: legs of this length (m), each turning at most this much from the previous one.
_LEG_LENGTH = (1.5, 3.5)
_MAX_TURN = 0.5 * np.pi
_ROUTE_CLEARANCE = 0.6  # random waypoints keep this far (m) from obstacles and the arena's edge
_COMMAND_TOLERANCE = 1e-4  # metres: a detour this close to the current one is not re-sent

ACTION_MODES = ("normalized", "absolute", "relative")
INVALID_ACTION_MODES = ("raise", "hold")
# Waypoints after the route target that the observation shows ("route_ahead").
ROUTE_AHEAD = 3
# Half-widths of the observation Boxes that are not bounded by nature (metres, m/s and rad/s, or
# the caption projection's units). Finite, so that the env checkers stay quiet; far beyond what a
# walking human produces, and observations are clipped into them.
OBS_BOUNDS = {
    "target": 4 * MAX_COORDINATE,
    "route_ahead": 4 * MAX_COORDINATE,
    "velocity": 100.0,
    "pose": 10.0,
}
OBS_BOUNDS["caption"] = 100.0


@dataclass
class EnvConfig:
    """The tunables of the motion_env environments (validated; see the env docstrings).

    The defaults are the ones measured for learning (README, "Learning"): normalised actions with
    a "follow the route" switch, four frames (one token, 0.2 s) per step, and a time cost.
    """

    action_mode: str = "normalized"
    frames_per_step: int = 4
    arrive_radius: float = 0.5
    terminate_on_arrival: bool = True
    arena_size: float = 10.0
    snap_radius: float = 0.05
    progress_weight: float = 1.0
    arrival_bonus: float = 1.0
    collision_penalty: float = 1.0
    time_penalty: float = 0.1
    reach: float = 3.0
    follow_action: bool = True
    invalid_action: str = "raise"
    random_start: bool = False
    route_length: tuple[int, int] = (2, 4)
    trail_length: int = 600

    def __post_init__(self) -> None:
        if self.action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {self.action_mode!r}")
        if self.invalid_action not in INVALID_ACTION_MODES:
            raise ValueError(
                f"invalid_action must be one of {INVALID_ACTION_MODES}, got {self.invalid_action!r}"
            )
        if int(self.frames_per_step) < 1 or int(self.frames_per_step) != self.frames_per_step:
            raise ValueError(f"frames_per_step must be an integer >= 1, got {self.frames_per_step!r}")
        self.frames_per_step = int(self.frames_per_step)
        for name in ("arrive_radius", "arena_size", "reach"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        for name in ("snap_radius", "progress_weight", "arrival_bonus", "collision_penalty", "time_penalty"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not isinstance(self.follow_action, (bool, np.bool_)):
            raise ValueError(f"follow_action must be True or False, got {self.follow_action!r}")
        lo, hi = (int(v) for v in self.route_length)
        if not 1 <= lo <= hi:
            raise ValueError(f"route_length must be (min, max) with 1 <= min <= max, got {self.route_length}")
        self.route_length = (lo, hi)
        if int(self.trail_length) < 1:
            raise ValueError(f"trail_length must be >= 1, got {self.trail_length}")

    @property
    def action_bound(self) -> float:
        """Half-width of the action Box: 1 (normalized), the arena (absolute), or (relative) any
        arena point from anywhere in it."""
        if self.action_mode == "normalized":
            return 1.0
        return self.arena_size if self.action_mode == "absolute" else 3.0 * self.arena_size

    @property
    def action_size(self) -> int:
        """2 (a point), or 3 with the normalized mode's "follow the route" switch."""
        return 3 if self.action_mode == "normalized" and self.follow_action else 2


# ----------------------------------------------------------------------------------------------
# Checking inputs
# ----------------------------------------------------------------------------------------------


def validate_start(start: Any) -> np.ndarray:
    """A start pose as (3,) float64 x, z, heading (ValueError otherwise)."""
    try:
        arr = np.array(start, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"start must be (x, z, heading): {exc}") from exc
    if arr.shape != (3,) or not np.isfinite(arr).all():
        raise ValueError(f"start must be three finite numbers (x, z, heading), got {start!r}")
    return arr


def validate_text_pool(text_pool: Sequence[str] | None) -> tuple[str, ...]:
    pool = DEFAULT_TEXT_POOL if text_pool is None else tuple(text_pool)
    if isinstance(text_pool, str) or not pool:
        raise ValueError(f"text_pool must be a non-empty sequence of captions, got {text_pool!r}")
    return tuple(check_text(t, f"text_pool[{i}]") for i, t in enumerate(pool))


def check_actions(
    actions: Any, batch: int, bound: float, invalid: str, size: int = 2
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a batch of actions.

    Args:
        actions: (B, size) (or (size,) when B = 1) numbers.
        batch: B.
        bound: the action Box's half-width; finite values beyond it are clipped.
        invalid: "raise" (ValueError for NaN/inf) or "hold" (those rows are flagged, not applied).
        size: numbers per action (2: a point; 3: a point and the follow switch).

    Returns:
        ((B, size) float64 clipped actions, (B,) bool valid rows, (B,) bool clipped rows).
    """
    what = "(x, z)" if size == 2 else "(x, z, follow)"
    try:
        raw = np.asarray(actions)
    except ValueError as exc:  # ragged nested lists
        raise ValueError(f"action must be numbers of shape ({batch}, {size}): {exc}") from None
    if raw.dtype.kind not in "biuf":  # complex parts would be dropped with only numpy's warning
        raise TypeError(f"action must be real numbers {what}, got dtype {raw.dtype}: {actions!r}")
    arr = raw.astype(np.float64)
    if batch == 1 and arr.shape == (size,):
        arr = arr[None]
    if arr.shape != (batch, size):
        expected = f"({size},)" if batch == 1 else f"({batch}, {size})"
        raise ValueError(f"action must have shape {expected} {what}, got {arr.shape}")
    valid = np.isfinite(arr).all(axis=1)
    if not valid.all() and invalid == "raise":
        rows = np.nonzero(~valid)[0].tolist()
        raise ValueError(
            f"action has NaN or infinite values (rows {rows}: {arr[~valid].tolist()}); the step was "
            "not taken and the episode can continue with a finite action (or make the env with "
            "invalid_action='hold' to keep the previous target instead)"
        )
    arr[~valid] = 0.0
    clipped = valid & (np.abs(arr) > bound).any(axis=1)
    return np.clip(arr, -bound, bound), valid, clipped


def sample_start(rng: np.random.Generator, config: EnvConfig, obstacles: Sequence[Obstacle]) -> np.ndarray:
    """(3,) start pose: the origin facing +Z, or (random_start) a free spot and heading in the arena."""
    if not config.random_start:
        return np.zeros(3)
    half = 0.5 * config.arena_size
    for _ in range(100):
        x, z = rng.uniform(-half, half, size=2)
        if obstacle_distance(np.array([x, z]), obstacles) > _ROUTE_CLEARANCE:
            break
    return np.array([x, z, rng.uniform(-np.pi, np.pi)])


def sample_route(
    rng: np.random.Generator,
    start: np.ndarray,
    config: EnvConfig,
    obstacles: Sequence[Obstacle],
    num: int | None = None,
) -> np.ndarray:
    """A random untimed route (K, 3) from `start`: legs of 1.5-3.5 m, turns of at most 90 degrees.

    Waypoints keep clear of obstacles and inside the arena (after a bounded number of tries the
    last candidate is used, pulled inside the arena).
    """
    if num is None:
        num = int(rng.integers(config.route_length[0], config.route_length[1] + 1))
    limit = max(config.arena_size - _ROUTE_CLEARANCE, 0.5 * config.arena_size)
    pos, direction = start[:2].astype(np.float64), float(start[2])
    out = np.full((num, 3), np.nan)
    for i in range(num):
        spread = _MAX_TURN if i else _MAX_TURN * 2.0 / 3.0
        for _ in range(50):
            heading = direction + rng.uniform(-spread, spread)
            point = pos + rng.uniform(*_LEG_LENGTH) * np.array([np.sin(heading), np.cos(heading)])
            inside = (np.abs(point) <= limit).all()
            if inside and obstacle_distance(point, obstacles) > _ROUTE_CLEARANCE:
                break
            spread = min(np.pi, spread * 1.1)  # widen the search when boxed in
        out[i, :2] = np.clip(point, -limit, limit)
        pos, direction = out[i, :2], heading
    return out.astype(np.float32)


def _pad_routes(routes: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per-character (K_b, 3) routes -> ((B, Kmax, 3) padded with the last row, (B,) counts)."""
    kmax = max(len(r) for r in routes)
    out = np.empty((len(routes), kmax, 3), np.float64)
    for b, r in enumerate(routes):
        out[b, : len(r)] = r
        out[b, len(r) :] = r[-1]
    return out, np.array([len(r) for r in routes], np.int64)


# ----------------------------------------------------------------------------------------------
# The batch
# ----------------------------------------------------------------------------------------------


class CharacterBatch:
    """B characters of one generator stream, with their routes, commands and reward bookkeeping.

    Call :meth:`start` once (creates the stream and emits everyone's first frame), then per env step
    :meth:`begin_step`, :meth:`command` (actions), :meth:`emit_frame` ``frames_per_step`` times and
    read :meth:`observations` and the per-step accumulators (``progress``, ``arrivals``,
    ``collisions``). :meth:`restart` re-initialises one character (vector autoreset); its first
    frame comes with the next :meth:`emit_frame`.
    """

    def __init__(self, config: EnvConfig, obstacles: Sequence[Obstacle]) -> None:
        self.config = config
        self.obstacles = obstacles
        self.stream: Any = None
        self.retargeter: Any = None  # a StreamRetargeter when the env emits robot qpos

    def use_robot(self, robot: Any, batch: int) -> None:
        """Also retarget every emitted frame onto `robot` (a name or an MJCF path; None: don't):
        ``self.robot_qpos`` (B, nq) float32 after each :meth:`emit_frame`."""
        if robot is None:
            self.retargeter = None
            return
        from motion_env.retarget.stream import StreamRetargeter

        self.retargeter = StreamRetargeter(robot, batch=batch)
        self.robot_qpos = self.retargeter.qpos.astype(np.float32)

    # -- setup ---------------------------------------------------------------------------------

    def start(
        self,
        generator: Any,
        texts: list[str],
        routes: list[np.ndarray],
        starts: np.ndarray,
        seed: int,
    ) -> None:
        """Open a stream for len(texts) characters and emit their first frame."""
        b = len(texts)
        self.texts = list(texts)
        self.routes = [validate_waypoints(r) for r in routes]
        self.route_arr, self.route_count = _pad_routes(self.routes)
        self.k = np.zeros(b, np.int64)
        self.following = np.ones(b, bool)
        self.command_xz = self.route_arr[:, 0, :2].copy()
        self.reached = np.zeros(b, bool)
        self.pos = np.asarray(starts, np.float64)[:, :2].copy()
        self.theta = np.asarray(starts, np.float64)[:, 2].copy()
        self.prev_pos, self.prev_theta = self.pos.copy(), self.theta.copy()
        self.vel = np.zeros((b, 3))
        self.joints = np.zeros((b, NUM_JOINTS, 3), np.float32)
        self.fresh = np.ones(b, bool)
        self.trails = [deque(maxlen=self.config.trail_length) for _ in range(b)]
        if self.retargeter is not None:
            self.retargeter.reset()
        self.stream = generator.stream(
            list(texts),
            waypoints=[r.copy() for r in self.routes],
            starts=np.asarray(starts, np.float32),
            seed=seed,
        )
        self.caption = self.stream.caption_features()
        self.begin_step()
        self.emit_frame()
        self.just_started[:] = True

    def restart(self, i: int, text: str, route: np.ndarray, start: np.ndarray) -> None:
        """Restart character i with a new caption, route and start (its first frame comes next)."""
        route = self._store_route(i, route)
        self.texts[i] = text
        self.pos[i], self.theta[i] = start[:2], start[2]
        self.fresh[i] = True
        self.trails[i].clear()
        self.progress[i] = self.arrivals[i] = self.collisions[i] = self.frames[i] = 0.0
        if self.retargeter is not None:
            self.retargeter.reset(i)
        self.stream.reset(i, text, waypoints=route.copy(), start=np.asarray(start, np.float32))
        self.caption[i] = self.stream.caption_features()[i]
        self.just_started[i] = True

    def _store_route(self, i: int, route: np.ndarray) -> np.ndarray:
        """Make `route` character i's route from R[0] on (following it); returns it validated."""
        route = validate_waypoints(route)
        self.routes[i] = route
        if len(route) > self.route_arr.shape[1]:
            self.route_arr, self.route_count = _pad_routes(self.routes)
        else:
            self.route_arr[i, : len(route)] = route
            self.route_arr[i, len(route) :] = route[-1]
            self.route_count[i] = len(route)
        self.k[i], self.following[i], self.reached[i] = 0, True, False
        self.command_xz[i] = route[0, :2]
        return route

    def set_text(self, text: str, index: int | None = None) -> None:
        self.stream.set_text(text, index=index)
        for i in range(len(self.texts)) if index is None else [index]:
            self.texts[i] = text
        self.caption = self.stream.caption_features()

    def set_route(self, i: int, route: np.ndarray) -> None:
        """Replace character i's route mid-episode: k = 0 and the character follows the new route."""
        route = self._store_route(i, route)
        self.stream.set_waypoints(route.copy(), index=i)

    # -- per step ------------------------------------------------------------------------------

    def begin_step(self) -> None:
        """Zero the per-step reward accumulators."""
        n = len(self.texts)
        self.progress = np.zeros(n)
        self.arrivals = np.zeros(n)
        self.collisions = np.zeros(n)
        self.frames = np.zeros(n)
        self.just_started = np.zeros(n, bool)
        self.step_frames: list[np.ndarray] = []

    def to_world(self, actions: np.ndarray) -> np.ndarray:
        """Actions (B, 2|3) in the configured mode -> world (x, z) command points.

        In the normalized mode a positive third component ("follow") commands the route target,
        which means "follow the route" (see the module docstring).
        """
        mode = self.config.action_mode
        if mode == "absolute":
            return actions[:, :2].astype(np.float64)
        scale = self.config.reach if mode == "normalized" else 1.0
        world = self.pos + from_heading_frame(actions[:, :2] * scale, self.theta)
        if mode == "normalized" and actions.shape[1] == 3:
            follow = actions[:, 2] > 0.0
            world[follow] = self.route_target[follow]
        return world

    def command(self, actions: np.ndarray, apply: np.ndarray) -> None:
        """Apply actions (B, 2|3) to the characters where `apply` (B,) is True (see module doc)."""
        cmd = self.to_world(actions)
        cols = np.arange(self.route_arr.shape[1])
        dist = np.linalg.norm(self.route_arr[:, :, :2] - cmd[:, None, :], axis=-1)
        on_route = (
            (cols >= self.k[:, None]) & (cols < self.route_count[:, None]) & (dist <= self.config.snap_radius)
        )
        for b in np.nonzero(apply)[0]:
            if on_route[b].any():
                j = int(np.argmax(on_route[b]))
                if self.following[b] and j == self.k[b]:
                    continue  # "keep following the route"
                self.k[b], self.following[b] = j, True
                self.command_xz[b] = self.route_arr[b, j, :2]
                self.stream.set_waypoints(self.routes[b][j:].copy(), index=int(b))
            else:
                if (
                    not self.following[b]
                    and np.linalg.norm(cmd[b] - self.command_xz[b]) <= _COMMAND_TOLERANCE
                ):
                    continue
                self.following[b] = False
                self.command_xz[b] = cmd[b]
                self.stream.set_waypoints(cmd[b][None].astype(np.float32), index=int(b))

    def emit_frame(self, rows: np.ndarray | None = None) -> None:
        """Emit one frame of every character (or of `rows`: the others wait) and update positions,
        velocities and route progress.

        A frame emitted for `rows` only (the first frame of a restarted character, vector-env
        autoreset in the same step) is not one of the step's frames: it starts the new episode.
        """
        every = rows is None
        rows = np.arange(len(self.texts)) if every else np.asarray(rows, np.int64)
        joints = np.asarray(self.stream.step(None if every else rows), dtype=np.float32)
        root = np.asarray(self.stream.root_state, dtype=np.float64)[rows]
        frame = np.asarray(self.stream.frame_index)[rows] - 1  # index of the frame just emitted
        self.joints[rows] = joints
        if every:
            self.step_frames.append(joints)
        else:
            self.just_started[rows] = True
        if self.retargeter is not None:
            self.robot_qpos[rows] = self.retargeter.step(joints, rows)[rows].astype(np.float32)
        fresh = self.fresh[rows]
        pos = joints[:, 0, [0, 2]].astype(np.float64)
        prev_pos = np.where(fresh[:, None], pos, self.pos[rows])
        prev_theta = np.where(fresh, root[:, 2], self.theta[rows])
        self.prev_pos[rows], self.prev_theta[rows] = prev_pos, prev_theta
        self.pos[rows], self.theta[rows] = pos, root[:, 2]
        self.fresh[rows] = False
        step = to_heading_frame(pos - prev_pos, root[:, 2]) * FPS
        self.vel[rows] = np.concatenate([step, wrap_angle(root[:, 2] - prev_theta)[:, None] * FPS], axis=1)
        for b in rows:
            self.trails[b].append(self.pos[b].copy())

        target = self.route_arr[rows, self.k[rows], :2]
        self.progress[rows] += np.linalg.norm(prev_pos - target, axis=1) - np.linalg.norm(
            pos - target, axis=1
        )
        self.collisions[rows] += obstacle_distance(pos, self.obstacles) < 0.0
        self.frames[rows] += 1
        self._advance_routes(rows, frame)

    def _advance_routes(self, rows: np.ndarray, frame: np.ndarray) -> None:
        r = self.config.arrive_radius
        pos = self.pos[rows]
        k, count, following = self.k[rows], self.route_count[rows], self.following[rows]
        arrivals = np.zeros(len(rows))
        for _ in range(self.route_arr.shape[1]):
            wp = self.route_arr[rows, k]
            near = np.linalg.norm(pos - wp[:, :2], axis=1) < r
            can = k < count - 1
            hit = can & near
            late = can & ~hit & following & ~np.isnan(wp[:, 2]) & (frame >= np.nan_to_num(wp[:, 2]))
            if not (hit | late).any():
                break
            arrivals += hit
            k = k + (hit | late)
        last = self.route_arr[rows, count - 1, :2]
        final = (k == count - 1) & ~self.reached[rows] & (np.linalg.norm(pos - last, axis=1) < r)
        self.k[rows] = k
        self.arrivals[rows] += arrivals + final
        self.reached[rows] |= final
        follow = rows[following]
        self.command_xz[follow] = self.route_arr[follow, self.k[follow], :2]

    # -- reading -------------------------------------------------------------------------------

    def step_joints(self) -> np.ndarray:
        """(B, F, 22, 3) the frames each character's last step emitted, F = ``frames_per_step``
        always (one shape, so vector envs can stack it): a character that (re)started this step
        shows its first frame F times, as the pose it stood in."""
        f = self.config.frames_per_step
        out = np.stack(self.step_frames[-f:], axis=1) if self.step_frames else self.joints[:, None]
        if out.shape[1] < f:
            out = np.concatenate([np.repeat(out[:, :1], f - out.shape[1], axis=1), out], axis=1)
        out[self.just_started] = self.joints[self.just_started][:, None]
        return out

    @property
    def route_target(self) -> np.ndarray:
        """(B, 2) world x, z of each character's route target R[k]."""
        return self.route_arr[np.arange(len(self.texts)), self.k, :2].copy()

    def route_ahead(self) -> np.ndarray:
        """(B, ROUTE_AHEAD, 2) world x, z of the waypoints after the route target (the last one
        repeated past the end of the route)."""
        ahead = self.k[:, None] + 1 + np.arange(ROUTE_AHEAD)[None]
        ahead = np.minimum(ahead, self.route_count[:, None] - 1)
        return self.route_arr[np.arange(len(self.texts))[:, None], ahead, :2]

    def observations(self) -> dict[str, np.ndarray]:
        """The Waypoints-v0 observation of every character, as (B, ...) float32 arrays."""
        b = len(self.texts)
        local = to_heading_frame(self.joints[:, :, [0, 2]] - self.pos[:, None, :], self.theta[:, None])
        pose = np.stack([local[..., 0], self.joints[..., 1], local[..., 1]], axis=-1)
        ahead = to_heading_frame(self.route_ahead() - self.pos[:, None], self.theta[:, None])
        last = self.k == self.route_count - 1
        obs = {
            "root": np.stack(
                [self.pos[:, 0], self.pos[:, 1], np.cos(self.theta), np.sin(self.theta)], axis=1
            ),
            "target": to_heading_frame(self.route_target - self.pos, self.theta),
            "route_ahead": ahead.reshape(b, ROUTE_AHEAD * 2),
            "route_state": np.stack(
                [self.following, last, np.minimum(self.route_count - 1 - self.k, ROUTE_AHEAD) / ROUTE_AHEAD],
                axis=1,
            ),
            "velocity": self.vel,
            "pose": pose.reshape(b, NUM_JOINTS * 3),
            "caption": self.caption,
        }
        obs["root"][:, :2] = np.clip(obs["root"][:, :2], -MAX_COORDINATE, MAX_COORDINATE)
        for name, bound in OBS_BOUNDS.items():
            obs[name] = np.clip(obs[name], -bound, bound)
        return {name: value.astype(np.float32) for name, value in obs.items()}

    def rewards(self) -> dict[str, np.ndarray]:
        """This step's reward terms (B,) each; their sum is the reward."""
        c = self.config
        return {
            "reward_progress": c.progress_weight * self.progress,
            "reward_arrival": c.arrival_bonus * self.arrivals,
            "reward_collision": -c.collision_penalty * self.collisions,
            "reward_time": -c.time_penalty * self.frames / FPS,
        }
