"""The studio's state and its one frame per tick, without any web page.

A :class:`StudioSession` holds B characters of one generator stream
(:class:`motion_env.generation.streaming.MotionStream`), their captions, routes, goals, joint targets,
the arena's obstacles and what has been generated so far. The page (:mod:`motion_env.studio.server`)
calls :meth:`StudioSession.tick` from its player thread, once per frame, and the edit methods
from the threads that serve the browser's events; one lock orders them, so a change lands between
two frames, which the stream turns into a change without a pop (from its next token on).

Everything a user can get wrong arrives here as a ValueError (or IndexError) whose message the
page shows as it is; nothing is changed then.
"""

from __future__ import annotations

import threading
import time
import warnings
from collections import deque
from collections.abc import Sequence
from typing import Any

import numpy as np

from motion_env.generation.request import check_feasible, check_text
from motion_env.joint_targets import JointTargets
from motion_env.motion.skeleton import FPS, NUM_JOINTS
from motion_env.motion.types import Motion
from motion_env.objectives import HeightLimit
from motion_env.studio.agent import GoalAgent
from motion_env.studio.geometry import resample_path
from motion_env.studio.robot_view import RobotFigure
from motion_env.studio.route_progress import ARRIVE_RADIUS, Route
from motion_env.studio.state import (
    Snapshot,
    Stats,
    check_index,
    check_joint,
    check_number,
    check_xz,
    start_positions,
)

__all__ = ["MAX_CHARACTERS", "StudioSession"]

MAX_CHARACTERS = 16  # a small crowd; the batched stream costs grow with it (see docs/benchmarks.md, "Studio")
MAX_HISTORY_FRAMES = 20 * 60 * FPS  # 20 minutes kept per session (about 6 MB per character)
TRAIL_FRAMES = 60 * FPS  # the trail drawn behind each character: its last minute
MAX_OBSTACLE_RADIUS = 5.0
PATH_SPACING = 0.5  # metres between the waypoints of a drawn path
MAX_TARGET_HEIGHT = 2.5  # metres: joint targets are placed from the floor up to this height
MIN_TARGET_SECONDS = 0.5  # a joint target this far ahead (10 frames) is met exactly at its frame
MAX_TARGET_SECONDS = 600.0
TARGET_SHOWN_FRAMES = FPS  # a met joint target stays drawn (greyed) this long after its frame
HEAD_LIMIT_RANGE = (0.6, MAX_TARGET_HEIGHT)  # metres: a lower head would need the body folded up
_FOREVER = 2**31 - 1  # the open end of a height limit, in frames


class _Character:
    """The per-character state of a session."""

    def __init__(self, caption: str, start: np.ndarray) -> None:
        self.caption = caption
        self.start = start  # (3,) x, z, heading
        self.route = Route()
        self.agent: GoalAgent | None = None
        self.captions_log: list[tuple[int, str]] = [(0, caption)]  # (frame, caption) changes
        self.targets = JointTargets.empty()  # frames of the character's episode
        self.head_limit: float | None = None  # metres


