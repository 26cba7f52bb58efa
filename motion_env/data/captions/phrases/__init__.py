"""The phrase tables of the caption writers: JSON files in this folder, each read once at import.

- ``verbs.json``: ``verbs``, the verbs the description reader recognises at the start of an
  action, and ``double_final``, the monosyllables that double their last consonant before -ing
  (:mod:`motion_env.data.captions.grammar`).
- ``bandai_contents.json``: Bandai Namco content label -> verb phrases; the right-side contents
  are derived from the left-side ones (:mod:`motion_env.data.captions.bandai`).
- ``bandai_styles.json``: style label -> ``adjectives``, ``adverbs``, ``phrases`` and optional
  ``subjects`` / ``neutral`` (see :class:`motion_env.data.captions.bandai.Style`), or the name of
  the style label it is another name for (``"old": "elderly"``).
- ``paraphrases.json``: the paraphrase bank of the caption adapter's training captions, in words
  the templates above never use (:mod:`motion_env.data.captions.paraphrases`).
- ``cmu_descriptions.json``: the word lists the description reader uses to turn terse action
  descriptions into sentences (:mod:`motion_env.data.captions.cmu`).
- ``pos.json``: the lexicon of the ``word/POS`` tagger (``words``: part of speech -> words, the
  first part of speech listing a word wins; ``verbs``: verbs of the phrase tables beyond
  ``verbs.json``) (:mod:`motion_env.data.captions.tokens`).

Verb phrases are written in base form with ``^`` before each verb to inflect
(``"^walk and ^turn left"`` -> "walks and turns left", "walking and turning left").
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def load(name: str) -> Any:
    """The parsed contents of ``<name>.json`` in this folder."""
    return json.loads(Path(__file__).with_name(f"{name}.json").read_text(encoding="utf-8"))
