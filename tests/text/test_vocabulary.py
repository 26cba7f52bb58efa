"""The caption vocabulary and the caption check: the non-English rule on examples, the length rule,
and the "far from anything known" threshold against the project's own wordings."""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.evaluation import captions as ec
from motion_env.text.vocabulary import (
    FAR_SIMILARITY,
    MAX_CAPTION_CHARS,
    caption_warning,
    language_problem,
    load_vocabulary,
)

UNRELATED = (
    "the stock market fell today", "a recipe for bread", "the weather will be sunny tomorrow",
    "quarterly earnings exceeded expectations", "install the package with pip",
    "the capital of France is Paris", "please reset your password", "a bowl of tomato soup",
    "the meeting is rescheduled to Monday", "an invoice for the consulting services",
    "the train to Berlin is delayed", "the function returns a list of integers",
    "the cat sleeps on the sofa", "a beautiful sunset over the ocean",
)  # fmt: skip


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("une personne court très vite", "French"),
        ("un homme marche lentement", "French"),
        ("eine Person läuft", "German"),
        ("ein Mann winkt mit der rechten Hand", "German"),
        ("una persona camina", "Spanish"),
        ("una persona corre muy rápido", "Spanish"),
        ("一个人在走路", "not in the Latin script"),
        ("человек идёт вперёд", "not in the Latin script"),
        ("🏃", "no letters"),
        ("🏃\u200d♂️💨 !!", "no letters"),
        ("a person walks 一个人在走路", "not in the Latin script"),  # mixed
        ("a person walks und dann läuft sie sehr schnell", "German"),  # mixed
    ],
)
def test_not_english(text: str, reason: str) -> None:
    assert reason in language_problem(text)


@pytest.mark.parametrize(
    "text",
    [
        "a person walks forward and turns left",
        "a person walks to the café",  # one foreign word is not a language
        "a naïve person waves",
        "someone ambles along at an easy, unhurried gait",
        "a person waves the left hand",
    ],
)
def test_english(text: str) -> None:
    assert language_problem(text) == ""


def test_no_english_warning_for_the_project_captions() -> None:
    from motion_env.data.captions import captions_for_bandai
    from motion_env.data.captions.bandai import BANDAI_CONTENTS, BANDAI_STYLES

    texts = [c for a in BANDAI_CONTENTS for s in BANDAI_STYLES for c in captions_for_bandai(a, s, n=3)]
    held = [ec.heldout_caption(a, s, "") for a in ec.ACTION_WORDS for s in ec.STYLE_WORDS]
    assert [t for t in texts + held if caption_warning(t)] == []


def test_long_caption_warns_with_the_fallback() -> None:
    text = "a person walks forward " * 500  # 11.5 kB
    message = caption_warning(text.strip())
    assert f"{MAX_CAPTION_CHARS:,} characters" in message and "ignores the rest" in message
    assert caption_warning("a person walks forward " * 40) == ""  # 920 characters


@pytest.fixture(scope="module")
def vocab_and_encoder():
    from motion_env.text.encoders import load_text_encoder

    vocab = load_vocabulary()
    if vocab is None:
        pytest.skip("the shipped weights have no vocabulary")
    return vocab, load_text_encoder(vocab.encoder)


def test_the_threshold_separates_new_wordings_from_unrelated_sentences(vocab_and_encoder) -> None:
    """The measurement behind FAR_SIMILARITY (the model card lists the numbers)."""
    vocab, enc = vocab_and_encoder
    held = [*ec.WALK_CAPTIONS, *ec.RUN_CAPTIONS, *ec.WAVE_LEFT, *ec.WAVE_RIGHT, *ec.TURN_LEFT, *ec.TURN_RIGHT]
    held += [c for v in ec.STYLE_CAPTIONS.values() for c in v]
    held += [ec.heldout_caption(a, s, "") for a in ec.ACTION_WORDS for s in ec.STYLE_WORDS]

    def best(texts: list[str]) -> np.ndarray:
        return np.array([vocab.nearest(e).similarity for e in enc.encode(texts).numpy()])

    held_sims, unrelated_sims = best(held), best(list(UNRELATED))
    assert held_sims.min() > FAR_SIMILARITY > unrelated_sims.max(), (held_sims.min(), unrelated_sims.max())


def test_warning_names_the_nearest_actions(vocab_and_encoder) -> None:
    vocab, enc = vocab_and_encoder
    [far, run, french] = enc.encode(
        ["a recipe for bread", "a woman races ahead", "une personne court"]
    ).numpy()
    assert caption_warning("a woman races ahead", run, vocab) == ""
    assert vocab.nearest(run).actions[0][0] in ("run", "dash")
    message = caption_warning("a recipe for bread", far, vocab)
    assert "far from every caption" in message and "nearest known actions: " in message
    assert "French" in caption_warning("une personne court", french, vocab)
