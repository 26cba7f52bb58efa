"""What every caption writer shares: how many captions, who does the motion, and :func:`draw`,
which turns a list of sentence templates into distinct captions."""

from __future__ import annotations

import random
from collections.abc import Callable, Sequence

from motion_env.data.captions.grammar import tidy

# Twelve: a text-conditioned model generalises to new wordings only when each motion is seen
# under many (HumanML3D has three human-written ones per clip; ours are drawn from phrase lists).
DEFAULT_NUM_CAPTIONS = 12

# The subjects of the sentences.
PEOPLE = (
    "a person", "someone", "the person", "a human", "a figure", "somebody", "a man", "a woman", "the man",
    "the woman", "a performer",
)  # fmt: skip


def draw(rng: random.Random, templates: Sequence[Callable[[], str]], n: int) -> list[str]:
    """Up to ``n`` distinct captions, cycling through the templates in a shuffled order."""
    out: list[str] = []
    order = list(range(len(templates)))
    rng.shuffle(order)
    attempts = 0
    while len(out) < n and attempts < 40 * max(n, 1):
        text = tidy(templates[order[attempts % len(order)]]())
        attempts += 1
        if text not in out:
            out.append(text)
    return out
