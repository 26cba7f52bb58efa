"""The evaluation's captions use words the training captions never use."""

from __future__ import annotations

import re

from motion_env.data.captions import BANDAI_CONTENTS, BANDAI_STYLES, captions_for_bandai
from motion_env.evaluation import captions as ev


def test_heldout_captions_use_new_words() -> None:
    assert ev.heldout_caption("run", "elderly", "fallback") == "a frail old person hurries ahead at full tilt"
    assert ev.heldout_caption("dance", "", "the take's own caption") == "the take's own caption"


def test_steering_captions_use_words_the_training_captions_never_use() -> None:
    # The steering numbers claim generalisation to new wordings: the words that carry the action
    # in each evaluation caption must stay out of the training captions' vocabulary.
    vocab: set[str] = set()
    for content in BANDAI_CONTENTS:
        for style in BANDAI_STYLES:
            for caption in captions_for_bandai(content, style, n=40, seed=0):
                vocab |= set(re.findall(r"[a-z]+", caption))
    new_words = {
        ev.WALK_CAPTIONS: ("ambles", "unhurried", "gait", "saunters", "clip"),
        ev.RUN_CAPTIONS: ("hurries", "tilt", "pounding", "races", "legs", "bolts", "top"),
        ev.WAVE_RIGHT + ev.WAVE_LEFT: ("greets", "friend"),
        ev.TURN_LEFT + ev.TURN_RIGHT: ("foot", "leftward", "rightward"),
        tuple(c for group in ev.STYLE_CAPTIONS.values() for c in group): (
            "drained",
            "drags",
            "nineties",
            "pep",
        ),
    }
    for captions, words in new_words.items():
        assert all(any(w in c.split() or w + "," in c.split() for c in captions) for w in words)
        assert not vocab & set(words), f"training captions use {sorted(vocab & set(words))}"
