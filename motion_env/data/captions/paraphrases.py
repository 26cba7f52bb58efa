"""Paraphrases of the Bandai Namco labels: training data for the caption adapter.

The generator learnt its actions from the captions of
:func:`~motion_env.data.captions.captions_for_bandai`: a few hundred words in a few sentence
shapes. :func:`paraphrases_for_bandai` says the same (content, style) pairs in wordings those
templates never use, so that the caption adapter (:mod:`motion_env.models.caption_adapter`) learns
to map other wordings onto the labels::

    >>> paraphrases_for_bandai("walk-turn-left", "elderly", n=3, seed=0)   # doctest: +SKIP
    ['the performer leading with the shoulders into a left turn while walking as old people do',
     'in a hallway, a white-haired performer walks in a left-turning arc', ...]

The bank (``phrases/paraphrases.json``) extends the template tables (:data:`BANDAI_CONTENTS`,
:data:`BANDAI_STYLES`, all reused): verb phrases per content in several registers (plain,
casual, literary, biomechanical, sports, animation direction); per style adjectives, adverbs,
trailing phrases, subjects ("a grandpa") and how the body looks ("back hunched"; ``steps`` only
for the walks); subjects, take nouns, settings; and the sentence frames, ``str.format`` strings
whose fields are listed above :data:`_STYLE_FIELDS`. Frames without style fields are style-free:
only the "normal" style uses them (half of its captions). As in :mod:`.bandai`, sides are the
performer's own and the right-side contents are the mirror images of the left-side ones.
"""

from __future__ import annotations

import random
import re
import string
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, replace

from motion_env.data.captions.bandai import BANDAI_CONTENTS, BANDAI_STYLES
from motion_env.data.captions.grammar import article, gerund, inflect, third_person
from motion_env.data.captions.phrases import load
from motion_env.data.captions.sentences import DEFAULT_NUM_CAPTIONS, draw
from motion_env.text.mirror import mirror_caption

__all__ = ["PARAPHRASE_CONTENTS", "PARAPHRASE_STYLES", "ParaphraseStyle", "paraphrases_for_bandai"]

_BANK = load("paraphrases")
# The right-side contents are the mirror images of the left-side ones (walk-left -> walk-right).
_MIRRORED = tuple((label, label.replace("left", "right")) for label in BANDAI_CONTENTS if "left" in label)
# Verbs beyond grammar's list that double their last consonant before -ing (plod -> plodding).
_DOUBLE_FINAL = frozenset(_BANK["double_final"])
# Adverbs of the template tables that are really trailing phrases ("in a manly way").
_PREPOSITIONS = ("in ", "with ", "like ", "as ")


@dataclass(frozen=True)
class ParaphraseStyle:
    """The ways to say one style label (all lowercase, without final punctuation).

    Attributes:
        adjectives: for the person ("exhausted", "worn out": hyphenated before a noun).
        adverbs: for the action ("wearily").
        phrases: follow the action ("as if running on empty").
        subjects: replace the person ("a grandpa").
        looks: how the body looks, after a comma ("shoulders slumped").
        steps: like ``looks``, only for walking contents ("shuffling the feet").
        neutral: the "normal" style: half of its captions carry no style words.
    """

    adjectives: tuple[str, ...]
    adverbs: tuple[str, ...]
    phrases: tuple[str, ...]
    subjects: tuple[str, ...]
    looks: tuple[str, ...]
    steps: tuple[str, ...]
    neutral: bool = False


def _unique(*groups: Iterable[str]) -> tuple[str, ...]:
    return tuple(dict.fromkeys(item for group in groups for item in group))


def _contents() -> dict[str, tuple[str, ...]]:
    bank: dict[str, list[str]] = _BANK["contents"]
    contents = {
        label: _unique(BANDAI_CONTENTS.get(label, ()), bank.get(label, ()))
        for label in {**BANDAI_CONTENTS, **bank}
    }
    for left, right in _MIRRORED:
        contents[right] = _unique(contents[right], (mirror_caption(p) for p in contents[left]))
    return contents


