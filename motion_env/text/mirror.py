"""Caption mirroring: swap left and right in a caption, for the mirror image of a clip.

Used where a motion is mirrored (the dataset build stores every take mirrored, with mirrored
captions) and by :class:`motion_env.text.encoders.SidedEncoder`, whose side vector is the
difference between the embeddings of a caption and of its mirror image.
"""

from __future__ import annotations

import re

__all__ = ["mirror_caption"]

_SWAPS = {
    "left": "right",
    "right": "left",
    "leftward": "rightward",
    "rightward": "leftward",
    "leftwards": "rightwards",
    "rightwards": "leftwards",
    "clockwise": "counterclockwise",
    "counterclockwise": "clockwise",
    "anticlockwise": "clockwise",
    "counter-clockwise": "clockwise",
    "anti-clockwise": "clockwise",
}
_SWAP_RE = re.compile(
    r"\b(counter-clockwise|anti-clockwise|counterclockwise|anticlockwise|clockwise|"
    r"leftwards|rightwards|leftward|rightward|left|right)\b"
    # "right away", "right now", "all right" are not sides.
    r"(?!\s+(?:away|now|after|before|then|here|there)\b)",
    re.IGNORECASE,
)


def mirror_caption(text: str) -> str:
    """Swap left and right (and clockwise / counterclockwise) for a mirrored clip.

    Case is kept (``Left`` -> ``Right``); ``right away``/``right now``/``all right`` are left alone.
    "left" as the past tense of "leave" cannot be told apart and is swapped too.
    """

    def swap(m: re.Match[str]) -> str:
        word = m.group(1)
        if word.lower() == "right" and re.search(r"\ball\s+$", text[: m.start()], re.IGNORECASE):
            return word
        new = _SWAPS[word.lower()]
        if word.isupper():
            return new.upper()
        return new[0].upper() + new[1:] if word[0].isupper() else new

    return _SWAP_RE.sub(swap, text)
