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

:func:`build_characters` checks what an environment is made of (captions, obstacles, generator)
once and builds its batch.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from typing import Any

import numpy as np

from motion_env.envs.arena import Obstacle, obstacle_distance, validate_obstacles
from motion_env.envs.config import OBS_BOUNDS, ROUTE_AHEAD, EnvConfig, validate_text_pool
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.kinematics import from_heading_frame, to_heading_frame
from motion_env.motion.skeleton import FPS, NUM_JOINTS
from motion_env.motion.trajectory import MAX_COORDINATE, validate_waypoints, wrap_angle

_COMMAND_TOLERANCE = 1e-4  # metres: a detour this close to the current one is not re-sent
# The observation's numeric parts, in its order, with their widths (the caption's comes last).
_OBS_SIZES = {
    "root": 4,
    "target": 2,
    "route_ahead": 2 * ROUTE_AHEAD,
    "route_state": 3,
    "velocity": 3,
    "pose": 3 * NUM_JOINTS,
}


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
        if self.config.lookahead != "auto":
            self.stream.lookahead = self.config.lookahead
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
        self.caption[i] = self.stream.caption_features(i)
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
        if index is None:
            self.caption = self.stream.caption_features()
        else:
            self.caption[index] = self.stream.caption_features(index)

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
        """Apply actions (B, 2|3) to the characters where `apply` (B,) is True (see module doc; the
        route test compiled where numba runs: :func:`motion_env.envs.core_jit.route_commands`)."""
        cmd = self.to_world(actions)
        if jit_enabled():
            asks = _loops().route_commands(
                cmd, apply, self.route_arr, self.route_count, self.k, self.following, self.command_xz,
                self.config.snap_radius, _COMMAND_TOLERANCE,
            )  # fmt: skip
            for b in np.nonzero(asks >= 0)[0]:
                self.stream.set_waypoints(self.routes[b][asks[b] :].copy(), index=int(b))
            detour = np.nonzero(asks == -2)[0]
            if len(detour):
                self.stream.set_goals(cmd[detour].astype(np.float32), detour)
            return
        cols = np.arange(self.route_arr.shape[1])
        dist = np.linalg.norm(self.route_arr[:, :, :2] - cmd[:, None, :], axis=-1)
        on_route = (
            (cols >= self.k[:, None]) & (cols < self.route_count[:, None]) & (dist <= self.config.snap_radius)
        )
        rows = np.nonzero(apply)[0]
        hit = on_route[rows].any(axis=1)
        for b in rows[hit]:
            j = int(np.argmax(on_route[b]))
            if self.following[b] and j == self.k[b]:
                continue  # "keep following the route"
            self.k[b], self.following[b] = j, True
            self.command_xz[b] = self.route_arr[b, j, :2]
            self.stream.set_waypoints(self.routes[b][j:].copy(), index=int(b))
        # Detours, all at once: the point each character walks to (an unchanged one is not re-sent).
        detour = rows[~hit]
        moved = np.linalg.norm(cmd[detour] - self.command_xz[detour], axis=1)
        detour = detour[self.following[detour] | (moved > _COMMAND_TOLERANCE)]
        if len(detour):
            self.following[detour] = False
            self.command_xz[detour] = cmd[detour]
            self.stream.set_goals(cmd[detour].astype(np.float32), detour)

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
        if jit_enabled():
            _loops().track_frame(
                rows, joints, root, frame, self.fresh, self.pos, self.theta, self.prev_pos,
                self.prev_theta, self.vel, self.route_arr, self.route_count, self.k, self.following,
                self.reached, self.command_xz, self.progress, self.arrivals, self.frames,
                self.config.arrive_radius, float(FPS),
            )  # fmt: skip
        else:
            self._track_frame(rows, joints, root, frame)
        if len(self.obstacles):
            self.collisions[rows] += obstacle_distance(self.pos[rows], self.obstacles) < 0.0
        for b in rows:
            self.trails[b].append(self.pos[b].copy())

    def _track_frame(self, rows: np.ndarray, joints: np.ndarray, root: np.ndarray, frame: np.ndarray) -> None:
        """Positions, velocities, route progress and route advance of characters `rows` after
        their frame `frame` (R,): (R, 22, 3) joints, (R, 3) root state (x, z, heading). Compiled
        twin: :func:`motion_env.envs.core_jit.track_frame`."""
        fresh = self.fresh[rows]
        pos = joints[:, 0, [0, 2]].astype(np.float64)
        prev_pos = np.where(fresh[:, None], pos, self.pos[rows])
        prev_theta = np.where(fresh, root[:, 2], self.theta[rows])
        self.prev_pos[rows], self.prev_theta[rows] = prev_pos, prev_theta
        self.pos[rows], self.theta[rows] = pos, root[:, 2]
        self.fresh[rows] = False
        step = to_heading_frame(pos - prev_pos, root[:, 2]) * FPS
        self.vel[rows] = np.concatenate([step, wrap_angle(root[:, 2] - prev_theta)[:, None] * FPS], axis=1)
        target = self.route_arr[rows, self.k[rows], :2]
        self.progress[rows] += np.linalg.norm(prev_pos - target, axis=1) - np.linalg.norm(
            pos - target, axis=1
        )
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
        """The Waypoints-v0 observation of every character, as (B, ...) float32 arrays (compiled
        where numba runs: :func:`motion_env.envs.core_jit.observe`)."""
        b = len(self.texts)
        if jit_enabled():
            obs = {name: np.empty((b, size), np.float32) for name, size in _OBS_SIZES.items()}
            _loops().observe(
                self.joints, self.pos, self.theta, self.vel, self.route_arr, self.route_count, self.k,
                self.following, ROUTE_AHEAD, MAX_COORDINATE, OBS_BOUNDS["target"],
                OBS_BOUNDS["route_ahead"], OBS_BOUNDS["velocity"], OBS_BOUNDS["pose"], *obs.values(),
            )  # fmt: skip
            bound = OBS_BOUNDS["caption"]
            return {**obs, "caption": np.clip(self.caption, -bound, bound).astype(np.float32)}
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


def _loops() -> Any:
    """:mod:`motion_env.envs.core_jit`, imported on first use (numba compiles it once per machine,
    and says so)."""
    from motion_env.envs import core_jit as module

    note_first_compile(module.track_frame, "the environments' bookkeeping")
    return module


def make_generator(generator: Any | None, model_path: str | None, device: str) -> Any:
    """The given generator, or the shipped (or `model_path`) model loaded on `device`."""
    if generator is not None:
        if not callable(getattr(generator, "stream", None)):
            raise TypeError(
                f"generator must have a stream(...) method (a MotionGenerator), got {type(generator)}"
            )
        return generator
    from motion_env.generation.generator import MotionGenerator

    return MotionGenerator.from_pretrained(model_path, device=device)


def build_characters(
    config: EnvConfig,
    text_pool: Sequence[str] | None,
    obstacles: np.ndarray | Sequence | None,
    generator: Any | None,
    model_path: str | None,
    device: str,
) -> tuple[tuple[str, ...], list[Obstacle], Any, CharacterBatch]:
    """What Waypoints-v0 and its vector env are made of, checked once: the caption pool, the
    obstacles, the generator and the batch of characters it streams."""
    pool = validate_text_pool(text_pool)
    checked = validate_obstacles(obstacles)
    return pool, checked, make_generator(generator, model_path, device), CharacterBatch(config, checked)
