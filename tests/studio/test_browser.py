"""The studio in a real browser: a caption and two waypoints set through the page reach the
character, and the figure is drawn.

Everything the user does goes through the page (typing, buttons, clicks on the 3-D floor); the
test reads the server's side (the session) to check what arrived, and a screenshot for what is
drawn. Skipped, with the reason, where viser, Playwright or Chromium is missing.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from motion_env.render.drawing import LEFT_COLOR, RIGHT_COLOR, hex_rgb

CHROMIUM = (
    os.environ.get("MOTION_ENV_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
)


def browser_missing() -> str | None:
    """Why the browser tests cannot run here, or None."""
    if importlib.util.find_spec("viser") is None:
        return 'viser is not installed (pip install -c constraints.txt -e ".[studio]")'
    if importlib.util.find_spec("playwright") is None:
        return "playwright is not installed (pip install playwright; the browser is the system's chromium)"
    if CHROMIUM is None:
        return "no chromium found (apt-get install chromium, or set MOTION_ENV_CHROMIUM=/path/to/it)"
    return None


pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(browser_missing() is not None, reason=browser_missing() or ""),
]

VIEW = {"width": 1280, "height": 800}
# Where the floor is seen, away from the control panel (right) and the notifications (top left).
FREE_AREA = (40, 220, 840, 780)  # x0, y0, x1, y1 in pixels


def wait_for(page, condition: Callable[[], bool], seconds: float, what: str) -> None:
    """Poll `condition`, letting Playwright read the browser's events meanwhile: a driver that is
    not read stalls the browser once its pipe fills (the page gets 20 updates a second)."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if condition():
            return
        page.wait_for_timeout(100)
    raise AssertionError(f"timed out after {seconds:g} s waiting for {what}")


def walked(studio, xz: np.ndarray) -> str:
    """What the player did, for a failure message: frames played, where character 0 went and how
    near it came to `xz`, and where the player thread is (a stall shows as a stack)."""
    pelvis = studio.session.clip(0).joints[:, 0][:, [0, 2]]
    near = np.linalg.norm(pelvis - xz, axis=1)
    k = int(near.argmin())
    player = studio._thread
    stack = sys._current_frames().get(player.ident) if player is not None else None
    where = "".join(traceback.format_stack(stack)[-6:]) if stack is not None else "no player thread"
    return (
        f"playing={studio.playing}, {studio.frames_played} frames played; the episode has "
        f"{len(pelvis)} frames, from {pelvis[0].round(2).tolist()} to {pelvis[-1].round(2).tolist()}, "
        f"nearest {near[k]:.2f} m at frame {k}; the player thread is at:\n{where}"
    )


def to_pixel(camera, point: np.ndarray, width: int, height: int) -> tuple[float, float]:
    """World point (3,) -> pixel of the tab whose camera this is (three.js: vertical fov)."""
    eye, target = np.asarray(camera.position), np.asarray(camera.look_at)
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, np.asarray(camera.up_direction))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    d = point - eye
    depth = d @ forward
    tan = np.tan(camera.fov / 2)
    x = (d @ right) / (depth * tan * width / height)
    y = (d @ up) / (depth * tan)
    return (x + 1) / 2 * width, (1 - y) / 2 * height


def figure_pixels(png: bytes) -> tuple[int, int]:
    """How many pixels of the left-limb blue and the right-limb orange a screenshot holds."""
    import io

    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), np.float64)
    x0, y0, x1, y1 = FREE_AREA
    rgb = rgb[y0:y1, x0:x1]
    counts = []
    for color in (LEFT_COLOR, RIGHT_COLOR):
        close = np.abs(rgb - hex_rgb(color) * 255).max(axis=-1) < 40
        counts.append(int(close.sum()))
    return counts[0], counts[1]


def keep_screenshot(png: bytes, name: str) -> Path | None:
    """Copy a screenshot to $MOTION_ENV_STUDIO_SHOTS (to look at it), when that is set."""
    folder = os.environ.get("MOTION_ENV_STUDIO_SHOTS")
    if not folder:
        return None
    path = Path(folder) / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png)
    return path


