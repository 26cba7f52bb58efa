"""Paraphrases of the Bandai Namco labels (motion_env.data.captions.paraphrases): determinism,
coverage of every label, no held-out evaluation word, sides, tidy text, and far more words than
the template captions."""

from __future__ import annotations

import re
from functools import cache

import pytest

from motion_env.data.captions import BANDAI_CONTENTS, BANDAI_STYLES, captions_for_bandai
from motion_env.data.captions.grammar import gerund, inflect, third_person
from motion_env.data.captions.paraphrases import (
    PARAPHRASE_CONTENTS,
    PARAPHRASE_STYLES,
    paraphrases_for_bandai,
)
from motion_env.data.captions.phrases import load
from motion_env.evaluation.captions import CARRYING_WORDS

_LEFT_CONTENTS = ("walk-turn-left", "walk-left", "wave-left-hand", "raise-up-left-hand")
_MAIN_CONTENTS = ("walk", "walk-turn-left", "walk-left", "run", "dash", "wave-both-hands", "wave-left-hand")
_MAIN_CONTENTS += ("raise-up-both-hands", "raise-up-left-hand")


def _words(text: str) -> list[str]:
    return re.findall(r"[a-z]+", text.lower())


@cache
def _all_captions(n: int) -> dict[tuple[str, str], list[str]]:
    return {(c, s): paraphrases_for_bandai(c, s, n=n) for c in BANDAI_CONTENTS for s in BANDAI_STYLES}


def test_paraphrases_are_deterministic_and_seeded() -> None:
    caps = paraphrases_for_bandai("walk-turn-left", "exhausted", n=20, seed=3)
    assert caps == paraphrases_for_bandai("walk-turn-left", "exhausted", n=20, seed=3)
    assert caps == paraphrases_for_bandai(" Walk-Turn-Left ", "EXHAUSTED", n=20, seed=3)
    assert caps != paraphrases_for_bandai("walk-turn-left", "exhausted", n=20, seed=4)
    assert paraphrases_for_bandai("run", "happy", n=5, seed="val") == paraphrases_for_bandai(
        "run", "happy", n=5, seed="val"
    )


def test_every_label_is_covered_with_n_distinct_captions() -> None:
    assert set(BANDAI_CONTENTS) <= set(PARAPHRASE_CONTENTS)
    assert set(BANDAI_STYLES) <= set(PARAPHRASE_STYLES)
    for (content, style), caps in _all_captions(200).items():
        assert len(caps) == 200 and len(set(caps)) == 200, (content, style)
    for n in (0, 1, 7):
        assert len(paraphrases_for_bandai("bow", "sad", n=n)) == n


def test_the_bank_is_a_superset_of_the_templates_and_rich_enough() -> None:
    for content, phrases in BANDAI_CONTENTS.items():
        assert set(phrases) <= set(PARAPHRASE_CONTENTS[content]), content
        assert len(PARAPHRASE_CONTENTS[content]) >= (30 if content in _MAIN_CONTENTS else 8), content
    for label, style in BANDAI_STYLES.items():
        para = PARAPHRASE_STYLES[label]
        assert set(style.adjectives) <= set(para.adjectives) and set(style.subjects) <= set(para.subjects)
        assert set(style.phrases) <= set(para.phrases), label
        ways = para.adjectives + para.adverbs + para.phrases + para.subjects + para.looks
        assert len(ways) >= 12 and para.steps, label


def test_no_held_out_word_is_ever_used() -> None:
    forbidden = {w.lower() for w in CARRYING_WORDS} | {"figure"}
    for (content, style), caps in _all_captions(200).items():
        for caption in caps:
            assert not forbidden & set(_words(caption)), (content, style, caption)
    # Every entry of the tables, in every form, whether or not a draw above reached it.
    for content, phrases in PARAPHRASE_CONTENTS.items():
        for phrase in phrases:
            for form in (third_person, gerund, str):
                assert not forbidden & set(_words(inflect(phrase, form))), (content, phrase)
    for label, style in PARAPHRASE_STYLES.items():
        for text in (
            style.adjectives + style.adverbs + style.phrases + style.subjects + style.looks + style.steps
        ):
            assert not forbidden & set(_words(text)), (label, text)
    bank = load("paraphrases")
    for text in (*bank["subjects"], *bank["nouns"], *bank["takes"], *bank["settings"], *bank["frames"]):
        assert not forbidden & set(_words(text)), text