def _styles() -> dict[str, ParaphraseStyle]:
    bank: dict[str, dict | str] = _BANK["styles"]
    styles: dict[str, ParaphraseStyle] = {}
    for label, spec in bank.items():
        if isinstance(spec, str):  # another name for a label ("old": "elderly")
            continue
        old = BANDAI_STYLES[label]  # the template words come first
        styles[label] = ParaphraseStyle(
            adjectives=_unique(old.adjectives, spec.get("adjectives", ())),
            adverbs=_unique(
                (a for a in old.adverbs if not a.startswith(_PREPOSITIONS)), spec.get("adverbs", ())
            ),
            phrases=_unique(
                old.phrases, (a for a in old.adverbs if a.startswith(_PREPOSITIONS)), spec["phrases"]
            ),
            subjects=_unique(old.subjects, spec.get("subjects", ())),
            looks=tuple(spec.get("looks", ())),
            steps=tuple(spec.get("steps", ())),
            neutral=bool(spec.get("neutral", False)),
        )
    styles.update((label, styles[spec]) for label, spec in bank.items() if isinstance(spec, str))
    return styles


# Verb phrases per content label (base form, ^ before the verbs to inflect): the template
# phrases and the bank's, the right-side contents mirrored from the left-side ones.
PARAPHRASE_CONTENTS: dict[str, tuple[str, ...]] = _contents()
# The ways to say each style label (its aliases share one entry).
PARAPHRASE_STYLES: dict[str, ParaphraseStyle] = _styles()

_SUBJECTS: dict[str, str] = _BANK["subjects"]  # subject -> the pronoun of a second sentence
_SUBJECT_LIST = tuple(_SUBJECTS)
_PRONOUNS = frozenset(("he", "she", "they"))
_NOUN_SUBJECTS = tuple(s for s in _SUBJECTS if s not in _PRONOUNS)  # "a person walking forward"
_WALKING = frozenset(_BANK["walking"])
_REPEATED = re.compile(r"\b(like|as if)\b.*\b\1\b")  # a comparison said twice
_FRAMES: tuple[str, ...] = tuple(_BANK["frames"])
# The fields of the frames: {s} a subject ("a man", "she", "they"), {n} one that is never a
# pronoun ("a man walking"), {v} the verb phrase agreeing with {s}, {v3} in the third person, {g}
# the gerund, {b} the base form ("walk forward"), {be} "is" or "are", {take} "animation", {a_take}
# "an animation", {where} a setting ("in a park"), {linking} "seems", {pro_look} / {pro_move} the
# pronoun of {s} and a verb ("she looks"); and the style fields, with the table each needs:
_STYLE_FIELDS = {
    "adj": "adjectives",  # "worn out"
    "an_adj": "adjectives",  # "a worn-out man"
    "the_adj": "adjectives",  # "the worn-out woman"
    "adv": "adverbs",
    "v_adv": "adverbs",  # {v} and an adverb, before the verb when the phrase has a comma
    "b_adv": "adverbs",
    "g_adv": "adverbs",
    "phr": "phrases",
    "look": "looks",
    "ss": "subjects",
}


def _fields(frame: str) -> frozenset[str]:
    return frozenset(name for _, name, _, _ in string.Formatter().parse(frame) if name)


def _gerund(verb: str) -> str:
    return verb + verb[-1] + "ing" if verb in _DOUBLE_FINAL else gerund(verb)


def _base(verb: str) -> str:
    return "are" if verb == "be" else verb


def _with_adverb(phrase: str, adverb: str) -> str:
    # After a phrase with a comma ("walks, veering left") a trailing adverb reads badly.
    return f"{adverb} {phrase}" if "," in phrase else f"{phrase} {adverb}"


