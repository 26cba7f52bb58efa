"""English helpers of the caption writers: verb inflection, articles, lists, whitespace.

Verb phrases are written in base form with ``^`` before each verb to inflect; :func:`inflect`
conjugates them with :func:`third_person` or :func:`gerund`. :data:`VERBS` (from
``phrases/verbs.json``) are the verbs the description reader recognises.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence

from motion_env.data.captions.phrases import load

_TABLES = load("verbs")
# Verbs the description reader recognises at the start of a phrase (CMU, file names).
VERBS: frozenset[str] = frozenset(_TABLES["verbs"])
# Monosyllables whose final consonant doubles before -ing (run -> running).
_DOUBLE_FINAL = frozenset(_TABLES["double_final"])
_IRREGULAR_3SG = {"be": "is", "have": "has", "do": "does", "go": "goes"}


def third_person(verb: str) -> str:
    """Third-person singular present of a base-form verb (``walk`` -> ``walks``)."""
    if verb in _IRREGULAR_3SG:
        return _IRREGULAR_3SG[verb]
    if verb.endswith(("s", "sh", "ch", "x", "z")):
        return verb + "es"
    if verb.endswith("y") and len(verb) > 1 and verb[-2] not in "aeiou":
        return verb[:-1] + "ies"
    return verb + "s"


def gerund(verb: str) -> str:
    """Present participle of a base-form verb (``run`` -> ``running``, ``wave`` -> ``waving``)."""
    if verb == "be":
        return "being"
    if verb.endswith("ie"):
        return verb[:-2] + "ying"
    if verb.endswith("e") and not verb.endswith(("ee", "ye", "oe")) and len(verb) > 2:
        return verb[:-1] + "ing"
    if verb in _DOUBLE_FINAL:
        return verb + verb[-1] + "ing"
    return verb + "ing"


def verb_lemma(word: str, verbs: frozenset[str] = VERBS) -> str | None:
    """The base form of `word` when it is one of `verbs` or their third person (``jumps`` ->
    ``jump``), else None."""
    if word in verbs:
        return word
    for suffix, repl in (("ies", "y"), ("es", ""), ("s", "")):
        if word.endswith(suffix) and word[: -len(suffix)] + repl in verbs:
            return word[: -len(suffix)] + repl
    return None


def inflect(phrase: str, form: Callable[[str], str]) -> str:
    """Apply ``form`` to every ``^verb`` of a phrase and drop the markers."""
    return re.sub(r"\^([a-z]+)", lambda m: form(m.group(1)), phrase)


def article(word: str) -> str:
    """The article ("a" or "an") before ``word``, by spelling with the common exceptions."""
    w = word.lower()
    if w.startswith(("uni", "use", "one", "eu")):
        return "a"
    if w.startswith(("hour", "honest")):
        return "an"
    return "an" if w[:1] in "aeiou" else "a"


def join(items: Sequence[str], conjunction: str = "and") -> str:
    """``["a", "b", "c"]`` -> ``"a, b and c"``."""
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + f" {conjunction} " + items[-1]


def tidy(text: str) -> str:
    """Collapse runs of whitespace and drop spaces before commas."""
    text = re.sub(r"\s+", " ", text).strip()
    return re.sub(r"\s+,", ",", text)