@pytest.fixture
def chromium():
    """A headless Chromium (the system's, driven by Playwright), closed after the test."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        # SwiftShader: WebGL in software, since a test machine need not have a GPU.
        args = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
        browser = p.chromium.launch(executable_path=CHROMIUM, args=args)
        try:
            yield browser
        finally:
            browser.close()


@pytest.fixture
def studio(generator):
    from motion_env.studio.server import Studio

    studio = Studio(generator, ["a person walks forward"], seed=0, port=0)
    studio.start()
    try:
        yield studio
    finally:
        studio.stop()


def open_tab(browser, studio):
    page = browser.new_page(viewport=VIEW)
    before = set(studio.server.get_clients())
    page.goto(studio.url)
    page.get_by_role("button", name="Apply caption").wait_for(timeout=60_000)
    # viser counts a tab once its first camera report arrives; a report sent while the websocket
    # is still opening is dropped (a race in viser's client), so a new tab may wait for its next
    # one. Turning the view a little, as any user does, sends one.
    page.mouse.move(420, 500)
    end = time.monotonic() + 60
    while not set(studio.server.get_clients()) - before:
        assert time.monotonic() < end, "timed out after 60 s waiting for the tab to connect"
        page.mouse.wheel(0, 1)
        page.wait_for_timeout(200)
    (client_id,) = set(studio.server.get_clients()) - before
    return page, studio.server.get_clients()[client_id]


def set_camera(page, client, position: tuple, look_at: tuple) -> None:
    """Move a tab's camera and wait until the tab says it has moved (its camera report comes back)."""
    reports: list[np.ndarray] = []
    client.camera.on_update(lambda camera: reports.append(np.array(camera.position)))
    with client.atomic():
        client.camera.position = position
        client.camera.look_at = look_at
    wait_for(
        page,
        lambda: any(np.allclose(r, position, atol=1e-3) for r in reports),
        20,
        "the tab's camera to move",
    )
    page.wait_for_timeout(300)  # a frame drawn from there


def text_box(page, label: str):
    """The text input of a labelled control (viser's label points at another id than its input's)."""
    row = (
        f"//label[normalize-space(text())='{label}']/ancestor::div[contains(@class, 'mantine-Flex-root')][1]"
    )
    return page.locator(f"xpath={row}//input")


def click_floor(page, client, xz: tuple[float, float]) -> None:
    # The tab reports its camera to the server; wait until it has one (its size is known).
    wait_for(page, lambda: client.camera.image_width > 0, 10, "the tab's camera")
    point = np.array([xz[0], 0.0, xz[1]])
    x, y = to_pixel(client.camera, point, client.camera.image_width, client.camera.image_height)
    x0, y0, x1, y1 = FREE_AREA
    assert x0 < x < x1 and y0 < y < y1, f"floor point {xz} is at pixel ({x:.0f}, {y:.0f}), off the free area"
    page.mouse.click(x, y)