# Words that share five letters with a carrying word yet carry nothing of it.
_HARMLESS_PREFIX_PAIRS = {("right", "rightward"), ("ninety", "nineties")}


def _carrying_prefix_clash(word: str) -> str | None:
    """The carrying word that ``word`` equals, or shares its first five letters with (5+ letters)."""
    for carrying in (w.lower() for w in CARRYING_WORDS):
        if word == carrying:
            return carrying
        if len(carrying) >= 5 and word[:5] == carrying[:5] and (word, carrying) not in _HARMLESS_PREFIX_PAIRS:
            return carrying
    return None


def _strings(node: object) -> list[str]:
    if isinstance(node, str):
        return [node]
    if isinstance(node, dict):
        return [s for key, value in node.items() for s in (key, *_strings(value))]
    if isinstance(node, list):
        return [s for item in node for s in _strings(item)]
    return []


def test_no_word_shares_a_five_letter_stem_with_a_held_out_word() -> None:
    # "doddery" says what "doddering" says: a word of the bank or of a drawn caption may not share
    # its first five letters with a carrying word of 5+ letters (shorter ones: exact matches only).
    words = {w for text in _strings(load("paraphrases")) for w in _words(text)}
    words |= {w for caps in _all_captions(200).values() for c in caps for w in _words(c)}
    clashes = {w: c for w in sorted(words) if (c := _carrying_prefix_clash(w))}
    assert not clashes, clashes


def test_sides_follow_the_labels_and_their_mirrors() -> None:
    for left in _LEFT_CONTENTS:
        right = left.replace("left", "right")
        for style in BANDAI_STYLES:
            for content, side, other in ((left, "left", "right"), (right, "right", "left")):
                for caption in paraphrases_for_bandai(content, style, n=60, seed=1):
                    words = _words(caption)
                    assert side in words and other not in words, (content, style, caption)


def test_captions_are_tidy() -> None:
    for caps in _all_captions(200).values():
        for caption in caps:
            assert caption == caption.strip() and caption == caption.lower(), caption
            assert "^" not in caption and "  " not in caption and " ," not in caption, caption
            assert "{" not in caption and "}" not in caption and not caption.endswith((".", ",")), caption
            assert " a a" not in f" {caption}" and " an a " not in f" {caption} ", caption
            assert not re.search(r"\b(like|as if)\b.*\b\1\b", caption), caption


def _says_style(label: str, caption: str) -> bool:
    """Whether the caption holds one of the style's entries (adjectives also hyphenated)."""
    style = PARAPHRASE_STYLES[label]
    texts = style.adjectives + style.adverbs + style.phrases + style.looks + style.steps + style.subjects
    texts += tuple(a.replace(" ", "-") for a in style.adjectives)
    return any(re.search(rf"\b{re.escape(t)}\b", caption) for t in texts)


def test_normal_style_is_style_free_about_half_the_time_and_others_never() -> None:
    caps = [c for content in _MAIN_CONTENTS for c in paraphrases_for_bandai(content, "normal", n=100)]
    free = sum(not _says_style("normal", c) for c in caps) / len(caps)
    assert 0.35 < free < 0.65, free
    for label in ("sad", "elderly", "chimpira", "tired"):
        for content in ("walk", "wave-left-hand", "bow"):
            for caption in paraphrases_for_bandai(content, label, n=100):
                assert _says_style(label, caption), (label, caption)


def test_unknown_labels_raise_naming_the_label() -> None:
    with pytest.raises(ValueError, match="moonwalk"):
        paraphrases_for_bandai("moonwalk", "normal")
    with pytest.raises(ValueError, match="sleepy-ish"):
        paraphrases_for_bandai("walk", "sleepy-ish")


def test_paraphrases_use_three_times_the_words_of_the_templates(capsys: pytest.CaptureFixture[str]) -> None:
    templates: set[str] = set()
    bank: set[str] = set()
    for content in BANDAI_CONTENTS:
        for style in BANDAI_STYLES:
            templates.update(w for c in captions_for_bandai(content, style, n=40) for w in _words(c))
            bank.update(w for c in paraphrases_for_bandai(content, style, n=40) for w in _words(c))
    assert len(bank) >= 3 * len(templates), (len(bank), len(templates))
    assert capsys.readouterr() == ("", "")
