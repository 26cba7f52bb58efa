"""Training settings: the base of the trainers' config dataclasses and their checks.

Each trainer has one config dataclass derived from :class:`TrainConfig`
(:class:`~motion_env.training.vqvae.VQVAETrainConfig`,
:class:`~motion_env.training.gpt.GPTTrainConfig`,
:class:`~motion_env.training.controller.ControllerTrainConfig`), each field written
``name: type = default  # what it does``, the type saying the bounds too (``steps: PositiveInt``).
A config is checked when it is made (a ``ValueError`` names the field and the value), is stored
in the checkpoint as a plain dict (``ckpt["settings"]``), and is the command line of
``motion-env train <model>``: one ``--field-name`` option per field, with the comment as its help
(:func:`motion_env.args.add_dataclass_arguments`).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, fields
from typing import Any

import torch

from motion_env.motion.validation import (
    CheckedConfig,
    NonNegativeFloat,
    NonNegativeInt,
    PositiveInt,
)

_EXPECTED = {bool: "True or False", int: "an integer", float: "a number", str: "a non-empty string"}


def _is(kind: type, value: Any) -> bool:
    if kind is bool:
        return isinstance(value, bool)
    if kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if kind is float:
        return isinstance(value, int | float) and not isinstance(value, bool) and not math.isnan(value)
    if kind is str:
        return isinstance(value, str) and bool(value.strip())
    return True


@dataclass(kw_only=True)
class TrainConfig(CheckedConfig):
    """The settings every trainer has: seeding, device, resuming, bookkeeping cadence, time limit.

    A trainer's own config adds its optimisation settings (steps, batch size, learning rate, ...),
    may change these defaults (a field written again keeps its bounds only if its annotation
    does: ``save_every: PositiveInt = 250``), and checks what its annotations cannot say in
    ``__post_init__`` after this one's. Here each field's type is checked first, then the bounds
    (:class:`~motion_env.motion.validation.CheckedConfig`), then the device.
    """

    seed: NonNegativeInt = 0  # seed of the model init and of the batch sampling
    device: str = "cpu"  # torch device: cpu, cuda, cuda:1, ...
    resume: bool = True  # continue from the checkpoint when it exists (--no-resume: start afresh)
    log_every: PositiveInt = 50  # steps between loss lines in the log
    save_every: PositiveInt = 100  # steps between checkpoints (one is also written at the end)
    eval_every: NonNegativeInt = 0  # steps between validations on the val split (0: only at the end)
    max_minutes: NonNegativeFloat = math.inf  # stop, with a checkpoint, after this much wall time
    progress: bool = True  # show a tqdm progress bar (--no-progress: hide it)

    def __post_init__(self) -> None:
        hints = typing.get_type_hints(type(self))
        for f in fields(self):
            value = getattr(self, f.name)
            if not _is(hints[f.name], value):
                expected = _EXPECTED[hints[f.name]]
                raise ValueError(f"{type(self).__name__}.{f.name} must be {expected}, got {value!r}")
        super().__post_init__()
        try:
            torch.device(self.device)
        except (RuntimeError, ValueError) as exc:
            raise ValueError(
                f"{type(self).__name__}.device {self.device!r} is not a torch device: {exc}"
            ) from exc

    def to_dict(self) -> dict[str, Any]:
        """The settings as a plain dict (what the checkpoint stores under ``"settings"``)."""
        return dataclasses.asdict(self)
