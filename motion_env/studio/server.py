"""The studio's web server: a viser page, a player thread, and the glue between them.

:class:`Studio` owns the :class:`viser.ViserServer` (which serves the page and its web client from
the wheel), the :class:`~motion_env.studio.session.StudioSession`, the scene and the control
panel. One player thread emits frames on a clock (20 frames per second times the playback speed)
and draws them; the browser's events arrive on viser's threads and go to the session, which
orders them between frames.

Real time: when a frame (generator step and drawing) takes longer than its slot, the clock does
not try to catch up by bursting; after :data:`MAX_LAG` seconds of lag it starts again from now
and the page says "behind" (the motion then plays slower than real time, never in jumps).
"""

from __future__ import annotations

import contextlib
import io
import socket
import tempfile
import threading
import time
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import viser

from motion_env.motion.skeleton import FPS
from motion_env.studio.geometry import floor_point, followed_camera
from motion_env.studio.panel import CLICK_MODES, ControlPanel, notify
from motion_env.studio.session import StudioSession
from motion_env.studio.view import SceneView

__all__ = ["MAX_LAG", "Studio"]

MAX_LAG = 0.25  # seconds behind the clock before it gives up catching up
_NUMBERS_EVERY = 5  # frames between updates of the live numbers (4 a second)
_FOLLOW_EVERY = 2  # frames between camera moves when the camera follows
# viser 1.1 sets an asyncio.Event of a tab's message buffer from the thread that sends (our
# player thread) while its event loop may be changing the event's waiters (a tab connecting or
# closing): the set then fails with "deque mutated during iteration" (seen once in CI, as a tab
# closed). A frame whose drawing meets that race is skipped, not the player thread ended: the
# next frame sends the whole scene again.
_VISER_RACE = "during iteration"


def _floor_of_drag(event: viser.SceneNodeDragEvent) -> np.ndarray | None:
    """Where the pointer of a drag is over the floor: the ray from the tab's camera through the
    drag's point (which viser gives on a plane facing the camera) meets y = 0 there."""
    eye = np.asarray(event.client.camera.position, np.float64)
    return floor_point(eye, np.asarray(event.end_position, np.float64) - eye)


def _follow_camera(camera: viser.CameraHandle, target: np.ndarray) -> None:
    """Move one tab's camera over `target` (:func:`followed_camera`).

    viser's position setter moves the look-at point with the eye, so the eye is set first and the
    look-at second (then a no-op): set the other way round, the look-at would move twice. A tab
    that has not reported its camera yet is left alone (viser has no camera to read for it).
    """
    try:
        position, look_at = followed_camera(camera.position, camera.look_at, target)
    except AssertionError:
        return
    with camera.client.atomic():
        camera.position = position
        camera.look_at = look_at


