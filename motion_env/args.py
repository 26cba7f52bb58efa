"""Command-line helpers shared by the CLI, the scripts and the examples.

- :func:`parse_dataclass`: a settings dataclass becomes command-line flags (``--field-name``), each
  with its type, its default and, as help, the comment written after the field; booleans get
  ``--flag`` / ``--no-flag``. The examples keep their settings in one such dataclass (CleanRL's
  ``Args``), so reading the dataclass is reading the command line.
- :class:`ExampleArgs`: the settings every example shares (output folder, seed, model, threads,
  video size) and :meth:`ExampleArgs.setup`, which applies them.
- :func:`parse_waypoints`: the ``"x,z[,t];..."`` text form of waypoints.
- :func:`write_json`: results as a JSON file (parent folders created).
- :func:`require`: import an optional dependency, or exit with the command that installs it
  (:func:`install_line`).
"""

from __future__ import annotations

import argparse
import dataclasses
import inspect
import re
import typing
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from motion_env.generation.generator import MotionGenerator
    from motion_env.motion.types import Motion

__all__ = [
    "ExampleArgs",
    "add_dataclass_arguments",
    "field_comments",
    "install_line",
    "parse_dataclass",
    "parse_waypoints",
    "require",
    "write_json",
]

T = TypeVar("T")

_COMMENTED_FIELD = re.compile(r"^\s+(\w+)\s*:[^#\n]*#\s*(.+?)\s*$")


def field_comments(cls: type) -> dict[str, str]:
    """``name -> comment`` for the fields of a dataclass written as ``name: type = default  # comment``.

    Base classes count too; a subclass's comment wins.
    """
    out: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        try:
            source = inspect.getsource(klass)
        except (OSError, TypeError):
            continue
        for line in source.splitlines():
            if m := _COMMENTED_FIELD.match(line):
                out[m.group(1)] = m.group(2)
    return out


def _converter(kind: Any, default: Any) -> Any:
    """The argparse ``type=`` of a field: int, float or str, or for ``X | None`` an X that reads
    ``none`` as None."""
    if kind in (int, float, str):
        return kind
    args = [a for a in typing.get_args(kind) if a is not type(None)]
    if len(args) == 1 and type(None) in typing.get_args(kind) and args[0] in (int, float, str):
        inner = args[0]

        def optional(text: str) -> Any:
            return None if text.strip().lower() == "none" else inner(text)

        optional.__name__ = inner.__name__  # argparse names the type in its errors
        return optional
    return type(default)


def add_dataclass_arguments(parser: argparse.ArgumentParser, cls: type) -> None:
    """Add one ``--field-name`` option per field of the dataclass `cls` (its default, its type).

    Booleans become ``--flag`` / ``--no-flag``; an ``X | None`` field takes ``none`` for None.
    """
    comments = field_comments(cls)
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        flag = "--" + f.name.replace("_", "-")
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()  # type: ignore[misc]
        # argparse formats help with %: a comment's own % signs are escaped.
        help_text = f"{comments.get(f.name, '')} (default: {default!r})".strip().replace("%", "%%")
        if hints.get(f.name) is bool or isinstance(default, bool):
            parser.add_argument(flag, action=argparse.BooleanOptionalAction, default=default, help=help_text)
        else:
            parser.add_argument(
                flag, type=_converter(hints.get(f.name), default), default=default, help=help_text
            )


def parse_dataclass(cls: type[T], argv: Sequence[str] | None = None, description: str | None = None) -> T:
    """Parse command-line flags into an instance of the dataclass `cls` (``--help`` lists them)."""
    parser = argparse.ArgumentParser(
        description=description, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    add_dataclass_arguments(parser, cls)
    values: dict[str, Any] = vars(parser.parse_args(argv))
    return cls(**values)


def parse_waypoints(text: str, what: str = "--waypoints") -> list[list[float]]:
    """``"x,z;x,z,t;..."`` -> rows of 3 (x, z and the frame at 20 fps; NaN time for ``"x,z"``).

    Raises ValueError naming the item (`what` names the option in the message).
    """
    rows = []
    for k, item in enumerate(part for part in text.split(";") if part.strip()):
        try:
            values = [float(v) for v in item.split(",")]
        except ValueError as exc:
            raise ValueError(f"{what} item {k} {item.strip()!r} is not 'x,z' or 'x,z,t' numbers") from exc
        if len(values) not in (2, 3):
            raise ValueError(f"{what} item {k} {item.strip()!r} has {len(values)} numbers, expected 2 or 3")
        rows.append(values + [float("nan")] * (3 - len(values)))
    if not rows:
        raise ValueError(f"{what} is empty; give 'x,z,t;x,z,t' (t = frame index at 20 fps, optional)")
    return rows


def write_json(path: str | Path, data: Any) -> Path:
    """Write `data` as indented JSON to `path` (parent folders created) and say so on stdout."""
    import json

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2) + "\n")
    print(f"wrote {path}")
    return path


def install_line(extra: str) -> str:
    """The command that installs the optional `extra` (``"robots"``, ``"rl"``, ...), run from the
    repository's root as the README's install is: the package is not on PyPI."""
    return f'pip install -c constraints.txt -e ".[{extra}]"'


def require(module: str, extra: str) -> Any:
    """Import an optional dependency; when it is missing, exit with the command that installs it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise SystemExit(
            f"{module} is not installed; install the optional extra: {install_line(extra)}"
        ) from None


@dataclass
class ExampleArgs:
    """The settings every example shares; an example's ``Args`` subclasses it and adds its own."""

    out: str = "runs/example"  # output folder
    seed: int = 0  # seed of the episode (and of token sampling)
    model: str = ""  # weights directory; empty = the shipped model
    random_model: bool = False  # tiny UNTRAINED random weights instead (smoke tests)
    threads: int = 1  # torch threads: the generator's small per-frame ops run fastest on one
    video: str = "mp4"  # mp4 or gif
    width: int = 640  # video width (pixels)
    height: int = 480  # video height (pixels)

    def setup(self) -> tuple[Path, MotionGenerator]:
        """Apply the settings: torch threads, the output folder (created) and the generator."""
        import torch

        from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator

        torch.set_num_threads(self.threads)
        out = Path(self.out)
        out.mkdir(parents=True, exist_ok=True)
        return out, MotionGenerator.from_pretrained(RANDOM_MODEL if self.random_model else self.model or None)

    def write_outputs(
        self,
        motion: Motion,
        stem: str,
        result: dict[str, Any],
        title: str | None = None,
        **drawing: Any,
    ) -> None:
        """Write what an example made into the output folder and say where it went: the motion
        (``stem.npz``), a video (``stem.mp4`` / ``.gif``), a top-down plot (``stem.png``) and
        ``result.json`` (these settings and `result`). `drawing` goes to the video and the plot
        (``obstacles=...``); ``highlight_frames`` / ``highlight_label`` to the video only."""
        import json
        from dataclasses import asdict

        from motion_env.render import plot_path, render_video

        out = Path(self.out)
        plot_drawing = {k: v for k, v in drawing.items() if not k.startswith("highlight")}
        written = [
            motion.save(out / f"{stem}.npz"),
            render_video(
                motion, out / f"{stem}.{self.video}", width=self.width, height=self.height, **drawing
            ),
            plot_path(motion, out / f"{stem}.png", title=title, **plot_drawing),
        ]
        print(json.dumps(result, indent=2))
        written.append(write_json(out / "result.json", {"args": asdict(self), **result}))
        for path in written[:-1]:
            print(f"wrote {path}")
