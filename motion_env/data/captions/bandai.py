"""Captions for Bandai Namco takes, from the (content, style) labels of their file names.

:data:`BANDAI_CONTENTS` holds verb phrases per content label and :data:`BANDAI_STYLES` the ways
to say each style (``phrases/bandai_contents.json``, ``phrases/bandai_styles.json``);
:func:`captions_for_bandai` combines them in varied sentence shapes::

    >>> captions_for_bandai("walk-turn-left", "exhausted", n=3, seed=0)   # doctest: +SKIP
    ['an exhausted person walks and turns to the left', 'someone worn out walks, veering left', ...]

Sides are the performer's own ("left hand" = the character's left), which
:func:`motion_env.text.mirror.mirror_caption` swaps; the right-side contents are the mirror
images of the left-side ones. The wording follows what the takes show (checked on the imported
joints): dataset-1's walk-left is a walk diagonally forward-left with the body still facing
forward, not a sidestep; bye and guide use the right hand, respond raises the left hand, byebye
waves both hands, call beckons.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass

from motion_env.data.captions.cmu import description_verb_phrases
from motion_env.data.captions.grammar import article, gerund, inflect, third_person
from motion_env.data.captions.phrases import load
from motion_env.data.captions.sentences import DEFAULT_NUM_CAPTIONS, PEOPLE, draw
from motion_env.text.mirror import mirror_caption


@dataclass(frozen=True)
class Style:
    """How one style label can be said: adjectives for the person, adverbs, phrases, subjects.

    Attributes:
        adjectives: qualify the person ("an exhausted person", "someone worn out").
        adverbs: qualify the action ("wearily").
        phrases: follow the action ("in an exhausted way").
        subjects: replace the person ("a giant"); may be empty.
        neutral: a "normal" style: half of its captions carry no style words at all.
    """

    adjectives: tuple[str, ...]
    adverbs: tuple[str, ...]
    phrases: tuple[str, ...]
    subjects: tuple[str, ...] = ()
    neutral: bool = False

    def __post_init__(self) -> None:
        # The phrase tables are JSON lists; a style is kept immutable.
        for name in ("adjectives", "adverbs", "phrases", "subjects"):
            object.__setattr__(self, name, tuple(getattr(self, name)))


def _load_styles() -> dict[str, Style]:
    styles: dict[str, Style] = {}
    for label, spec in load("bandai_styles").items():
        # A string names the label this one is another name for ("old": "elderly").
        styles[label] = styles[spec] if isinstance(spec, str) else Style(**spec)
    return styles


# Verb phrases per content label, base form with ^ on the verbs to inflect.
BANDAI_CONTENTS: dict[str, tuple[str, ...]] = {k: tuple(v) for k, v in load("bandai_contents").items()}
BANDAI_CONTENTS.update(
    (right, tuple(mirror_caption(p) for p in BANDAI_CONTENTS[left]))
    for left, right in (
        ("walk-turn-left", "walk-turn-right"),
        ("walk-left", "walk-right"),
        ("wave-left-hand", "wave-right-hand"),
        ("raise-up-left-hand", "raise-up-right-hand"),
    )
)
BANDAI_STYLES: dict[str, Style] = _load_styles()


def canonical_style(style: str) -> str:
    """The first label of :data:`BANDAI_STYLES` that names the same style as `style` ("old" ->
    "elderly"); `style` itself when the table does not know it."""
    spec = BANDAI_STYLES.get(style)
    return next((label for label, other in BANDAI_STYLES.items() if other is spec), style)


_NOUNS = ("person", "person", "man", "woman")  # "an exhausted <noun>"
_POSTPOSITIVE_PEOPLE = ("someone", "somebody")  # "someone worn out walks"


def _with_article(adjective: str, noun: str = "person") -> str:
    adjective = adjective.replace(" ", "-")  # attributive: "a worn-out person"
    return f"{article(adjective)} {adjective} {noun}"


def _unknown_style(style: str) -> Style:
    words = style.replace("-", " ").replace("_", " ").strip()
    return Style([words], [], [f"in a {words} way", f"in a {words} manner"])


def _adverb_after(subject: str, verb_phrase: str, adverb: str) -> str:
    # After a phrase with a comma ("walks, veering left") a trailing adverb reads badly.
    if "," in verb_phrase:
        return f"{subject} {adverb} {verb_phrase}"
    return f"{subject} {verb_phrase} {adverb}"


def captions_for_bandai(
    content: str, style: str, n: int = DEFAULT_NUM_CAPTIONS, seed: int | str = 0
) -> list[str]:
    """``n`` distinct captions for a Bandai Namco take labelled (content, style).

    Unknown labels still get captions: the content is read like a CMU description and the
    style is used as an adjective ("in a <style> way").

    Args:
        content: the action label of the file name, e.g. ``"walk-turn-left"``.
        style: the style label, e.g. ``"exhausted"``.
        n: how many captions (fewer only when the labels allow fewer distinct sentences).
        seed: an int or a string; the same (labels, seed) always gives the same captions.
    Returns:
        list of lowercase captions without final punctuation.
    """
    content = content.strip().lower()
    style = style.strip().lower()
    verb_phrases = BANDAI_CONTENTS.get(content) or description_verb_phrases(content.replace("-", " "))
    sty = BANDAI_STYLES.get(style) or _unknown_style(style)
    rng = random.Random(f"bandai|{content}|{style}|{seed}")

    def subject() -> str:
        return rng.choice(PEOPLE)

    def vp() -> str:
        return inflect(rng.choice(verb_phrases), third_person)

    def vp_gerund() -> str:
        return inflect(rng.choice(verb_phrases), gerund)

    templates: list[Callable[[], str]] = []
    if sty.adjectives:
        templates += [
            lambda: f"{_with_article(rng.choice(sty.adjectives), rng.choice(_NOUNS))} {vp()}",
            lambda: f"{rng.choice(sty.adjectives)}, {subject()} {vp()}",
            lambda: f"{subject()} {vp()}, looking {rng.choice(sty.adjectives)}",
            lambda: f"{rng.choice(_POSTPOSITIVE_PEOPLE)} {rng.choice(sty.adjectives)} {vp()}",
            lambda: (
                f"{subject()} who {rng.choice(('is', 'looks', 'seems'))} {rng.choice(sty.adjectives)} {vp()}"
            ),
            lambda: f"{_with_article(rng.choice(sty.adjectives), rng.choice(_NOUNS))} {vp_gerund()}",
            lambda: f"looking {rng.choice(sty.adjectives)}, {subject()} {vp()}",
        ]
    if sty.adverbs:
        templates += [
            lambda: f"{subject()} {rng.choice(sty.adverbs)} {vp()}",
            lambda: _adverb_after(subject(), vp(), rng.choice(sty.adverbs)),
        ]
    if sty.phrases:
        templates.append(lambda: f"{subject()} {vp()} {rng.choice(sty.phrases)}")
    if sty.subjects:
        templates.append(lambda: f"{rng.choice(sty.subjects)} {vp()}")
    if sty.neutral:
        plain = [
            lambda: f"{subject()} {vp()}",
            lambda: f"{subject()} is {vp_gerund()}",
            lambda: f"{subject()} can be seen {vp_gerund()}",
        ]
        # Half of a neutral style's captions say nothing about style.
        templates = plain * max(1, len(templates)) + templates
    return draw(rng, templates, n)