class Studio:
    """A studio for the characters of `captions`, served on `host`:`port` once :meth:`start` runs.

    Args:
        generator: a :class:`motion_env.MotionGenerator`.
        captions: one caption per character (several make a crowd).
        seed: seed of the stream.
        host: interface to listen on; the default serves this machine only.
        port: TCP port (0: any free one; :attr:`url` tells which).
    """

    def __init__(
        self,
        generator: Any,
        captions: Sequence[str],
        seed: int = 0,
        host: str = "127.0.0.1",
        port: int = 8080,
    ) -> None:
        self.session = StudioSession(generator, captions, seed)
        self.host, self.port = host, port
        self.speed = 1.0
        self.server: viser.ViserServer | None = None
        self.recording_from: int | None = None
        self.frames_played = 0
        self.skipped_draws = 0  # frames not drawn: viser's event race (_VISER_RACE)
        self.play_seconds = 0.0  # wall time spent playing
        self._playing = threading.Event()
        self._playing.set()
        self._step_request = threading.Event()
        # Held while a frame is made: a pause waits for the frame in flight, so once
        # set_playing(False) returns the episode stands still (re-entrant: a frame may pause).
        self._frame_lock = threading.RLock()
        self._stop = threading.Event()
        self._restart = threading.Event()
        self._thread: threading.Thread | None = None
        self._tick_times: deque[float] = deque(maxlen=2 * FPS)
        self._last_slip = -1e9
        self._strokes: dict[int, list[np.ndarray]] = {}  # paths being drawn, per tab

    # ------------------------------------------------------------------ life cycle
    @property
    def url(self) -> str:
        host = "localhost" if self.host in ("127.0.0.1", "0.0.0.0", "::") else self.host
        return f"http://{host}:{self.port}"

    def start(self) -> str:
        """Open the server and start playing; returns the page's URL."""
        # viser prints a banner of its own; the command line prints the URL in its words.
        with contextlib.redirect_stdout(io.StringIO()):
            server = viser.ViserServer(
                host=self.host, port=self.port, label="motion-env studio", verbose=False
            )
        self.server = server
        self.port = server.get_port()
        count = self.session.num_characters
        self.scene = SceneView(server, count, self._on_drag_waypoint)
        self.panel = ControlPanel(self)
        # A front-left view of the start (the characters face +Z, their left is +X), wider for a crowd.
        reach = max(1.0, count * 0.4)
        server.initial_camera.position = (4.0 * reach, 2.5 * reach, 5.0 * reach)
        server.initial_camera.look_at = (0.0, 0.9, 0.0)
        server.scene.on_click()(self._on_floor_click)
        self.scene.floor.on_drag("left", modifier="shift")(self._on_floor_drag)
        self.scene.draw(self.session.snapshot())
        self._thread = threading.Thread(target=self._play_loop, name="studio-player", daemon=True)
        self._thread.start()
        return self.url

    def stop(self) -> None:
        """Stop the player and the server, and free the port. Safe to call twice."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
            self._thread = None
        if self.server is not None:
            server, self.server = self.server, None
            # viser says "Server stopped" on stdout; the command line has its own last word.
            with contextlib.redirect_stdout(io.StringIO()):
                server.stop()
            _wait_until_free(self.host, self.port)

    def serve_forever(self) -> None:
        """Block until Ctrl-C (KeyboardInterrupt, raised to the caller) or :meth:`stop`."""
        while not self._stop.wait(0.2):
            pass

    # ------------------------------------------------------------------ playback
    @property
    def playing(self) -> bool:
        return self._playing.is_set()

    def set_playing(self, playing: bool) -> None:
        if playing:
            self._restart.set()  # the pause is no lag to catch up on
            self._playing.set()
        else:
            self._playing.clear()
            with self._frame_lock:  # the frame in flight, if any, ends first
                pass
        self.panel.show_playing(playing)

    def step_once(self) -> None:
        """One frame, then paused."""
        self.set_playing(False)
        self._step_request.set()

    def restart_clock(self) -> None:
        self._restart.set()

    @property
    def fps(self) -> float:
        """Frames per second over the last two seconds of play."""
        times = self._tick_times
        if len(times) < 2 or times[-1] - times[0] <= 0:
            return 0.0
        return (len(times) - 1) / (times[-1] - times[0])

    def _play_loop(self) -> None:
        due = last = time.perf_counter()
        while not self._stop.is_set():
            now = time.perf_counter()
            if self.playing:
                self.play_seconds += now - last
            last = now
            stepping = self._step_request.is_set()
            if not (self.playing or stepping):
                self._tick_times.clear()
                self._stop.wait(0.02)
                due = time.perf_counter()
                continue
            self._step_request.clear()
            if self._restart.is_set():
                self._restart.clear()
                due = now
            with self._frame_lock:
                if not (self.playing or stepping):
                    continue  # paused while this tick waited
                self._frame()
            done = time.perf_counter()
            if self.playing:
                self.frames_played += 1
                self._tick_times.append(done)
            due += 1.0 / (FPS * max(self.speed, 1e-3))
            if due > done:
                self._stop.wait(due - done)
            elif done - due > MAX_LAG:
                due, self._last_slip = done, done

    def _frame(self) -> None:
        """One tick: the next frame of everyone, drawn (:meth:`_draw`)."""
        snap = self.session.tick()
        try:
            self._draw(snap)
        except RuntimeError as exc:
            if _VISER_RACE not in str(exc):
                raise
            self.skipped_draws += 1

    def _draw(self, snap: Any) -> None:
        """The frame `snap` on every tab; the numbers and notices now and then."""
        self.scene.draw(snap)
        if snap.frame % _NUMBERS_EVERY == 0:
            behind = time.perf_counter() - self._last_slip < 2.0
            self.panel.show_numbers(self.session.stats(self.panel.selected), self.fps, behind)
        if self.panel.follow.value and snap.frame % _FOLLOW_EVERY == 0 and self.server is not None:
            i, robot = self.panel.selected, snap.robot
            target = robot.root if robot is not None and robot.character == i else snap.joints[i, 0]
            for client in self.server.get_clients().values():
                _follow_camera(client.camera, target)
        notices = self.session.pop_notices()
        if notices and self.server is not None:
            for client in self.server.get_clients().values():
                for text in notices:
                    notify(client, "Note", text)

    # ------------------------------------------------------------------ the floor
    def _on_floor_click(self, event: viser.SceneClickEvent) -> None:
        point = floor_point(event.ray_origin, event.ray_direction)
        if point is None:
            notify(
                event.client, "Not on the floor", "Click on the floor grid to place something.", error=True
            )
            return
        i, mode = self.panel.selected, self.panel.click_mode.value
        try:
            if mode == CLICK_MODES[0]:
                seconds = float(self.panel.waypoint_seconds.value)
                self.session.add_waypoint(i, point, seconds or None)
            elif mode == CLICK_MODES[1]:
                self.session.add_obstacle(point, float(self.panel.obstacle_radius.value))
            elif mode == CLICK_MODES[2]:
                self.session.set_goal(i, point)
            else:
                panel = self.panel
                self.session.set_joint_target(
                    i,
                    panel.target_joint.value,
                    point,
                    float(panel.target_height.value),
                    float(panel.target_seconds.value),
                )
        except (ValueError, IndexError) as exc:
            what = mode if mode == CLICK_MODES[3] else mode.split()[0]
            notify(event.client, f"No {what} placed", str(exc), error=True)

    def _on_floor_drag(self, event: viser.SceneNodeDragEvent) -> None:
        """Shift + drag on the floor draws a path; on release it becomes the route."""
        stroke = self._strokes.setdefault(event.client_id, [])
        if event.phase == "start":
            stroke.clear()
            stroke.append(np.asarray(event.start_position, np.float64)[[0, 2]])
        point = _floor_of_drag(event)
        if point is not None:
            stroke.append(point)
        if event.phase != "end":
            return
        points = self._strokes.pop(event.client_id, [])
        if len(points) < 2:
            return
        try:
            count = self.session.set_path(self.panel.selected, np.array(points))
            notify(event.client, "Path drawn", f"{count} waypoints, every 0.5 m")
        except (ValueError, IndexError) as exc:
            notify(event.client, "Path not used", str(exc), error=True)

    def _on_drag_waypoint(self, i: int, j: int, event: viser.SceneNodeDragEvent) -> None:
        point = _floor_of_drag(event)
        if point is None:
            return
        if event.phase != "end":
            event.target.position = (float(point[0]), 0.12, float(point[1]))
            return
        try:
            self.session.move_waypoint(i, j, point)
        except (ValueError, IndexError) as exc:
            notify(event.client, "Waypoint not moved", str(exc), error=True)

    # ------------------------------------------------------------------ keep what you made
    def judge(self, index: int, seconds: float) -> str:
        """The MuJoCo plausibility verdict of character `index`'s last `seconds`, as markdown."""
        from motion_env.replay import evaluate

        report = evaluate(self.session.clip(index, last_seconds=seconds))
        if not report["judged"]:
            return f"not judged: {report['summary']}"
        word = "**plausible**" if report["plausible"] else "**not plausible**"
        return f"last {seconds:g} s: {word}: {report['summary']}"

    def download(
        self, client: viser.ClientHandle | None, index: int, kind: str, robot: str = "unitree_g1"
    ) -> None:
        """Send character `index`'s episode to `client` as a file: "npz", "bvh" or a robot format
        of :data:`~motion_env.studio.keep.ROBOT_KINDS` (retargeted onto `robot`)."""
        from motion_env.studio.keep import clip_file

        if client is None:
            return
        motion = self.session.clip(index)
        name = f"studio_character{index + 1}_frame{self.session.frame}"
        if kind not in ("npz", "bvh"):
            name += f"_{robot}"
        filename, data = clip_file(motion, kind, name, robot)
        client.send_file_download(filename, data, save_immediately=True)

    def start_recording(self) -> None:
        self.recording_from = self.session.frame

    def stop_recording(self, client: viser.ClientHandle | None, index: int) -> None:
        """Render the frames since :meth:`start_recording` and send the .mp4 to `client`."""
        from motion_env.render.video import render_video

        start, self.recording_from = self.recording_from, None
        if start is None:
            raise ValueError("not recording: press Start recording first")
        frames = self.session.frame - start if self.session.frame > start else self.session.frame
        motion = self.session.clip(index, last_seconds=max(frames, 1) / FPS)
        obstacles = self.session.snapshot().obstacles
        note = None
        if client is not None:
            text = f"rendering {motion.num_frames} frames..."
            note = client.add_notification("Recording", text, loading=True, with_close_button=False)
        try:
            with tempfile.TemporaryDirectory() as folder:
                path = Path(folder) / f"studio_character{index + 1}.mp4"
                render_video(motion, path, obstacles=obstacles if len(obstacles) else None)
                data = path.read_bytes()
        finally:
            if note is not None:
                note.remove()
        if client is not None:
            client.send_file_download(path.name, data, save_immediately=True)


def _wait_until_free(host: str, port: int, seconds: float = 5.0) -> None:
    """Return once a new server could listen on `port` again (viser closes its socket a moment
    after stop()). SO_REUSEADDR, as servers bind: the connections the server closed linger in
    TIME_WAIT for a minute, which blocks a plain bind but not a new listener."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        with socket.socket() as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                probe.bind((host, port))
                return
            except OSError:
                time.sleep(0.05)