def _caption(rng: random.Random, frame: str, verb_phrases: Sequence[str], style: ParaphraseStyle) -> str:
    """One caption: ``frame`` with every field drawn from the tables."""
    subject = rng.choice(_SUBJECT_LIST)
    agree = _base if subject == "they" else third_person
    pronoun = _SUBJECTS[subject]
    pro_agree = _base if pronoun == "they" else third_person
    vp = rng.choice(verb_phrases)
    adjective = rng.choice(style.adjectives) if style.adjectives else ""
    attributive = f"{adjective.replace(' ', '-')} {rng.choice(_BANK['nouns'])}"
    adverb = rng.choice(style.adverbs) if style.adverbs else ""
    take = rng.choice(_BANK["takes"])
    values = {
        "s": subject,
        "n": rng.choice(_NOUN_SUBJECTS),
        "v": inflect(vp, agree),
        "v3": inflect(vp, third_person),
        "g": inflect(vp, _gerund),
        "b": inflect(vp, _base),
        "be": agree("be"),
        "take": take,
        "a_take": f"{article(take)} {take}",
        "where": rng.choice(_BANK["settings"]),
        "linking": rng.choice(_BANK["linking"]),
        "pro_look": f"{pronoun} {pro_agree('look')}",
        "pro_move": f"{pronoun} {pro_agree('move')}",
        "adj": adjective,
        "an_adj": f"{article(attributive)} {attributive}",
        "the_adj": f"the {attributive}",
        "adv": adverb,
        "v_adv": _with_adverb(inflect(vp, agree), adverb),
        "b_adv": _with_adverb(inflect(vp, _base), adverb),
        "g_adv": _with_adverb(inflect(vp, _gerund), adverb),
        "phr": rng.choice(style.phrases) if style.phrases else "",
        "look": rng.choice(style.looks) if style.looks else "",
        "ss": rng.choice(style.subjects) if style.subjects else "",
    }
    return frame.format_map(values)


def paraphrases_for_bandai(
    content: str, style: str, n: int = DEFAULT_NUM_CAPTIONS, seed: int | str = 0
) -> list[str]:
    """``n`` distinct paraphrases of a Bandai Namco take labelled (content, style).

    Training data for the caption adapter: the same meaning as the template captions of
    :func:`~motion_env.data.captions.captions_for_bandai`, in wordings those templates never use
    (other verbs, registers, subjects, sentence shapes and added context).

    Args:
        content: the action label, a key of :data:`PARAPHRASE_CONTENTS` (``"walk-turn-left"``).
        style: the style label, a key of :data:`PARAPHRASE_STYLES` (``"exhausted"``).
        n: how many captions (fewer only when the bank allows fewer distinct sentences).
        seed: an int or a string; the same (labels, seed) always gives the same captions.
    Returns:
        list of lowercase captions without final punctuation.
    Raises:
        ValueError: for a content or style label the bank does not cover.
    """
    content_key = content.strip().lower()
    style_key = style.strip().lower()
    if content_key not in PARAPHRASE_CONTENTS:
        raise ValueError(
            f"no paraphrases for the content label {content!r}; known: {sorted(PARAPHRASE_CONTENTS)}"
        )
    if style_key not in PARAPHRASE_STYLES:
        raise ValueError(f"no paraphrases for the style label {style!r}; known: {sorted(PARAPHRASE_STYLES)}")
    verb_phrases = PARAPHRASE_CONTENTS[content_key]
    sty = PARAPHRASE_STYLES[style_key]
    sty = replace(sty, looks=sty.looks + (sty.steps if content_key in _WALKING else ()))
    rng = random.Random(f"paraphrase|{content_key}|{style_key}|{seed}")

    def template(frame: str) -> Callable[[], str]:
        def caption() -> str:
            text = _caption(rng, frame, verb_phrases, sty)
            for _ in range(8):  # "run like the wind like a giant": draw again
                if not _REPEATED.search(text):
                    break
                text = _caption(rng, frame, verb_phrases, sty)
            return text

        return caption

    styled: list[Callable[[], str]] = []
    plain: list[Callable[[], str]] = []
    for frame in _FRAMES:
        tables = {_STYLE_FIELDS[name] for name in _fields(frame) if name in _STYLE_FIELDS}
        if not tables:
            plain.append(template(frame))
        elif all(getattr(sty, table) for table in tables):
            styled.append(template(frame))
    # Half of a neutral style's captions say nothing about style; the others always do.
    templates = plain * max(1, round(len(styled) / len(plain))) + styled if sty.neutral else styled
    return draw(rng, templates, n)