def test_caption_and_two_waypoints_through_the_page(studio, chromium, tmp_path) -> None:
    page, client = open_tab(chromium, studio)
    session = studio.session

    # Pause, so that the camera (which follows the character) holds still while we click.
    page.get_by_role("button", name="Pause").click()
    wait_for(page, lambda: not studio.playing, 10, "the pause")
    # A new episode: the character back at its start, so that its way to the waypoints does not
    # depend on how long the page took to load (a slow machine walks it far off before the pause).
    page.get_by_role("button", name="Reset").click()
    wait_for(page, lambda: session.frame <= 1, 20, "the reset")
    text_box(page, "Caption").fill("a person jogs")
    page.get_by_role("button", name="Apply caption").click()
    wait_for(page, lambda: session.snapshot().captions[0] == "a person jogs", 20, "the caption to arrive")

    # A fixed, high view of the area, so that the two floor points are on screen.
    set_camera(page, client, (3.0, 7.0, -3.0), (0.0, 0.0, 3.0))
    targets = [(1.5, 2.5), (-1.0, 5.5)]
    for k, xz in enumerate(targets):
        click_floor(page, client, xz)
        wait_for(page, lambda k=k: len(session.snapshot().routes[0]) == k + 1, 10, f"waypoint {k + 1}")
    route = session.snapshot().routes[0]
    # The clicks land where they were aimed (the pixel grid and the float16 of the ray: a few cm).
    np.testing.assert_allclose(route[:, :2], targets, atol=0.1)
    assert np.isnan(route[:, 2]).all()

    page.get_by_role("button", name="Play").click()
    for xz in route[:, :2]:
        try:
            wait_for(
                page,
                lambda xz=xz: session.arrived(0, xz),
                60,
                f"the character to reach {xz.round(2).tolist()}",
            )
        except AssertionError as error:
            raise AssertionError(f"{error}; {walked(studio, xz)}") from None
    assert session.snapshot().reached[0]
    assert session.clip(0).meta["captions"].endswith(": a person jogs")

    # A close view of where the character stands now, for the picture (paused: the camera follows
    # the character, so a playing one would move the view on from where it is set).
    page.get_by_role("button", name="Pause").click()
    wait_for(page, lambda: not studio.playing, 10, "the pause")
    page.wait_for_timeout(300)  # a frame being played ends
    pelvis = session.snapshot().joints[0, 0]
    set_camera(page, client, tuple(pelvis + (2.0, 0.9, 2.6)), tuple(pelvis * (1, 0, 1) + (0, 0.9, 0)))
    png = page.screenshot()
    keep_screenshot(png, "studio_waypoints.png")
    left, right = figure_pixels(png)
    assert left > 150 and right > 150, f"the figure is not drawn: {left} blue and {right} orange pixels"


def test_two_tabs_a_closed_tab_a_long_caption_and_a_click_off_the_floor(studio, chromium) -> None:
    session = studio.session
    first, _ = open_tab(chromium, studio)
    # Paused while the second tab loads: two tabs drawing WebGL in software on a small machine.
    first.get_by_role("button", name="Pause").click()
    second, client = open_tab(chromium, studio)
    assert len(studio.server.get_clients()) == 2

    # A 10 kB caption: accepted (the text encoder reads its beginning).
    long_caption = ("a person walks forward and waves with the right hand " * 200)[:10_000]
    text_box(second, "Caption").fill(long_caption)
    second.get_by_role("button", name="Apply caption").click()
    wait_for(second, lambda: session.snapshot().captions[0] == long_caption.strip(), 60, "the long caption")

    # A click on the sky: no waypoint, a notification, no error on the server.
    set_camera(second, client, (0.0, 1.5, -4.0), (0.0, 3.0, 4.0))  # looking up: the top of the view is sky
    second.mouse.click(400, 260)
    second.get_by_text("Not on the floor").wait_for(timeout=10_000)
    assert len(session.snapshot().routes[0]) == 0

    # Closing a tab leaves the other one, and the frames, going.
    first.close()
    wait_for(second, lambda: len(studio.server.get_clients()) == 1, 20, "the closed tab to leave")
    second.get_by_role("button", name="Play").click()
    wait_for(second, lambda: studio.playing, 10, "play from the remaining tab")
    frame = session.frame
    wait_for(second, lambda: session.frame > frame + 20, 20, "more frames after a tab closed")


def test_download_npz_through_the_page(studio, chromium, tmp_path) -> None:
    from motion_env.motion.types import Motion

    page, _ = open_tab(chromium, studio)
    page.get_by_role("button", name="Clear joint targets").wait_for(timeout=10_000)  # the joint control
    wait_for(page, lambda: studio.session.frame > 30, 20, "some frames")
    page.get_by_text("Keep").click()  # the folder starts closed
    with page.expect_download(timeout=30_000) as download:
        page.get_by_role("button", name="Download .npz").click()
    path = tmp_path / download.value.suggested_filename
    download.value.save_as(path)
    motion = Motion.load(path)
    assert motion.num_frames > 30 and motion.text == "a person walks forward"
