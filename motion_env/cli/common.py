"""What every command of `motion-env` shares: the parser that reports a bad argument in one line,
the user errors, the rule for existing outputs, the checks of a device and the torch threads.

Nothing heavy is imported here at module level: torch only inside :func:`check_device` and
:func:`set_threads`, which the commands that use torch call once their cheap checks have passed.
"""

from __future__ import annotations

import argparse
import gc
import os
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

__all__ = [
    "USER_ERRORS",
    "CommandError",
    "CommandParser",
    "add_overwrite",
    "add_threads",
    "check_device",
    "check_new_file",
    "check_suffix",
    "one_line",
    "paused_gc",
    "reported_warnings",
    "set_threads",
]


class CommandError(Exception):
    """A user error found by the command line itself (a wrong option, a file in the way)."""


# What a command reports in one line (exit code 2) instead of a traceback: files that cannot be
# read or written, and the input checks of the library (ValueError, TypeError).
USER_ERRORS = (CommandError, OSError, ValueError, TypeError)


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line, ``motion-env <command>: error: <message>``."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def one_line(exc: BaseException) -> str:
    """An exception's message on one line (its type's name when it has none)."""
    text = " ".join(line.strip() for line in str(exc).splitlines() if line.strip())
    return text or type(exc).__name__


@contextmanager
def reported_warnings(prog: str) -> Iterator[None]:
    """Show warnings as ``<prog>: warning: <message>`` lines, each message once."""
    seen: set[str] = set()

    def show(message, category, filename, lineno, file=None, line=None) -> None:  # noqa: ANN001
        text = one_line(message) if isinstance(message, BaseException) else " ".join(str(message).split())
        if text not in seen:
            seen.add(text)
            print(f"{prog}: warning: {text}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


@contextmanager
def paused_gc() -> Iterator[None]:
    """No cyclic garbage collection while the block runs (then as before).

    For loading models: importing torch, transformers and sentence-transformers creates millions
    of long-lived objects, and the collector walks them all again and again while they are being
    made (about 0.8 s of a 3.5 s cold start here). A bounded phase, so nothing piles up.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def add_overwrite(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--overwrite", action="store_true", help="replace output files that exist (default: refuse)"
    )


def add_threads(parser: argparse.ArgumentParser, what: str = "") -> None:
    parser.add_argument(
        "--threads", type=int, default=1,
        help=f"torch CPU threads (default 1: the models' small sequential steps run fastest on one{what})",
    )  # fmt: skip


def check_suffix(path: str | Path, suffixes: tuple[str, ...], flag: str, hint: str = "") -> Path:
    """`path` as a Path if it ends in one of `suffixes` (exactly), else a CommandError."""
    path = Path(path)
    if path.suffix not in suffixes:
        kinds = " or ".join(suffixes)
        raise CommandError(f"{flag} {path}: must end in {kinds}, not {path.suffix or 'no suffix'!r}{hint}")
    return path


def check_new_file(path: str | Path, overwrite: bool, flag: str) -> Path:
    """Check that a command may write `path`: it is no folder, does not exist (or `overwrite`),
    and its folder exists or can be made, and is writable. Nothing is written."""
    path = Path(path)
    if path.is_dir():
        raise CommandError(f"{flag} {path}: is a folder; give a file name")
    if path.exists() and not overwrite:
        raise CommandError(f"{path} exists: nothing was written (pass --overwrite to replace it)")
    folder = path.absolute().parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise CommandError(f"{flag} {path}: {folder} is a file, not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise CommandError(f"{flag} {path}: cannot write in {folder} (permission denied)")
    return path


def check_device(device: str) -> str:
    """The torch device `device` names, if this torch can use it; a one-line CommandError if not
    (a CPU-only torch asked for CUDA, no GPU, a GPU index that does not exist, a typo)."""
    import torch

    try:
        dev = torch.device(device)
    except (RuntimeError, ValueError) as exc:
        raise CommandError(f"--device {device!r} is not a torch device ({one_line(exc)})") from None
    if dev.type == "cuda":
        if torch.version.cuda is None and getattr(torch.version, "hip", None) is None:
            raise CommandError(
                f"--device {device}: torch {torch.__version__} has no CUDA here (CPU build): use "
                "--device cpu, or install a CUDA build of torch (see docs/usage.md, 'Install')"
            )
        if not torch.cuda.is_available():
            raise CommandError(
                f"--device {device}: torch {torch.__version__} is built for CUDA but finds no usable "
                "GPU here (driver, CUDA_VISIBLE_DEVICES?): use --device cpu"
            )
        count = torch.cuda.device_count()
        if dev.index is not None and dev.index >= count:
            raise CommandError(f"--device {device}: there is no GPU {dev.index} (this machine has {count})")
    elif dev.type == "mps" and not torch.backends.mps.is_available():
        raise CommandError(f"--device {device}: Apple's MPS is not available here: use --device cpu")
    return device


def set_threads(threads: int) -> None:
    """``torch.set_num_threads(threads)`` (our commands default to 1: on a small machine torch's
    default of one thread per core makes the models' small steps slower, not faster)."""
    if threads < 1:
        raise CommandError(f"--threads must be >= 1, got {threads}")
    import torch

    torch.set_num_threads(int(threads))


CAPTION_READER_HELP = (
    "which caption reader (a text encoder and its caption adapter) reads the captions: default "
    "(the weights' caption_adapter.pt), none (the models read the text encoder as trained, without "
    "the adapter), or a named one such as mpnet (caption_adapter.mpnet.pt; needs the optional mpnet "
    "encoder)"
)


def add_weights(p: argparse.ArgumentParser) -> None:
    """``--model`` (or its alias ``--weights``): the generator's weights folder, in every command
    that loads one (``args.model``)."""
    p.add_argument(
        "--model", "--weights", dest="model", default=None,
        help="generator weights directory (default: the shipped model); --weights is the same",
    )  # fmt: skip


def add_caption_reader(p: argparse.ArgumentParser) -> None:
    """``--caption-reader`` (commands that load a generator's weights)."""
    p.add_argument("--caption-reader", default=None, metavar="NAME", help=CAPTION_READER_HELP)


def check_model_choice(args: argparse.Namespace) -> None:
    """``--model`` and ``--random-model`` (commands that load a generator): one at most, and a
    weights directory that exists; checked before anything heavy is imported."""
    if args.random_model and args.model is not None:
        raise CommandError("give either --model or --random-model, not both")
    if args.model is not None and not Path(args.model).is_dir():
        raise FileNotFoundError(f"--model/--weights {args.model}: no generator weights directory there")


def load_generator(args: argparse.Namespace, captions: list[str]) -> Any:
    """The generator of ``--model`` / ``--random-model`` on ``--device`` with ``--threads``, its text
    encoder loaded and `captions` encoded (so the first frame is not a pause of seconds)."""
    with paused_gc():
        check_device(args.device)  # imports torch
        set_threads(args.threads)
        from motion_env.generation.generator import MotionGenerator

        if args.random_model:
            gen = MotionGenerator.random(seed=args.seed, device=args.device)
        else:
            reader = getattr(args, "caption_reader", None)
            gen = MotionGenerator.from_pretrained(args.model, device=args.device, caption_reader=reader)
        gen.encode_text(sorted(set(captions)))  # the text encoder loads here (unless cached)
    return gen
