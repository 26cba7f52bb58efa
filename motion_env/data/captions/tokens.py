"""HumanML3D's ``word/POS`` token field (``caption#tokens#start#end`` lines) for our captions.

HumanML3D tagged its captions with spaCy; only its GloVe-based evaluators read the field, so a
small lexicon tagger (``phrases/pos.json`` plus the verbs and the Bandai style adjectives of the
caption writers) and a few word-order rules are enough for the sentences written here.
"""

from __future__ import annotations

import re

from motion_env.data.captions.bandai import BANDAI_STYLES
from motion_env.data.captions.grammar import VERBS, verb_lemma
from motion_env.data.captions.phrases import load


def _lexicon() -> tuple[dict[str, str], frozenset[str]]:
    """Word -> part of speech (the first one listing the word wins), and the verbs."""
    tables = load("pos")
    pos_of: dict[str, str] = {}
    for pos, words in tables["words"].items():
        for word in words:
            pos_of.setdefault(word, pos)
    for style in BANDAI_STYLES.values():
        for adjective in style.adjectives:
            for part in [*adjective.split(), adjective.replace(" ", "").replace("-", "")]:
                pos_of.setdefault(part, "ADJ")
    return pos_of, VERBS | frozenset(tables["verbs"])


_POS_WORDS, _TAGGER_VERBS = _lexicon()
_CLOSED_CLASSES = ("DET", "PRON", "ADP", "CCONJ", "SCONJ", "AUX", "PART")


def _verb_lemma(word: str) -> str | None:
    """:func:`verb_lemma` over the tagger's verbs, and for an -ing form its known stem (else the
    word less its ending)."""
    lemma = verb_lemma(word, _TAGGER_VERBS)
    if lemma is None and word.endswith("ing") and len(word) > 4:
        stem = word[:-3]
        return next((c for c in (stem, stem + "e", stem[:-1], stem[:-1] + "ie") if c in _TAGGER_VERBS), stem)
    return lemma


def _noun_lemma(word: str) -> str:
    if word.endswith("ies") and len(word) > 4:
        return word[:-3] + "y"
    if word.endswith("s") and not word.endswith(("ss", "us", "is")):
        return word[:-1]
    return word


def caption_tokens(caption: str) -> str:
    """HumanML3D's ``word/POS`` token field for a caption (e.g. ``a/DET person/NOUN walk/VERB``).

    Mirrors HumanML3D's ``process_text``: hyphens removed, non-alphabetic tokens dropped, nouns and
    verbs lemmatised (except "left"). Tags come from a small lexicon plus word-order rules, not
    spaCy, so uncommon words may be tagged differently from HumanML3D.
    """
    words = [w.lower() for w in re.findall(r"[A-Za-z]+", caption.replace("-", ""))]
    tokens = []
    prev_pos = ""
    seen_verb = False
    for word in words:
        pos = _POS_WORDS.get(word)
        lemma = None if pos in _CLOSED_CLASSES else _verb_lemma(word)
        # A verb form right after a subject, a manner adverb, a conjunction or an auxiliary, or
        # the first one after an adjective ("someone weary walks").
        after = prev_pos in ("", "PRON", "NOUN", "CCONJ", "AUX", "PART") or (
            prev_pos == "ADV" and tokens[-1].split("/")[0].endswith("ly")
        )
        if lemma and (after or word.endswith("ing") or (prev_pos == "ADJ" and not seen_verb)):
            pos = "VERB"
        elif lemma and prev_pos == "ADP" and tokens and tokens[-1].startswith("to/") and pos is None:
            pos = "VERB"
        elif pos is None:
            pos = "ADV" if word.endswith("ly") else "NOUN"
        if word in ("left", "right") and prev_pos == "VERB":
            pos = "ADV"
        if word == "left" or pos not in ("NOUN", "VERB"):
            out = word
        else:
            out = (lemma or word) if pos == "VERB" else _noun_lemma(word)
        tokens.append(f"{out}/{pos}")
        prev_pos = pos
        seen_verb = seen_verb or pos == "VERB"
    return " ".join(tokens)