class StudioSession:
    """B characters streamed one frame per :meth:`tick`, editable from other threads between ticks.

    Args:
        generator: a :class:`motion_env.MotionGenerator` (its :meth:`stream` and :meth:`encode_text`
            are all that is used).
        captions: one caption per character (1 to :data:`MAX_CHARACTERS`).
        seed: seed of the stream; :meth:`reset` can change it.
    """

    def __init__(self, generator: Any, captions: Sequence[str], seed: int = 0) -> None:
        if isinstance(captions, str):
            captions = [captions]
        captions = [check_text(c, f"caption of character {i + 1}") for i, c in enumerate(captions)]
        if not 1 <= len(captions) <= MAX_CHARACTERS:
            raise ValueError(f"a studio holds 1 to {MAX_CHARACTERS} characters, got {len(captions)}")
        self._gen = generator
        self._lock = threading.RLock()
        starts = start_positions(len(captions))
        self._chars = [_Character(c, starts[i]) for i, c in enumerate(captions)]
        self._obstacles: list[tuple[float, float, float]] = []
        self._version = 0
        self._notices: deque[str] = deque(maxlen=20)
        self.seed = self._check_seed(seed)
        self._robot: RobotFigure | None = None  # the robot view's retargeter, of one character
        self._robot_index, self._robot_pose = 0, None
        self._open_stream()

    # ------------------------------------------------------------------ episode
    @staticmethod
    def _check_seed(seed: Any) -> int:
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or not 0 <= seed < 2**31:
            raise ValueError(f"the seed must be a whole number from 0 to {2**31 - 1}, got {seed!r}")
        return int(seed)

    def _open_stream(self) -> None:
        """A new stream for everyone from frame 0 (held lock or not yet shared)."""
        chars = self._chars
        for c in chars:
            c.route.restart()
            c.captions_log = [(0, c.caption)]
            c.targets = JointTargets.empty()  # frames of the old episode
            if c.agent is not None:
                c.agent = GoalAgent(c.agent.goal, self._obstacles)
        routes = [c.route.ahead(0) for c in chars]
        starts = np.stack([c.start for c in chars])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self._stream = self._gen.stream(
                [c.caption for c in chars], waypoints=routes, starts=starts, seed=self.seed, infeasible="warn"
            )
        self._note_warnings(caught)
        for i, c in enumerate(chars):
            if c.head_limit is not None:
                self._send_head_limit(i, 0)
        self._frame = 0
        self._joints = np.zeros((len(chars), NUM_JOINTS, 3), np.float32)
        self._history: deque[np.ndarray] = deque(maxlen=MAX_HISTORY_FRAMES)  # (B, 22, 3) per frame
        self._pelvis: deque[np.ndarray] = deque(maxlen=TRAIL_FRAMES)  # (B, 2) floor x, z per frame
        self._step_ms: deque[float] = deque(maxlen=FPS)
        self._version += 1
        if self._robot is not None:
            self._robot.reset()
        self._tick_once()  # frame 0: something to draw before the first play

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode: everyone back at their start, same captions, routes, goals and
        obstacles; `seed` (default: the current one) seeds the new stream."""
        with self._lock:
            if seed is not None:
                self.seed = self._check_seed(seed)
            self._open_stream()

    # ------------------------------------------------------------------ the frame
    def tick(self) -> Snapshot:
        """Emit the next frame of every character; returns what to draw."""
        with self._lock:
            self._tick_once()
            return self._snapshot()

    def _tick_once(self) -> None:
        t0 = time.perf_counter()
        joints = np.asarray(self._stream.step(), np.float32)  # (B, 22, 3)
        self._step_ms.append(1000.0 * (time.perf_counter() - t0))
        self._joints = joints
        self._history.append(joints)
        self._pelvis.append(joints[:, 0, [0, 2]].astype(np.float64))
        self._frame = int(self._stream.frame_index[0])
        frame = self._frame - 1  # the frame just emitted
        if self._robot is not None:
            self._robot_pose = self._robot.step(joints[self._robot_index], self._robot_index)
        for i, c in enumerate(self._chars):
            pelvis = joints[i, 0, [0, 2]].astype(np.float64)
            if c.route.advance(pelvis, frame):
                self._version += 1
            # The agent looks again once per token (4 frames): re-planning is what costs.
            if c.agent is not None and frame % 4 == 0:
                self._update_agent(i, pelvis)
            if len(c.targets):
                met = (c.targets.frames == frame).any()  # drawn grey from now on
                shown = c.targets.between(frame - TARGET_SHOWN_FRAMES, None)
                if met or len(shown) < len(c.targets):
                    c.targets = shown
                    self._version += 1

    def _update_agent(self, i: int, pelvis: np.ndarray) -> None:
        c = self._chars[i]
        try:
            plan = c.agent.update(pelvis)
        except ValueError as exc:
            c.agent = None
            self._version += 1
            self._notices.append(f"character {i + 1}: the A* agent gave up: {exc}")
            return
        if plan is not None:
            c.route.replace(plan)
            self._send_route(i)

    def _send_route(self, i: int) -> None:
        """Give character i's route ahead to the stream (held lock)."""
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self._stream.set_waypoints(self._chars[i].route.ahead(self._frame), index=i)
        self._note_warnings(caught)
        self._version += 1

    def _note_warnings(self, caught: list) -> None:
        for w in caught:
            self._notices.append(str(w.message))

    # ------------------------------------------------------------------ edits
    @property
    def num_characters(self) -> int:
        return len(self._chars)

    def set_robot(self, robot: str | None, index: int = 0) -> None:
        """Show character `index` retargeted onto `robot` (a known robot's name) from its next
        frame on, or no robot (None). ValueError without the ``robots`` extra."""
        i = check_index(index, len(self._chars))
        same = self._robot is not None and self._robot.name == robot
        figure = None if robot is None else self._robot if same else RobotFigure(robot)
        with self._lock:
            if figure is not None and (figure is not self._robot or i != self._robot_index):
                figure.reset()  # another character, or another robot: a first frame
            self._robot, self._robot_index = figure, i
            self._robot_pose = None if figure is None else figure.step(self._joints[i], i)

    def set_caption(self, index: int, text: str) -> str:
        """Give character `index` a new caption (from its next token on); returns it, stripped."""
        text = check_text(text, "the caption")
        i = check_index(index, len(self._chars))
        # A caption never seen costs the text encoder a few ms (seconds for the first one of the
        # process): encode it here, outside the lock, so that the frames keep coming meanwhile.
        # What the model says about it (another language, nothing it knows) goes to the page.
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            self._gen.encode_text([text])
        with self._lock:
            self._notices.extend(f"character {i + 1}: {w.message}" for w in caught)
        with self._lock:
            self._stream.set_text(text, index=i)
            c = self._chars[i]
            c.caption = text
            c.captions_log.append((self._frame, text))
        return text

    def add_waypoint(self, index: int, xz: Sequence[float], seconds: float | None = None) -> int:
        """Append a waypoint to character `index`'s route; returns its number (1-based).

        Args:
            xz: the point on the floor.
            seconds: reach it this many seconds from now (None or 0: untimed, at the caption's pace).
        """
        i = check_index(index, len(self._chars))
        point = check_xz(xz, "waypoint")
        if seconds is not None and not (np.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"a waypoint's time must be a number of seconds >= 0, got {seconds!r}")
        with self._lock:
            c = self._chars[i]
            frame = None if not seconds else self._frame + max(1, round(seconds * FPS))
            route = c.route.copy()
            route.add(point, frame)
            if frame is not None:
                here = self._joints[i, 0, [0, 2]]
                try:
                    check_feasible(route.ahead(self._frame), here, "raise", self._frame)
                except ValueError as exc:
                    reason = str(exc).split(". Times are")[0].split("asks for", 1)[-1]
                    raise ValueError(
                        f"waypoint {len(route)} in {seconds:g} s is too fast: it asks for{reason}"
                    ) from None
            c.agent = None  # the user takes the route over from the A* agent
            c.route.add(point, frame)
            self._send_route(i)
            return len(route)

    def move_waypoint(self, index: int, waypoint: int, xz: Sequence[float]) -> None:
        """Move waypoint `waypoint` (0-based) of character `index` to `xz`."""
        i = check_index(index, len(self._chars))
        point = check_xz(xz, "waypoint")
        with self._lock:
            c = self._chars[i]
            c.route.move(int(waypoint), point)
            c.agent = None
            self._send_route(i)

    def set_path(self, index: int, points: np.ndarray | Sequence) -> int:
        """Replace character `index`'s route by a drawn path (N, 2), resampled every 0.5 m;
        returns the number of waypoints."""
        i = check_index(index, len(self._chars))
        pts = np.asarray(points, np.float64).reshape(-1, 2)
        for p in pts:
            check_xz(p, "path point")
        route = resample_path(pts, PATH_SPACING)
        with self._lock:
            c = self._chars[i]
            c.route.replace(route)
            c.agent = None
            self._send_route(i)
        return len(route)

    def clear_route(self, index: int) -> None:
        """No route for character `index`: it follows its caption alone."""
        i = check_index(index, len(self._chars))
        with self._lock:
            c = self._chars[i]
            c.route.replace(None)
            c.agent = None
            self._send_route(i)

    def set_goal(self, index: int, xz: Sequence[float]) -> None:
        """Let the A* agent walk character `index` to `xz` around the obstacles (it re-plans as
        obstacles come and go, and when the character drifts off its plan)."""
        i = check_index(index, len(self._chars))
        goal = check_xz(xz, "goal")
        with self._lock:
            c = self._chars[i]
            agent = GoalAgent(goal, self._obstacles)
            plan = agent.update(self._joints[i, 0, [0, 2]].astype(np.float64))  # ValueError: no path
            c.agent = agent
            c.route.replace(plan)
            self._send_route(i)

    def clear_goal(self, index: int) -> None:
        """Stop the A* agent of character `index` (its last plan stays as the route)."""
        i = check_index(index, len(self._chars))
        with self._lock:
            self._chars[i].agent = None
            self._version += 1

    def add_obstacle(self, xz: Sequence[float], radius: float) -> None:
        """A circle obstacle; the A* agents re-plan around it."""
        centre = check_xz(xz, "obstacle")
        if not (np.isfinite(radius) and 0 < radius <= MAX_OBSTACLE_RADIUS):
            raise ValueError(
                f"an obstacle's radius must be in (0, {MAX_OBSTACLE_RADIUS:g}] m, got {radius!r}"
            )
        with self._lock:
            self._obstacles.append((float(centre[0]), float(centre[1]), float(radius)))
            self._obstacles_changed()

    def clear_obstacles(self) -> None:
        with self._lock:
            self._obstacles.clear()
            self._obstacles_changed()

    def _obstacles_changed(self) -> None:
        for c in self._chars:
            if c.agent is not None:
                c.agent.set_obstacles(self._obstacles)
        self._version += 1

    def set_joint_target(
        self,
        index: int,
        joint: str | int,
        xz: Sequence[float],
        height: float,
        seconds: float = 1.0,
    ) -> int:
        """Ask character `index`'s `joint` to be at (x, `height`, z) `seconds` from now; returns
        the episode frame it is met at.

        The character's earlier targets stay (a new one for the same joint and frame replaces it).
        At least :data:`MIN_TARGET_SECONDS` ahead, the stream meets it exactly at its frame, the
        joint easing into it over the half second before and out of it over the half second after.

        Args:
            joint: a name of :data:`motion_env.motion.skeleton.JOINT_NAMES` or its index.
            xz: the point on the floor under the target.
            height: metres above the floor, 0 to :data:`MAX_TARGET_HEIGHT`.
            seconds: from now, :data:`MIN_TARGET_SECONDS` to :data:`MAX_TARGET_SECONDS`.
        """
        i = check_index(index, len(self._chars))
        j = check_joint(joint)
        point = check_xz(xz, "joint target")
        y = check_number(height, 0.0, MAX_TARGET_HEIGHT, "a joint target's height", "m")
        delay = check_number(
            seconds,
            MIN_TARGET_SECONDS,
            MAX_TARGET_SECONDS,
            "a joint target's time",
            "seconds from now (sooner cannot be met exactly)",
        )
        with self._lock:
            frame = self._frame + max(1, round(delay * FPS))
            c = self._chars[i]
            c.targets = c.targets.with_entry(frame, j, (point[0], y, point[1]))
            self._send_targets(i)
            return frame

    def clear_joint_targets(self, index: int) -> None:
        """Character `index` has no joint targets any more (one being eased into lets go)."""
        i = check_index(index, len(self._chars))
        with self._lock:
            self._chars[i].targets = JointTargets.empty()
            self._send_targets(i)

    def _send_targets(self, i: int) -> None:
        """Give character i's joint targets ahead to the stream (held lock); the stream keeps
        those it has not met yet and is not surprised by the ones it already had."""
        ahead = self._chars[i].targets.between(self._frame, None)
        self._stream.set_joint_targets(ahead if len(ahead) else None, index=i)
        self._version += 1

    def set_head_limit(self, index: int, max_height: float | None) -> None:
        """Keep character `index`'s head at most `max_height` metres above the floor from half a
        second on (None: no limit); the limit stays across a reset."""
        i = check_index(index, len(self._chars))
        if max_height is not None:
            low, high = HEAD_LIMIT_RANGE
            max_height = check_number(max_height, low, high, "the head's height limit", "m")
        with self._lock:
            self._chars[i].head_limit = max_height
            self._send_head_limit(i, self._frame + round(MIN_TARGET_SECONDS * FPS))

    def _send_head_limit(self, i: int, first: int) -> None:
        """Give character i's head limit, from episode frame `first` on, to the stream (held lock)."""
        height = self._chars[i].head_limit
        limits = None
        if height is not None:
            limits = [HeightLimit(joint="head", max_height=height, frames=(first, _FOREVER))]
        self._stream.set_objectives(limits, index=i)

    # ------------------------------------------------------------------ reading
    @property
    def frame(self) -> int:
        return self._frame

    def snapshot(self) -> Snapshot:
        with self._lock:
            return self._snapshot()

    def _snapshot(self) -> Snapshot:
        pelvis = np.stack(self._pelvis)  # (N, B, 2)
        chars = self._chars
        return Snapshot(
            frame=self._frame,
            joints=self._joints.copy(),
            trails=[pelvis[:, i] for i in range(len(chars))],
            routes=[c.route.points.copy() for c in chars],
            next_waypoint=[c.route.next for c in chars],
            reached=[c.route.reached for c in chars],
            goals=[None if c.agent is None else c.agent.goal for c in chars],
            obstacles=np.array(self._obstacles, np.float64).reshape(-1, 3),
            captions=[c.caption for c in chars],
            version=(self._version, *(c.route.version for c in chars)),
            joint_targets=[c.targets.rows() for c in chars],
            robot=self._robot_pose if self._robot is not None else None,
        )

    def stats(self, index: int = 0) -> Stats:
        """The live numbers of character `index`."""
        i = check_index(index, len(self._chars))
        with self._lock:
            count = min(len(self._pelvis), FPS + 1)
            pelvis = np.stack([self._pelvis[k][i] for k in range(-count, 0)])  # (N, 2), the last second
            seconds = (len(pelvis) - 1) / FPS
            speed = float(np.linalg.norm(pelvis[-1] - pelvis[0]) / seconds) if seconds > 0 else 0.0
            c = self._chars[i]
            target = c.route.target()
            to_next = None if target is None else float(np.linalg.norm(pelvis[-1] - target))
            steps = list(self._step_ms) or [0.0]
            left = 0 if c.route.reached or not len(c.route) else len(c.route) - c.route.next
            targets = len(c.targets.between(self._frame, None))
            control = self._stream.control_summary(i)
            return Stats(
                self._frame, steps[-1], max(steps), speed, to_next, left, targets, control, c.head_limit
            )

    def pop_notices(self) -> list[str]:
        """Messages for the user since the last call (retimed waypoints, an agent that gave up)."""
        with self._lock:
            out = list(self._notices)
            self._notices.clear()
            return out

    def clip(self, index: int = 0, last_seconds: float | None = None) -> Motion:
        """What character `index` did this episode (or its last `last_seconds`) as a Motion.

        The caption is the current one; ``meta["captions"]`` lists every caption with the frame it
        was given at; ``waypoints`` are the route's, their times frames of the episode.
        """
        i = check_index(index, len(self._chars))
        with self._lock:
            joints = np.stack(self._history)[:, i]
            c = self._chars[i]
            first = self._frame - len(joints)  # frames dropped from a very long session
            log = " | ".join(f"{f}: {t}" for f, t in c.captions_log)
            waypoints = c.route.points.copy() if len(c.route) else None
            seed = self.seed
        if last_seconds is not None:
            keep = max(1, int(round(last_seconds * FPS)))
            first += max(0, len(joints) - keep)
            joints = joints[-keep:]
        meta = {"source": "motion-env studio", "seed": str(seed), "first_frame": str(first), "captions": log}
        return Motion(joints, fps=FPS, text=c.caption, waypoints=waypoints, meta=meta)

    def arrived(self, index: int, xz: Sequence[float], radius: float = ARRIVE_RADIUS) -> bool:
        """True when character `index`'s pelvis has passed within `radius` of `xz` this episode."""
        i = check_index(index, len(self._chars))
        with self._lock:
            pelvis = np.stack(self._history)[:, i, 0][:, [0, 2]]
        return bool((np.linalg.norm(pelvis - np.asarray(xz, np.float64), axis=1) < radius).any())
