"""The `motion-env` command line (the console script is :func:`main`).

Each subcommand has an ``add_<name>`` function that declares its arguments and a ``run_<name>``
function that calls the library: :mod:`.generate` (``generate``, ``bench``), :mod:`.files`
(``show``, ``replay``), :mod:`.offline` (``data build``, ``train``), :mod:`.export` (``export``),
:mod:`.retarget` (``retarget``), :mod:`.studio` (``studio``), :mod:`.evaluate` (``eval control``,
``eval captions``, ``eval natural``), :mod:`.captions` (``captions``);
:mod:`.common` holds what they share. The heavy modules are imported only by the command that
needs them, after its cheap checks, so `motion-env --help` and a typo are answered at once.

The rules every command follows:

- a user error (a bad argument, a file that is missing or in the way, an input the library
  rejects, a device this torch cannot use) is one line on stderr,
  ``motion-env <command>: error: <message>``, and exit code 2; anything else is a bug and shows
  its traceback;
- an output file that exists is never replaced without ``--overwrite`` (``train --out`` resumes
  from its checkpoint instead);
- warnings are ``motion-env <command>: warning: <message>`` lines, each once;
- torch runs on one thread unless ``--threads`` says otherwise.
"""

from __future__ import annotations

import argparse
import gc
import sys
from collections.abc import Sequence

from motion_env.cli.captions import add_captions
from motion_env.cli.common import USER_ERRORS, CommandParser, one_line, reported_warnings
from motion_env.cli.evaluate import add_eval
from motion_env.cli.export import add_export
from motion_env.cli.files import add_replay, add_show
from motion_env.cli.generate import add_bench, add_generate
from motion_env.cli.offline import add_data, add_train
from motion_env.cli.retarget import add_retarget
from motion_env.cli.studio import add_studio

__all__ = ["build_parser", "main"]


def _version() -> str:
    from motion_env import __version__

    return __version__


def build_parser() -> argparse.ArgumentParser:
    parser = CommandParser(
        prog="motion-env", description="Text- and path-controllable human motion as a Gymnasium env."
    )
    parser.add_argument("--version", action="version", version=f"motion-env {_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    commands = (
        add_show, add_data, add_train, add_generate, add_bench, add_eval, add_replay, add_export,
        add_retarget, add_captions,
    )  # fmt: skip
    for add in (*commands, add_studio):
        add(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns its exit code (0 done, 1 `replay --strict` verdict, 2 user error,
    130 interrupted). A bad argument, ``--help`` and ``--version`` exit through argparse.

    ``argv=None`` (the arguments of ``sys.argv``) means the console script, about to exit: the
    objects left at the end are then frozen (``gc.freeze``) rather than collected. Callers in
    Python pass a list.
    """
    args = build_parser().parse_args(argv)
    prog = f"motion-env {args.command}" + (f" {args.data_command}" if args.command == "data" else "")
    prog += f" {args.eval_command}" if args.command == "eval" else ""
    try:
        with reported_warnings(prog):
            return int(args.run(args) or 0)
    except USER_ERRORS as exc:
        print(f"{prog}: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    finally:
        if argv is None:  # the console script, about to exit (not a caller in Python)
            # The outputs are written and closed. Spare the exit a garbage collection over the
            # millions of objects torch and sentence-transformers leave (about 1 s here): frozen
            # objects are left to the operating system; atexit handlers and stdio flushes still run.
            gc.freeze()


if __name__ == "__main__":
    sys.exit(main())
