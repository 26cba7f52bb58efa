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
    "walk-left": "heads forward on foot, straying off leftward",
    "walk-right": "heads forward on foot, straying off rightward",
    "run": "hurries ahead at full tilt",
    "dash": "bolts ahead at top speed",
    "wave-both-hands": "greets someone, both arms swinging overhead",
    "wave-left-hand": "greets someone, swinging the left arm overhead",
    "wave-right-hand": "greets someone, swinging the right arm overhead",
    "raise-up-both-hands": "elevates both arms up above the head",
    "raise-up-left-hand": "elevates the left arm up above the head",
    "raise-up-right-hand": "elevates the right arm up above the head",
}
STYLE_WORDS = {
    "active": "a peppy", "elderly": "a wizened", "exhausted": "a drained", "feminine": "a ladylike",
    "masculine": "a burly", "normal": "an unremarkable", "youthful": "a teenage",
}  # fmt: skip


# A second set of new words in another sentence frame ("<style> figure <action>"), written before
# any caption model was trained on paraphrases, so that a single lucky phrasing decides nothing.
ACTION_WORDS_2 = {
    "walk": "strides along in a straight line",
    "walk-turn-left": "strides along, then wheels around toward the left",
    "walk-turn-right": "strides along, then wheels around toward the right",
    "walk-left": "advances at an angle off to the left",
    "walk-right": "advances at an angle off to the right",
    "run": "tears down the track at a gallop",
    "dash": "rockets off in an all-out burst",
    "wave-both-hands": "flails both arms high to get noticed",
    "wave-left-hand": "signals with the left palm, flapping it high",
    "wave-right-hand": "signals with the right palm, flapping it high",
    "raise-up-both-hands": "hoists both arms skyward",
    "raise-up-left-hand": "hoists the left arm skyward",
    "raise-up-right-hand": "hoists the right arm skyward",
}
STYLE_WORDS_2 = {
    "active": "a spirited", "elderly": "a doddering", "exhausted": "a spent", "feminine": "a dainty",
    "masculine": "a brawny", "normal": "a regular", "youthful": "a juvenile",
}  # fmt: skip
# The words that carry the action or style in each held-out wording and steering caption above (a
# test keeps them out of every caption a model trains on).
CARRYING_WORDS = (
    "ambles", "unhurried", "gait", "saunters", "clip", "pounding", "races", "legs", "friend",
    "drags", "nineties", "pep",
    "foot", "curving", "leftward", "rightward", "heads", "straying", "hurries", "tilt", "bolts",
    "top", "greets", "overhead", "elevates", "peppy", "wizened", "drained", "ladylike", "burly",
    "unremarkable", "teenage", "strides", "wheels", "advances", "tears", "track",
    "gallop", "rockets", "burst", "flails", "noticed", "signals", "palm", "flapping", "hoists",
    "skyward", "spirited", "doddering", "spent", "dainty", "brawny", "regular", "juvenile",
)  # fmt: skip


def heldout_captions(label: str, style: str) -> list[str]:
    """The held-out new wordings of a take's labels (empty for labels without them)."""
    if label not in ACTION_WORDS:
        return []
    return [
        f"{STYLE_WORDS.get(style, 'a')} person {ACTION_WORDS[label]}",
        f"{STYLE_WORDS_2.get(style, 'a')} figure {ACTION_WORDS_2[label]}",
    ]


def heldout_caption(label: str, style: str, fallback: str) -> str:
    """The first held-out new wording of a take's labels (or `fallback`)."""
    return next(iter(heldout_captions(label, style)), fallback)
