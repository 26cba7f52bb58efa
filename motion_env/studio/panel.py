"""The studio's control panel (viser GUI) and what each control does.

The controls are shared by every open tab: a caption applied in one tab shows in the others.
Each callback runs on one of viser's worker threads; it hands the change to the
:class:`~motion_env.studio.session.StudioSession` (which orders it between two frames) or to the
:class:`~motion_env.studio.server.Studio` (playback), and reports a mistake to the tab that made it
as a notification, never as a traceback.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import viser

from motion_env.motion.skeleton import FPS, JOINT_NAMES
from motion_env.studio.keep import ROBOT_KINDS
from motion_env.studio.robot_view import ROBOT_CHOICES
from motion_env.studio.session import HEAD_LIMIT_RANGE, MAX_TARGET_HEIGHT, MIN_TARGET_SECONDS, StudioSession
from motion_env.studio.state import Stats

__all__ = ["CLICK_MODES", "ControlPanel", "notify"]

CLICK_MODES = ("waypoint", "obstacle", "goal (A* agent)", "joint target")
SHOW_CHOICES = ("character", *ROBOT_CHOICES)
JUDGE_SECONDS = 5.0
# The dropdowns' hints (shown on hover).
SHOW_HINT = (
    "the character, or the character retargeted onto a robot frame by frame "
    '(needs the robots extra: pip install -c constraints.txt -e ".[robots]")'
)
CLICK_HINT = (
    "what a click on the floor places; drag a waypoint to move it; shift + drag on the floor draws a path"
)
ROBOT_FORMAT_HINT = (
    "csv: the project's; lafan_csv: LAFAN-style (mjlab's csv_to_npz); mjlab: its tracking .npz; "
    "gmr: GMR's .pkl"
)


def notify(client: viser.ClientHandle | None, title: str, body: str, error: bool = False) -> None:
    """A notification in one tab (the one that asked), closing by itself after a while."""
    if client is None:
        return
    client.add_notification(title, body, auto_close_seconds=8.0, color="red" if error else None)


def reported(title: str) -> Callable:
    """Decorate a GUI callback: a ValueError / IndexError / OSError becomes a notification."""

    def wrap(func: Callable[[viser.GuiEvent], None]) -> Callable[[viser.GuiEvent], None]:
        def run(event: viser.GuiEvent) -> None:
            try:
                func(event)
            except (ValueError, IndexError, OSError, RuntimeError) as exc:
                notify(event.client, title, str(exc), error=True)

        return run

    return wrap


def _dropdown(
    gui: viser.GuiApi, label: str, choices: Sequence[str], hint: str, initial: str | None = None
) -> viser.GuiDropdownHandle:
    """A dropdown of `choices` starting on `initial` (the first choice by default)."""
    return gui.add_dropdown(label, tuple(choices), initial_value=initial or choices[0], hint=hint)


class Playback(Protocol):
    """What the panel drives: :class:`~motion_env.studio.server.Studio` (a protocol here, so the
    panel does not import the server that builds it)."""

    server: Any
    session: StudioSession
    playing: bool
    speed: float
    recording_from: int | None

    def set_playing(self, playing: bool) -> None: ...
    def step_once(self) -> None: ...
    def restart_clock(self) -> None: ...
    def judge(self, index: int, seconds: float) -> str: ...
    def download(self, client: Any, index: int, kind: str, robot: str = ...) -> None: ...
    def start_recording(self) -> None: ...
    def stop_recording(self, client: Any, index: int) -> None: ...


class ControlPanel:
    """Builds the GUI of `studio` and keeps its numbers up to date."""

    def __init__(self, studio: Playback) -> None:
        self.studio = studio
        gui = studio.server.gui
        gui.configure_theme(control_layout="floating", control_width="large", show_logo=False)
        self._add_character(gui, studio.session)
        self._add_route(gui)
        self._add_joint_target(gui)
        self._add_playback(gui, studio.session)
        self._add_numbers(gui)
        self._add_keep(gui)
        self._wire()

    # ------------------------------------------------------------------ the folders
    def _add_character(self, gui: viser.GuiApi, session: StudioSession) -> None:
        with gui.add_folder("Character"):
            self.character = _dropdown(
                gui,
                "Character",
                [str(i + 1) for i in range(session.num_characters)],
                "which character the controls below act on",
            )
            self.character.visible = session.num_characters > 1
            self.caption = gui.add_text(
                "Caption", session.snapshot().captions[0], hint="what the character does"
            )
            self.apply_caption = gui.add_button(
                "Apply caption", hint="from the next token on (0.2 s), no pop"
            )
            self.show = _dropdown(gui, "Show", SHOW_CHOICES, SHOW_HINT)

    def _add_route(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Route"):
            self.click_mode = _dropdown(gui, "Click places", CLICK_MODES, CLICK_HINT)
            self.waypoint_seconds = gui.add_number(
                "Reach in (s)",
                0.0,
                min=0.0,
                max=600.0,
                step=0.5,
                hint="0: untimed (at the caption's pace); else reached this many seconds after the click",
            )
            self.obstacle_radius = gui.add_slider("Obstacle radius (m)", 0.2, 3.0, 0.1, 0.6)
            self.clear_route = gui.add_button("Clear route", hint="no waypoints: the caption alone steers")
            self.clear_goal = gui.add_button("Stop the A* agent", hint="its last plan stays as the route")
            self.clear_obstacles = gui.add_button("Clear obstacles")

    def _add_joint_target(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Joint target"):
            self.target_joint = _dropdown(
                gui,
                "Joint",
                JOINT_NAMES,
                'with "Click places: joint target", a click on the floor puts this joint above it',
                initial="right_wrist",
            )
            # No min / max here: the session refuses a height out of range and the page says why.
            self.target_height = gui.add_number(
                "Height (m)", 1.2, step=0.05, hint=f"above the floor, 0 to {MAX_TARGET_HEIGHT:g} m"
            )
            self.target_seconds = gui.add_number(
                "Target in (s)",
                1.0,
                min=MIN_TARGET_SECONDS,
                max=600.0,
                step=0.5,
                hint=f"met exactly this long after the click (at least {MIN_TARGET_SECONDS:g} s)",
            )
            self.clear_targets = gui.add_button(
                "Clear joint targets", hint="the selected character's joints are free again"
            )
            low, high = HEAD_LIMIT_RANGE
            self.head_limit = gui.add_number(
                "Head at most (m)",
                0.0,
                step=0.05,
                hint=f"0: no limit; else {low:g} to {high:g} m (the knees bend)",
            )
            self.apply_head_limit = gui.add_button(
                "Apply head limit", hint="from half a second on, for the selected character"
            )

    def _add_playback(self, gui: viser.GuiApi, session: StudioSession) -> None:
        with gui.add_folder("Playback"):
            self.play = gui.add_button("Pause", hint="play / pause")
            self.step = gui.add_button("Step", hint="one frame (1/20 s), then pause")
            self.seed = gui.add_number("Seed", int(session.seed), min=0, max=2**31 - 1, step=1)
            self.reset = gui.add_button(
                "Reset", hint="a new episode with this seed: same captions, route, obstacles"
            )
            self.speed = gui.add_slider(
                "Speed", 0.25, 2.0, 0.25, 1.0, hint="playback speed (1 = real time, 20 fps)"
            )
            self.follow = gui.add_checkbox(
                "Follow with the camera",
                True,
                hint="the view turns about the selected character and moves with it (untick to pan)",
            )

    def _add_numbers(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Numbers"):
            self.numbers = gui.add_markdown("")
            self.judge = gui.add_button(
                f"Judge the last {JUDGE_SECONDS:g} s",
                hint="MuJoCo humanoid replay: is it physically plausible?",
            )
            self.verdict = gui.add_markdown("")

    def _add_keep(self, gui: viser.GuiApi) -> None:
        with gui.add_folder("Keep", expand_by_default=False):
            self.save_npz = gui.add_button("Download .npz", hint="the episode so far (Motion.save)")
            self.save_bvh = gui.add_button(
                "Download .bvh", hint="the episode so far on the canonical skeleton"
            )
            self.robot_format = _dropdown(gui, "Robot format", ROBOT_KINDS, ROBOT_FORMAT_HINT)
            self.save_robot = gui.add_button(
                "Download robot file",
                hint="the episode retargeted onto the robot shown (else the Unitree G1), 50 fps",
            )
            self.record = gui.add_button("Start recording", hint="then stop: an .mp4 of the recorded frames")

    # ------------------------------------------------------------------ callbacks
    @property
    def selected(self) -> int:
        return int(self.character.value) - 1

    def _wire(self) -> None:
        studio, session = self.studio, self.studio.session

        # Buttons that only hand one change to the session, with the title of the notification
        # that reports a mistake.
        for button, title, change in (
            (self.clear_route, "Route", lambda: session.clear_route(self.selected)),
            (self.clear_goal, "A* agent", lambda: session.clear_goal(self.selected)),
            (self.clear_obstacles, "Obstacles", session.clear_obstacles),
            (self.clear_targets, "Joint targets", lambda: session.clear_joint_targets(self.selected)),
        ):
            button.on_click(reported(title)(lambda _, change=change: change()))
        for button, kind in ((self.save_npz, "npz"), (self.save_bvh, "bvh")):
            button.on_click(
                reported("Download")(
                    lambda event, kind=kind: studio.download(event.client, self.selected, kind)
                )
            )

        @self.save_robot.on_click
        @reported("Robot file")
        def _(event: viser.GuiEvent) -> None:
            robot = ROBOT_CHOICES.get(self.show.value, "unitree_g1")
            studio.download(event.client, self.selected, self.robot_format.value, robot)

        @self.character.on_update
        def _(event: viser.GuiEvent) -> None:
            self.caption.value = session.snapshot().captions[self.selected]
            self._show_robot(event.client)

        self.show.on_update(lambda event: self._show_robot(event.client))

        @self.apply_caption.on_click
        @reported("Caption not applied")
        def _(event: viser.GuiEvent) -> None:
            text = session.set_caption(self.selected, self.caption.value)
            notify(event.client, "Caption applied", _short(text, 120))

        @self.apply_head_limit.on_click
        @reported("Head limit not applied")
        def _(event: viser.GuiEvent) -> None:
            height = float(self.head_limit.value)
            session.set_head_limit(self.selected, height or None)
            text = f"the head stays below {height:g} m" if height else "no head limit"
            notify(event.client, "Head limit", text)

        @self.reset.on_click
        @reported("Reset")
        def _(_: viser.GuiEvent) -> None:
            session.reset(int(self.seed.value))
            studio.restart_clock()

        @self.judge.on_click
        @reported("Judge")
        def _(_: viser.GuiEvent) -> None:
            self.verdict.content = "judging..."
            self.verdict.content = studio.judge(self.selected, JUDGE_SECONDS)

        @self.record.on_click
        @reported("Recording")
        def _(event: viser.GuiEvent) -> None:
            if studio.recording_from is None:
                studio.start_recording()
                self.record.label = "Stop recording"
            else:
                self.record.label = "Start recording"
                studio.stop_recording(event.client, self.selected)

        @self.speed.on_update
        def _(_: viser.GuiEvent) -> None:
            studio.speed = float(self.speed.value)

        self.play.on_click(lambda _: studio.set_playing(not studio.playing))
        self.step.on_click(lambda _: studio.step_once())

    def _show_robot(self, client: viser.ClientHandle | None) -> None:
        """The robot view of the selected character as the "Show" dropdown says; without the
        robots extra the tab is told why and the character stays."""
        try:
            self.studio.session.set_robot(ROBOT_CHOICES.get(self.show.value), self.selected)
        except ValueError as exc:
            notify(client, "No robot view", str(exc), error=True)
            self.show.value = SHOW_CHOICES[0]  # which comes back here and turns the robot off

    # ------------------------------------------------------------------ numbers
    def show_playing(self, playing: bool) -> None:
        self.play.label = "Pause" if playing else "Play"

    def show_numbers(self, stats: Stats, fps: float, behind: bool) -> None:
        """The live numbers of the selected character (called by the player thread a few times a second)."""
        rate = f"{fps:.1f}" + (" (behind: slower than real time)" if behind else "")
        if stats.to_next_m is None:
            route = "no route"
        elif stats.waypoints_left == 0:
            route = f"last waypoint reached ({stats.to_next_m:.2f} m)"
        else:
            route = f"{stats.to_next_m:.2f} m to the next waypoint ({stats.waypoints_left} left)"
        ahead = f" ({stats.targets_left} ahead)" if stats.targets_left else ""
        head = "" if stats.head_limit is None else f" · head at most {stats.head_limit:g} m"
        self.numbers.content = (
            f"**frame** {stats.frame} ({stats.frame / FPS:.1f} s) · **fps** {rate}  \n"
            f"**step** {stats.step_ms:.1f} ms (slowest in the last second {stats.step_ms_max:.1f} ms)  \n"
            f"**speed** {stats.speed_mps:.2f} m/s · {route}  \n"
            f"**joint targets** {stats.control}{ahead}{head}"
        )


def _short(text: str, length: int) -> str:
    return text if len(text) <= length else text[: length - 1] + "…"
