"""Natural-language captions for motion capture that only has labels.

The Bandai Namco takes carry an action ("content") and a style label in their file names, the CMU
trials a terse one-line description (``02_03  run/jog``), and a user's own BVH files at best a
descriptive file name. A text-to-motion model wants several varied sentences per clip, so this
package turns each label set into captions by combining hand-written phrase lists (synonyms,
word order, the style as an adjective, an adverb or a phrase)::

    >>> captions_for_bandai("walk-turn-left", "exhausted", n=3, seed=0)   # doctest: +SKIP
    ['an exhausted person walks and turns to the left', 'someone worn out walks, veering left', ...]

Everything is deterministic given ``seed`` (and the labels). Mirrored clips get their captions
through :func:`motion_env.text.mirror.mirror_caption`, which swaps left and right.

What is where:

- :mod:`.files`: the entry point: :func:`labels_for_file` reads a file name into
  :class:`ClipLabels`, :func:`captions_for` writes their captions (Bandai, CMU, or the words of
  the file name: :func:`captions_for_file_name`);
- :mod:`.bandai`: Bandai Namco (content, style) -> captions (:func:`captions_for_bandai`);
- :mod:`.cmu`: the CMU index and terse descriptions -> captions (:func:`parse_cmu_index`,
  :func:`captions_for_description`, :func:`description_label`);
- :mod:`.tokens`: :func:`caption_tokens`, the ``word/POS`` field of HumanML3D's text files;
- :mod:`.grammar`: verb inflection (``^`` markers in the phrases), articles, lists;
- :mod:`.sentences`: the number of captions, the subjects, drawing distinct sentences;
- ``phrases/*.json``: the phrase tables (:mod:`.phrases` says which file holds what).
"""

from motion_env.data.captions.bandai import (
    BANDAI_CONTENTS,
    BANDAI_STYLES,
    Style,
    canonical_style,
    captions_for_bandai,
)
from motion_env.data.captions.cmu import (
    captions_for_description,
    description_label,
    parse_cmu_index,
)
from motion_env.data.captions.files import (
    BANDAI_FILE_NAME,
    CMU_FILE_NAME,
    ClipLabels,
    captions_for,
    captions_for_file_name,
    file_stem,
    labels_for_file,
)
from motion_env.data.captions.grammar import VERBS, gerund, third_person
from motion_env.data.captions.sentences import DEFAULT_NUM_CAPTIONS
from motion_env.data.captions.tokens import caption_tokens

__all__ = [
    "BANDAI_CONTENTS",
    "BANDAI_FILE_NAME",
    "BANDAI_STYLES",
    "CMU_FILE_NAME",
    "DEFAULT_NUM_CAPTIONS",
    "VERBS",
    "ClipLabels",
    "Style",
    "canonical_style",
    "caption_tokens",
    "captions_for",
    "captions_for_bandai",
    "captions_for_description",
    "captions_for_file_name",
    "description_label",
    "file_stem",
    "gerund",
    "labels_for_file",
    "parse_cmu_index",
    "third_person",
]
