"""`motion-env studio`: a local web page where you type a caption, click waypoints on the floor and
watch the character (or a small crowd) stream in 3-D, 20 frames a second. Needs the optional
viser package (pip install -c constraints.txt -e ".[studio]"). Stop it with Ctrl-C.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import signal
import socket
import sys
import threading

from motion_env.args import install_line
from motion_env.cli.common import CommandError, add_threads, add_weights, check_model_choice, load_generator

__all__ = ["add_studio", "run_studio"]

DEFAULT_CAPTION = "a person walks forward"


def add_studio(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "studio",
        help="a local web page: caption, waypoints, obstacles; the character streams in 3-D",
        description=__doc__,
    )
    p.add_argument(
        "--port", type=int, default=8080, help="TCP port of the page (default 8080; 0: any free one)"
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to listen on (default 127.0.0.1: this machine only; 0.0.0.0 opens it to the network)",
    )
    p.add_argument("--no-browser", action="store_true", help="print the URL but do not open a browser")
    p.add_argument(
        "--text",
        action="append",
        default=None,
        help=f'caption of a character (repeat for several; default "{DEFAULT_CAPTION}")',
    )
    p.add_argument(
        "--characters",
        type=int,
        default=None,
        help="how many characters (a crowd, captions taken from --text in turn; default: one per --text)",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed of the stream (the page can change it)")
    add_weights(p)
    p.add_argument("--random-model", action="store_true", help="tiny UNTRAINED random weights (for testing)")
    p.add_argument("--device", default="cpu", help="torch device (default cpu)")
    add_threads(p)
    p.set_defaults(run=run_studio)


def _check_port(host: str, port: int) -> None:
    """The port is a number a server can listen on here, and nothing listens on it yet."""
    if not 0 <= port <= 65535:
        raise CommandError(f"--port must be from 0 to 65535, got {port}")
    try:
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            # As the server binds: connections of a studio just stopped (TIME_WAIT) do not count.
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            probe.bind((host, port))
    except socket.gaierror:
        raise CommandError(f"--host {host!r} is not an address of this machine") from None
    except OSError as exc:
        if port and exc.errno in (98, 48, 10048):  # EADDRINUSE on Linux, macOS, Windows
            raise CommandError(
                f"--port {port} is in use (another studio?): pick another with --port N, or --port 0 "
                "for any free one"
            ) from None
        raise CommandError(f"--host {host} --port {port}: cannot listen there ({exc.strerror})") from None


def _captions(args: argparse.Namespace) -> list[str]:
    from motion_env.generation.request import check_text
    from motion_env.studio.session import MAX_CHARACTERS

    texts = [check_text(t, "--text") for t in (args.text or [DEFAULT_CAPTION])]
    count = len(texts) if args.characters is None else args.characters
    if not 1 <= count <= MAX_CHARACTERS:
        raise CommandError(f"--characters must be from 1 to {MAX_CHARACTERS}, got {count}")
    return [texts[i % len(texts)] for i in range(count)]


def _can_open_a_browser() -> bool:
    """A graphical browser can open here: without a display, Python's webbrowser falls back to a
    text browser that would take over this terminal."""
    return sys.platform in ("darwin", "win32") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    )


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def run_studio(args: argparse.Namespace) -> int:
    if importlib.util.find_spec("viser") is None:
        raise CommandError(f"the studio needs the viser package: {install_line('studio')}")
    check_model_choice(args)
    captions = _captions(args)
    _check_port(args.host, args.port)
    gen = load_generator(args, captions)
    # New captions typed in the page are encoded while it plays: load the encoder now (the
    # captions above may have come from the cache), so that the first one is not a pause of seconds.
    _ = gen.pipeline.text_encoder
    from motion_env.studio.server import Studio

    # `kill` ends the studio as Ctrl-C does: the page closes, the port is freed, exit code 130.
    # Ctrl-C works even where the studio was started with SIGINT ignored (a shell's background
    # job, `cmd &` in a script): a server that can only be killed hard is worse.
    # (Handlers can only be set from the main thread; tests run commands from others.)
    on_main = threading.current_thread() is threading.main_thread()
    previous = (
        (signal.signal(signal.SIGTERM, _interrupt), signal.signal(signal.SIGINT, signal.default_int_handler))
        if on_main
        else None
    )
    studio = Studio(gen, captions, seed=args.seed, host=args.host, port=args.port)
    try:
        url = studio.start()
        opened = False
        if not args.no_browser and _can_open_a_browser():
            import webbrowser

            opened = webbrowser.open(url)
        how = "opened in your browser" if opened else "open it in a browser"
        print(f"motion-env studio: {url} ({how}; Ctrl-C to stop)", flush=True)
        studio.serve_forever()
    finally:
        studio.stop()
        if studio.frames_played:
            print(
                f"motion-env studio: played {studio.frames_played} frames in {studio.play_seconds:.1f} s "
                f"({studio.frames_played / max(studio.play_seconds, 1e-9):.1f} fps)",
                flush=True,
            )
        if previous is not None:
            signal.signal(signal.SIGTERM, previous[0])
            signal.signal(signal.SIGINT, previous[1])
    return 0
