"""The evaluation's captions use words no caption any model trains on uses."""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

from motion_env.data.captions import BANDAI_CONTENTS, BANDAI_STYLES, captions_for_bandai, paraphrases
from motion_env.data.captions.paraphrases import paraphrases_for_bandai
from motion_env.evaluation import captions as ev


@lru_cache(maxsize=1)
def _training_vocabulary() -> frozenset[str]:
    """Every word of the generator's caption templates and of the caption adapter's paraphrases."""
    vocab: set[str] = set()
    for content in BANDAI_CONTENTS:
        for style in BANDAI_STYLES:
            for caption in captions_for_bandai(content, style, n=40, seed=0):
                vocab |= set(re.findall(r"[a-z]+", caption.lower()))
            for caption in paraphrases_for_bandai(content, style, n=200, seed=0):
                vocab |= set(re.findall(r"[a-z]+", caption.lower()))
    # ... and every word of the paraphrase bank, drawn or not.
    bank = (Path(paraphrases.__file__).parent / "phrases" / "paraphrases.json").read_text()
    return frozenset(vocab | set(re.findall(r"[a-z]+", bank.lower())))


def test_heldout_captions_use_new_words() -> None:
    assert ev.heldout_caption("run", "elderly", "fallback") == "a wizened person hurries ahead at full tilt"
    assert ev.heldout_captions("run", "elderly")[1] == "a doddering figure tears down the track at a gallop"
    assert ev.heldout_caption("dance", "", "the take's own caption") == "the take's own caption"
    assert ev.heldout_captions("dance", "") == []


def test_heldout_wordings_carry_their_meaning_in_words_no_training_caption_uses() -> None:
    held = {w for a in ev.ACTION_WORDS for s in ev.STYLE_WORDS for c in ev.heldout_captions(a, s)
            for w in re.findall(r"[a-z]+", c)}  # fmt: skip
    steering = {w for c in (*ev.WALK_CAPTIONS, *ev.RUN_CAPTIONS, *ev.WAVE_RIGHT, *ev.TURN_LEFT)
                for w in re.findall(r"[a-z]+", c)}  # fmt: skip
    assert set(ev.CARRYING_WORDS) <= held | steering | set(re.findall(r"[a-z]+", str(ev.STYLE_CAPTIONS)))
    # Every action and style of a held-out wording is carried by at least one such word.
    carrying = set(ev.CARRYING_WORDS)
    for words in (*ev.ACTION_WORDS.values(), *ev.STYLE_WORDS.values(), *ev.ACTION_WORDS_2.values(),
                  *ev.STYLE_WORDS_2.values()):  # fmt: skip
        assert carrying & set(re.findall(r"[a-z]+", words)), words
    used = _training_vocabulary() & carrying
    assert not used, f"training captions use the held-out words {sorted(used)}"


def test_steering_captions_use_words_the_training_captions_never_use() -> None:
    # The steering numbers claim generalisation to new wordings: the words that carry the action
    # in each evaluation caption must stay out of the training captions' vocabulary.
    vocab = _training_vocabulary()
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
