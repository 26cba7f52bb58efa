"""Captions of the evaluation, in words and sentence frames the training captions never use.

A test (``tests/evaluation/test_captions.py``) fails if the words that carry any of them ever
appear in the training captions, so these measure how the model generalises to new wordings.
"""

from __future__ import annotations

# Captions written for the evaluation, in words and sentence frames the training captions
# (motion_env/data/captions) do not use.
WALK_CAPTIONS = (
    "someone ambles along at an easy, unhurried gait",
    "a man makes his way forward on foot at a comfortable clip",
    "the character saunters ahead calmly",
)
RUN_CAPTIONS = (
    "someone hurries along at full tilt, feet pounding",
    "a woman races ahead as fast as her legs allow",
    "the character bolts forward at top speed",
)
# For contrast only: running captions in the training phrasing (motion_env/data/captions).
RUN_CAPTIONS_TRAINING_PHRASING = ("a person runs forward", "someone jogs straight ahead")
WAVE_RIGHT = ("standing still, someone greets a friend by waving with the right hand",)
WAVE_LEFT = ("standing still, someone greets a friend by waving with the left hand",)
TURN_LEFT = ("a man makes his way forward on foot, then curves off leftward",)
TURN_RIGHT = ("a man makes his way forward on foot, then curves off rightward",)
STYLE_CAPTIONS = {
    "exhausted": ("drained and out of breath, an exhausted man drags himself forward",),
    "elderly": ("an elderly gentleman in his nineties makes his way forward with care",),
    "active": ("full of pep, an active young woman heads forward",),
}
# Held-out takes: the take's action and style in new words.
ACTION_WORDS = {
    "walk": "makes their way straight ahead on foot",
    "walk-turn-left": "makes their way forward on foot, curving off leftward",
    "walk-turn-right": "makes their way forward on foot, curving off rightward",
    "walk-left": "heads forward on foot, drifting off leftward",
    "walk-right": "heads forward on foot, drifting off rightward",
    "run": "hurries ahead at full tilt",
    "dash": "bolts ahead at top speed",
    "wave-both-hands": "greets someone, both arms swinging overhead",
    "wave-left-hand": "greets someone, swinging the left arm overhead",
    "wave-right-hand": "greets someone, swinging the right arm overhead",
    "raise-up-both-hands": "lifts both arms up above the head",
    "raise-up-left-hand": "lifts the left arm up above the head",
    "raise-up-right-hand": "lifts the right arm up above the head",
}
STYLE_WORDS = {
    "active": "a peppy", "elderly": "a frail old", "exhausted": "a drained", "feminine": "a graceful",
    "masculine": "a burly", "normal": "an ordinary", "youthful": "a teenage",
}  # fmt: skip


def heldout_caption(label: str, style: str, fallback: str) -> str:
    """A caption for a held-out take written from its labels in new words (or `fallback`)."""
    if label not in ACTION_WORDS:
        return fallback
    return f"{STYLE_WORDS.get(style, 'a')} person {ACTION_WORDS[label]}"
