"""Natural-language captions for motion capture that only has labels.

The Bandai Namco takes carry an action ("content") and a style label in their file names, the CMU
trials a terse one-line description (``02_03  run/jog``), and a user's own BVH files at best a
descriptive file name. A text-to-motion model wants several varied sentences per clip, so this
module turns each label set into captions by combining hand-written phrase lists (synonyms,
word order, the style as an adjective, an adverb or a phrase)::

    >>> captions_for_bandai("walk-turn-left", "exhausted", n=3, seed=0)   # doctest: +SKIP
    ['an exhausted person walks and turns to the left', 'someone worn out walks, veering left', ...]

Everything is deterministic given ``seed`` (and the labels). :func:`mirror_caption` swaps left and
right for mirrored clips; :func:`caption_tokens` writes the ``word/POS`` token field of
HumanML3D's text files with a small lexicon tagger (HumanML3D used spaCy; only its GloVe-based
evaluators read that field).

Label-less files: :func:`captions_for_file_name` drops digits and take numbers from the file
name and reads the remaining words like a CMU description (``jump_forward_03.bvh`` -> "a person
jumps forward").
"""

from __future__ import annotations

import random
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from motion_env.text.mirror import mirror_caption

# Twelve: a text-conditioned model generalises to new wordings only when each motion is seen
# under many (HumanML3D has three human-written ones per clip; ours are drawn from phrase lists).
DEFAULT_NUM_CAPTIONS = 12

# --------------------------------------------------------------------------------------------
# Verbs: conjugation of phrases written in base form with "^" before each verb to inflect.
# --------------------------------------------------------------------------------------------

# Verbs the description reader recognises at the start of a phrase (CMU, file names).
VERBS: frozenset[str] = frozenset(
    """
    approach arch balance bend bounce bow box breaststroke carry cartwheel catch chase clap climb close
    crawl crouch cry dance dangle descend dig direct dribble dodge drag drink drop duck eat fall fight
    flip fly gallop get give go golf grab hang hide hit hold hop hug jog juggle jump kick kneel
    laugh lean leap lie lift limp look lower lunge march mop move navigate nod open paint pick
    pirouette play point pose pour pretend pull punch push put raise reach read rest ride rise
    rock roll rotate run salute scoop scratch screw sew shake shoot shuffle shrug sidestep sing
    sit skip slash slide slip sneak spin squat stagger stand step stomp stop stretch stride
    strike stroll stumble sway sweep swim swing take talk tap throw tiptoe tilt touch turn twist
    type unscrew vacuum walk wash watch wave wipe write yawn
    """.split()
)
# Monosyllables whose final consonant doubles before -ing (run -> running).
_DOUBLE_FINAL = frozenset(
    "bob chop clap dig drag drip drop flap grab hit hop hug jog nod pat put rob run shop shrug sit "
    "skip slip spin step stop strip strut swim swap tap trip trot wag".split()
)
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


def _inflect(phrase: str, form: Callable[[str], str]) -> str:
    """Apply ``form`` to every ``^verb`` of a phrase and drop the markers."""
    return re.sub(r"\^([a-z]+)", lambda m: form(m.group(1)), phrase)


# --------------------------------------------------------------------------------------------
# Bandai Namco labels.
# --------------------------------------------------------------------------------------------

# Verb phrases per content label, base form with ^ on the verbs to inflect. Sides are the
# performer's own ("left hand" = the character's left), which mirror_caption swaps. The wording
# follows what the takes show (checked on the imported joints): dataset-1's walk-left is a walk
# diagonally forward-left with the body still facing forward, not a sidestep; bye and guide use
# the right hand, respond raises the left hand, byebye waves both hands, call beckons.
BANDAI_CONTENTS: dict[str, tuple[str, ...]] = {
    "walk": (
        "^walk",
        "^walk forward",
        "^walk straight ahead",
        "^walk in a straight line",
        "^take a few steps forward",
        "^stroll forward",
        "^walk at a steady pace",
        "^walk along at a normal pace",
        "^go forward at a walking pace",
        "^move ahead step by step",
        "^walk a short distance forward",
        "^walk onward",
    ),
    "walk-turn-left": (
        "^walk and ^turn left",
        "^walk and ^turn to the left",
        "^walk, veering left",
        "^walk forward and then ^turn left",
        "^make a left turn while walking",
        "^walk along a path that curves to the left",
        "^turn left while walking",
        "^walk in an arc to the left",
        "^walk, then ^change direction to the left",
        "^walk and ^swing around to the left",
    ),
    "run": (
        "^run",
        "^run forward",
        "^run straight ahead",
        "^jog forward",
        "^run in a straight line",
        "^run fast",
        "^run quickly",
        "^break into a run",
        "^run along",
        "^go forward at a run",
        "^jog along",
        "^run at a fast pace",
        "^run ahead",
        "^trot forward quickly",
        "^move forward at a running pace",
    ),
    "dash": (
        "^sprint",
        "^dash forward",
        "^sprint forward",
        "^run very fast",
        "^rush forward at full speed",
        "^run at the fastest pace possible",
        "^sprint ahead",
        "^dash ahead at maximum speed",
        "^charge forward at high speed",
        "^sprint flat out",
        "^take off at a sprint",
        "^speed forward very quickly",
        "^run forward extremely fast",
    ),
    "walk-back": (
        "^walk backward",
        "^walk backwards",
        "^step backward",
        "^walk in reverse",
        "^back up step by step",
        "^retreat backward",
        "^take steps backward",
        "^move backward step by step",
        "^walk backward carefully",
    ),
    "walk-left": (
        "^walk diagonally forward to the left",
        "^walk forward and to the left",
        "^walk forward while drifting to the left",
        "^walk at an angle toward the left",
        "^walk ahead, bearing left",
        "^walk toward the front left",
        "^walk forward at a slant to the left",
    ),
    "wave-both-hands": (
        "^wave both hands",
        "^wave with both hands",
        "^raise both hands and ^wave",
        "^wave both arms",
        "^wave hello with both hands",
        "^wave hi with both hands",
        "^wave both hands in the air",
        "^say hello waving both hands",
        "^wave to someone with both arms",
        "^hold up both hands and ^wave them",
    ),
    "wave-left-hand": (
        "^wave the left hand",
        "^wave with the left hand",
        "^raise the left hand and ^wave",
        "^wave the left arm",
        "^wave hello with the left hand",
        "^wave hello using the left hand",
        "^say hello with the left hand",
        "^give a wave with the left hand",
        "^lift the left hand and ^wave it back and forth",
        "^wave to someone with the left hand",
        "^wave the left hand from side to side",
        "^hold up the left hand and ^wave",
        "^use the left hand to wave hi",
    ),
    "raise-up-both-hands": (
        "^raise both hands",
        "^raise both arms up",
        "^lift both hands above the head",
        "^put both hands up",
        "^hold both arms up in the air",
        "^raise both arms high in the air",
        "^throw both hands up",
        "^stretch both arms up high",
        "^reach up with both hands",
    ),
    "raise-up-left-hand": (
        "^raise the left hand",
        "^raise the left arm up",
        "^lift the left hand above the head",
        "^put the left hand up",
        "^hold the left arm up in the air",
        "^raise the left arm high",
        "^stick the left hand up",
        "^reach the left hand up high",
        "^lift the left arm up high",
        "^put up the left hand",
    ),
    "bow": ("^bow", "^bow politely", "^bend forward in a bow", "^take a bow", "^bow at the waist"),
    "bye": (
        "^wave goodbye",
        "^raise the right hand and ^wave goodbye",
        "^say bye with a wave of the hand",
        "^wave farewell with the right hand",
        "^lift a hand to wave bye",
        "^wave goodbye with the right hand",
        "^say goodbye by waving the right hand",
        "^wave bye with the right hand",
        "^wave the right hand to say goodbye",
    ),
    "byebye": (
        "^wave goodbye with both hands",
        "^wave bye-bye with both hands raised",
        "^raise both hands and ^wave goodbye",
        "^wave farewell with both arms",
        "^keep waving both hands to say goodbye",
        "^say goodbye waving both hands",
        "^wave both arms to say bye",
    ),
    "guide": (
        "^gesture to show the way",
        "^guide someone with an open hand",
        "^point the way with the right hand",
        "^show someone where to go with a hand gesture",
        "^extend the right arm to direct someone",
    ),
    "respond": (
        "^raise the left hand to respond",
        "^respond by raising the left hand high",
        "^answer by putting the left hand up",
        "^lift the left hand above the head in response",
        "^raise a hand high to answer",
        "^put the left hand up to answer",
        "^answer with the left hand raised",
    ),
    "call": (
        "^beckon someone over",
        "^call someone over with a wave of the arms",
        "^gesture for someone to come closer",
        "^wave someone over",
        "^call to someone with a beckoning gesture",
    ),
    "punch": ("^punch", "^throw punches", "^punch forward", "^strike with a fist", "^throw a punch"),
    "kick": ("^kick", "^kick forward", "^do a kick", "^kick with one leg", "^throw a kick"),
    "slash": (
        "^slash with a sword",
        "^swing a sword",
        "^make a slashing motion",
        "^cut through the air with a slash",
        "^slash with a blade",
    ),
    "dance-long": (
        "^dance",
        "^perform a long dance",
        "^dance for a while",
        "^perform a dance routine",
        "^dance with many moves",
    ),
    "dance-short": (
        "^dance",
        "^perform a short dance",
        "^dance briefly",
        "^do a short dance move",
        "^dance for a moment",
    ),
}


class Style:
    """How one style label can be said: adjectives for the person, adverbs, phrases, subjects.

    Attributes:
        adjectives: qualify the person ("an exhausted person", "someone worn out").
        adverbs: qualify the action ("wearily").
        phrases: follow the action ("in an exhausted way").
        subjects: replace the person ("a giant"); may be empty.
        neutral: a "normal" style: half of its captions carry no style words at all.
    """

    def __init__(
        self,
        adjectives: Sequence[str],
        adverbs: Sequence[str],
        phrases: Sequence[str],
        subjects: Sequence[str] = (),
        neutral: bool = False,
    ) -> None:
        self.adjectives = tuple(adjectives)
        self.adverbs = tuple(adverbs)
        self.phrases = tuple(phrases)
        self.subjects = tuple(subjects)
        self.neutral = neutral


_ELDERLY = Style(
    ["elderly", "old", "aged", "frail"],
    ["stiffly", "feebly", "slowly and stiffly"],
    ["like an elderly person", "in the manner of an old person", "with the stiffness of old age"],
    ["an elderly person", "an old person", "a senior"],
)
_EXHAUSTED = Style(
    ["exhausted", "tired", "worn out", "weary", "fatigued"],
    ["wearily", "tiredly", "sluggishly"],
    ["as if exhausted", "in an exhausted way", "with heavy, tired movements", "like someone worn out"],
)
_MASCULINE = Style(
    ["masculine", "macho", "manly"],
    ["in a manly way", "boldly"],
    ["in a masculine manner", "in a masculine way", "with broad, masculine movements"],
)
_CHILDISH = Style(
    ["childish", "childlike", "playful"],
    ["childishly", "playfully"],
    ["like a child", "in a childish way", "with childlike energy"],
)
BANDAI_STYLES: dict[str, Style] = {
    "normal": Style(
        [], ["normally", "casually", "naturally"], ["in a normal way", "in an ordinary manner"], neutral=True
    ),
    "active": Style(
        ["energetic", "lively", "active", "vigorous"],
        ["energetically", "vigorously", "actively", "briskly"],
        ["with lots of energy", "in a lively way", "full of energy"],
    ),
    "elderly": _ELDERLY,
    "old": _ELDERLY,
    "exhausted": _EXHAUSTED,
    "tired": _EXHAUSTED,
    "feminine": Style(
        ["feminine", "graceful"],
        ["gracefully", "femininely"],
        ["in a feminine manner", "in a feminine way", "with feminine movements"],
    ),
    "masculine": _MASCULINE,
    "masculinity": _MASCULINE,
    "youthful": Style(
        ["youthful", "young", "sprightly"],
        ["youthfully", "spryly"],
        ["in a youthful way", "with youthful energy", "like a young person"],
        ["a young person", "a youngster"],
    ),
    "happy": Style(
        ["happy", "cheerful", "joyful"],
        ["happily", "cheerfully", "joyfully"],
        ["in a happy mood", "with joy", "in a cheerful way"],
    ),
    "sad": Style(
        ["sad", "unhappy", "gloomy", "downcast"],
        ["sadly", "gloomily", "dejectedly"],
        ["in a sad mood", "with a sad, drooping posture", "in a sad way"],
    ),
    "angry": Style(
        ["angry", "furious", "irritated"],
        ["angrily", "furiously", "irritably"],
        ["in an angry way", "with anger", "in a fit of anger"],
    ),
    "proud": Style(
        ["proud", "self-assured", "confident"],
        ["proudly", "confidently"],
        ["with pride", "with the chest held high", "in a proud manner"],
    ),
    "not-confident": Style(
        ["unconfident", "insecure", "timid", "hesitant", "shy"],
        ["timidly", "hesitantly", "shyly"],
        ["without confidence", "in an insecure way", "with little confidence"],
    ),
    "childish": _CHILDISH,
    "children": _CHILDISH,
    "musical": Style(
        ["theatrical", "showy"],
        ["theatrically", "dramatically"],
        [
            "like a performer in a musical",
            "in a theatrical, musical style",
            "with exaggerated stage gestures",
        ],
    ),
    "giant": Style(
        ["giant", "huge", "enormous"],
        ["heavily", "ponderously"],
        ["like a giant", "with heavy, lumbering movements", "as if they were a giant"],
        ["a giant", "a huge giant"],
    ),
    "chimpira": Style(
        ["thuggish", "cocky", "delinquent"],
        ["thuggishly", "menacingly", "cockily"],
        ["like a street thug", "like a delinquent", "with a thug's swagger", "in a cocky, thuggish manner"],
        ["a thug", "a street punk"],
    ),
}

_PEOPLE = (
    "a person", "someone", "the person", "a human", "a figure", "somebody", "a man", "a woman", "the man",
    "the woman", "a performer",
)  # fmt: skip
_NOUNS = ("person", "person", "man", "woman")  # "an exhausted <noun>"
_POSTPOSITIVE_PEOPLE = ("someone", "somebody")  # "someone worn out walks"


def _article(word: str) -> str:
    """The article ("a" or "an") before ``word``, by spelling with the common exceptions."""
    w = word.lower()
    if w.startswith(("uni", "use", "one", "eu")):
        return "a"
    if w.startswith(("hour", "honest")):
        return "an"
    return "an" if w[:1] in "aeiou" else "a"


def _with_article(adjective: str, noun: str = "person") -> str:
    adjective = adjective.replace(" ", "-")  # attributive: "a worn-out person"
    return f"{_article(adjective)} {adjective} {noun}"


def _unknown_style(style: str) -> Style:
    words = style.replace("-", " ").replace("_", " ").strip()
    return Style([words], [], [f"in a {words} way", f"in a {words} manner"])


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
    verb_phrases = BANDAI_CONTENTS.get(content) or _description_verb_phrases(content.replace("-", " "))
    sty = BANDAI_STYLES.get(style) or _unknown_style(style)
    rng = random.Random(f"bandai|{content}|{style}|{seed}")

    def subject() -> str:
        return rng.choice(_PEOPLE)

    def vp() -> str:
        return _inflect(rng.choice(verb_phrases), third_person)

    def vp_gerund() -> str:
        return _inflect(rng.choice(verb_phrases), gerund)

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
    return _draw(rng, templates, n)


def _adverb_after(subject: str, verb_phrase: str, adverb: str) -> str:
    # After a phrase with a comma ("walks, veering left") a trailing adverb reads badly.
    if "," in verb_phrase:
        return f"{subject} {adverb} {verb_phrase}"
    return f"{subject} {verb_phrase} {adverb}"


def _draw(rng: random.Random, templates: Sequence[Callable[[], str]], n: int) -> list[str]:
    """Up to ``n`` distinct captions, cycling through the templates in a shuffled order."""
    out: list[str] = []
    order = list(range(len(templates)))
    rng.shuffle(order)
    attempts = 0
    while len(out) < n and attempts < 40 * max(n, 1):
        text = _tidy(templates[order[attempts % len(order)]]())
        attempts += 1
        if text not in out:
            out.append(text)
    return out


def _tidy(text: str) -> str:
    text = re.sub(r"\s+", " ", text).strip()
    return re.sub(r"\s+,", ",", text)


# --------------------------------------------------------------------------------------------
# CMU one-line descriptions (and file-name words).
# --------------------------------------------------------------------------------------------

# "slow walk" -> "walks slowly": modifiers that become adverbs after the verb.
_MODIFIER_ADVERBS = {
    "slow": "slowly",
    "brisk": "briskly",
    "fast": "fast",
    "quick": "quickly",
    "forward": "forward",
    "backward": "backward",
    "backwards": "backward",
    "sideways": "sideways",
    "side": "sideways",
    "careful": "carefully",
}
_BODY_PARTS = frozenset(
    "arm arms hand hands leg legs foot feet knee knees ankle ankles chin head shoulder shoulders "
    "hip hips elbow elbows wrist wrists body torso".split()
)
_COUNTABLE = frozenset(
    "ball ladder stool stepstool chair box table door bottle bottlecap cup bucket broom rope bar "
    "step bench bag hoop bat racket stick sword window".split()
)
_DEFINITE = frozenset("ground floor wall ceiling air".split())
_DETERMINERS = frozenset(
    "a an the my your our their his her its this that each every some both one two".split()
)
_PREPOSITIONS = frozenset("on in to for with at under over onto into against from off of by".split())
_RESPELL = {"bottlecap": "bottle cap", "stepstool": "step stool", "self": "themselves"}
# Activities named by a noun that read best with a specific verb.
_ACTIVITY_PHRASES = {
    "swordplay": ("^practice swordplay", "^fight with a sword"),
    "boxing": ("^box", "^throw boxing punches"),
    "laugh": ("^laugh",),
    "exaggerated stride": ("^walk with an exaggerated stride", "^take exaggerated strides"),
}
# Context labels before " - " in CMU descriptions.
_SPORTS = frozenset("basketball soccer football baseball golf tennis volleyball frisbee hockey".split())
_PLACES = {
    "playground": ("on playground equipment", "at a playground", "on a jungle gym"),
}
_DANCE_WORDS = frozenset({"dance", "ballet", "salsa", "dancing"})
_NUMBER = re.compile(r"^\d|^(one|two|three|four|five|six|seven|eight|nine|ten)$")


def _fix_objects(words: list[str]) -> list[str]:
    """Insert the articles and possessives a terse description leaves out."""
    out: list[str] = []
    np_start = 0  # where the current noun phrase would begin in `out`
    for i, word in enumerate(words):
        lower = word.lower()
        if i == 0 or lower in _PREPOSITIONS:
            out.append(_RESPELL.get(lower, word))
            np_start = len(out)
            continue
        head = out[np_start:]
        bare = not any(w in _DETERMINERS or _NUMBER.match(w) for w in head)
        if bare and lower in _BODY_PARTS:
            det = "the" if head and head[0] == "other" else "their"
            out.insert(np_start, det)
        elif bare and lower in _DEFINITE:
            out.insert(np_start, "the")
        elif bare and lower in _COUNTABLE:
            first = (head[0] if head else _RESPELL.get(lower, lower)).split()[0]
            out.insert(np_start, _article(first))
        out.append(_RESPELL.get(lower, word))
        if lower in _BODY_PARTS or lower in _COUNTABLE or lower in _DEFINITE:
            np_start = len(out)
    return out


def _verb_lemma(word: str) -> str | None:
    """The base form of ``word`` when it is a known verb (``jumps`` -> ``jump``), else None."""
    if word in VERBS:
        return word
    for suffix, repl in (("ies", "y"), ("es", ""), ("s", "")):
        if word.endswith(suffix) and word[: -len(suffix)] + repl in VERBS:
            return word[: -len(suffix)] + repl
    return None


def _action_phrases(action: str) -> tuple[str, ...]:
    """Verb phrases (base form, ^ on the verb) for one comma-separated action of a description."""
    words = action.split()
    if not words:
        return ()
    if action in _ACTIVITY_PHRASES:
        return _ACTIVITY_PHRASES[action]
    first, last = words[0], words[-1]
    if first in VERBS:
        return ("^" + " ".join(_fix_objects(words)),)
    # "slow walk", "forward jumps" -> "walks slowly", "jumps forward".
    lemma = _verb_lemma(last)
    if lemma and len(words) > 1 and all(w in _MODIFIER_ADVERBS for w in words[:-1]):
        return (f"^{lemma} " + " ".join(_MODIFIER_ADVERBS[w] for w in words[:-1]),)
    if first in _MODIFIER_ADVERBS.values() or first in ("left", "right", "up", "down", "around"):
        return (action,)  # a direction continuing the previous verb: "walk forward, backward"
    if first in _BODY_PARTS:
        verb = next((w for w in words[1:] if w in VERBS), None)
        if verb:  # "legs push off against" -> "pushes off with their legs"
            rest = [w for w in words[words.index(verb) + 1 :] if w != "against"]
            return (" ".join(["^" + verb, *rest, "with", *_fix_objects(["x", first])[1:]]),)
        # "hand on chin" -> "has their hand on their chin"
        return ("^have " + " ".join(_fix_objects(["x", *words])[1:]),)
    if len(words) == 1 and first.endswith("ing"):
        return (f"^be {first}",)
    if _verb_lemma(last) == last and len(words) > 1 and first not in _DETERMINERS:
        return (f"^do {_article(first)} {action}",)  # "crossover dribble" -> "does a crossover dribble"
    return (f"^do {action}",)


def _split_description(description: str) -> tuple[str | None, list[str]]:
    """``"basketball - forward dribble, shoot"`` -> ``("basketball", ["forward dribble", "shoot"])``."""
    text = description.strip().lower().rstrip(".")
    context = None
    if " - " in text:
        context, text = (part.strip() for part in text.split(" - ", 1))
    actions = [a.strip() for a in re.split(r",|;| and ", text) if a.strip()]
    return context, actions


def _choose_alternatives(rng: random.Random, text: str) -> str:
    """Pick one side of each slash: ``run/jog`` -> ``run`` or ``jog``."""
    return re.sub(r"[\w'-]+(?:/[\w'-]+)+", lambda m: rng.choice(m.group(0).split("/")), text)


def _join(items: Sequence[str], conjunction: str = "and") -> str:
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + f" {conjunction} " + items[-1]


def _description_verb_phrases(description: str) -> tuple[str, ...]:
    """Base-form verb phrases for a whole description without slashes (a Bandai fallback)."""
    _, actions = _split_description(description)
    phrases = [p for a in actions for p in _action_phrases(a)[:1]]
    return (_join(phrases),) if phrases else ("^move",)


def _dance_moves(actions: Sequence[str]) -> str:
    moves = []
    for move in actions:
        first = move.split()[0]
        plural = any(w.endswith("s") for w in move.split())
        plain = plural or first.endswith("ing") or _NUMBER.match(first) or first in _DETERMINERS
        moves.append(move if plain else f"{_article(first)} {move}")
    return _join(moves)


def captions_for_description(
    description: str, n: int = DEFAULT_NUM_CAPTIONS, seed: int | str = 0
) -> list[str]:
    """``n`` distinct captions from a terse action description such as CMU's.

    The description is split into a context (``"basketball - ..."``) and comma-separated
    actions; each action becomes a verb phrase (``"dangle legs"`` -> ``"dangles their legs"``,
    ``"slow walk"`` -> ``"walks slowly"``, ``"jumping jacks"`` -> ``"does jumping jacks"``), and
    the sentences vary the subject, the conjunctions, the slash alternatives (``run/jog``) and
    where the context goes. Unusual wording falls back to "does <words>".

    Args:
        description: e.g. ``"playground - climb, sit, dangle legs, jump down"``.
        n: how many captions (fewer only when the description allows fewer distinct sentences).
        seed: an int or a string; the same (description, seed) always gives the same captions.
    Returns:
        list of lowercase captions without final punctuation.
    """
    rng = random.Random(f"description|{description}|{seed}")

    def sentence() -> str:
        ctx, actions = _split_description(_choose_alternatives(rng, description))
        subject = rng.choice(_PEOPLE)
        if ctx is not None and ctx.split()[0] in _DANCE_WORDS:
            lead = rng.choice(("^dance", "^perform a dance", "^dance ballet"))
            moves = _dance_moves(actions)
            vp = f"{lead} with {moves}" if moves else lead
            return f"{subject} {_inflect(vp, third_person)}"
        label = None
        if ctx is not None and ctx not in _PLACES and ctx not in _SPORTS:
            if ctx.split()[0] not in VERBS:
                label = ctx  # "nursery rhyme - ...": kept as a leading label
            # a verb context ("navigate - walk forward, ...") is spelled out by its actions
        phrases = [rng.choice(_action_phrases(a)) if _action_phrases(a) else a for a in actions]
        phrases = [p for p in phrases if p]
        if not phrases:
            phrases = ["^move"]
        if len(phrases) > 1 and rng.random() < 0.35:
            # "first ..., then ..." variant for sequences.
            body = _join(phrases[:-1]) + ", then " + phrases[-1]
            body = ("first " if rng.random() < 0.5 else "") + body
        else:
            body = _join(phrases, rng.choice(("and", "and", "and then")))
        vp = _inflect(body, third_person)
        if ctx in _PLACES:
            where = rng.choice(_PLACES[ctx])
            return f"{where}, {subject} {vp}" if rng.random() < 0.4 else f"{subject} {vp} {where}"
        if ctx in _SPORTS:
            return f"{subject} {vp} while playing {ctx}" if rng.random() < 0.7 else f"{subject} {vp}"
        return f"{label}: {subject} {vp}" if label else f"{subject} {vp}"

    def progressive() -> str:
        # "someone is walking" (only reads well for one short action)
        ctx, actions = _split_description(_choose_alternatives(rng, description))
        if ctx is not None or len(actions) != 1 or not _action_phrases(actions[0]):
            return sentence()
        vp = _inflect(rng.choice(_action_phrases(actions[0])), gerund)
        if vp.startswith("being "):
            return sentence()
        return f"{rng.choice(_PEOPLE)} is {vp}"

    return _draw(rng, [sentence, sentence, progressive], n)


def captions_for_file_name(stem: str, n: int = DEFAULT_NUM_CAPTIONS, seed: int | str = 0) -> list[str]:
    """Captions for a BVH file with no labels, from the words of its file name.

    ``"Jump_Forward_03"`` -> "a person jumps forward", ...: underscores, hyphens and camelCase
    split words; digits and words like "take" are dropped; a word that names a Bandai style
    ("happy", "tired", ...) is used as the style (:func:`captions_for_bandai`); the words are
    otherwise read as a description (:func:`captions_for_description`). A name with no words
    left gives "a person moves".
    """
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", stem)
    words = [w for w in re.split(r"[\s_\-.]+", text.lower()) if w and not any(c.isdigit() for c in w)]
    words = [w for w in words if w not in ("take", "clip", "motion", "mocap", "bvh")]
    styles = [w for w in words if w in BANDAI_STYLES]
    rest = [w for w in words if w not in BANDAI_STYLES]
    if styles and rest:  # "walk_happy" -> "a happy person walks"
        return captions_for_bandai("-".join(rest), styles[0], n=n, seed=seed)
    return captions_for_description(" ".join(words) if words else "move", n=n, seed=seed)


def description_label(description: str) -> str:
    """A short label for a description, used to group clips in summaries.

    The context when there is one (``"basketball - dribble"`` -> ``"basketball"``), else the verb of
    the first action (``"slow walk"`` -> ``"walk"``), else its first word.
    """
    context, actions = _split_description(description)
    if context:
        return context
    if not actions:
        return "unlabelled"
    words = actions[0].split()
    for word in (words[0], words[-1]):
        lemma = _verb_lemma(word.split("/")[0])
        if lemma:
            return lemma
    return actions[0]


def parse_cmu_index(text: str) -> dict[str, str]:
    """Trial id -> description from the text of B. Hahne's ``CMU-INDEX.md``.

    Lines look like ``02_01  walk`` (two or more spaces or a tab after the id).
    """
    index: dict[str, str] = {}
    for line in text.splitlines():
        m = re.match(r"^\s*(\d{2,3}_\d{2,3})\s+(.+?)\s*$", line)
        if m:
            index[m.group(1)] = m.group(2)
    return index


# --------------------------------------------------------------------------------------------
# One entry point: labels read from a file name -> captions.
# --------------------------------------------------------------------------------------------

BANDAI_FILE_NAME = re.compile(r"^(dataset-\d+)_([A-Za-z0-9-]+)_([A-Za-z0-9-]+)_(\d+)$")
CMU_FILE_NAME = re.compile(r"^(\d{2,3}_\d{2,3})$")


@dataclass(frozen=True)
class ClipLabels:
    """What a motion file's name says about it.

    Attributes:
        source: ``"bandai"`` (``dataset-N_{content}_{style}_{take}``), ``"cmu"`` (a trial id such
            as ``02_01`` found in the CMU index) or ``"other"``.
        take: the file name without ``.bvh`` / ``.bvh.gz``.
        label: the action used to group clips in summaries (Bandai content, CMU context or first
            verb, else the file-name words).
        style: the Bandai style label, else ``""``.
        description: the CMU description or the file-name words, else ``""``.
    """

    source: str
    take: str
    label: str
    style: str = ""
    description: str = ""


def file_stem(path: str | Path) -> str:
    """``a/b/02_01.bvh.gz`` -> ``02_01`` (also strips ``.bvh``)."""
    name = Path(path).name
    for suffix in (".gz", ".bvh"):
        if name.lower().endswith(suffix):
            name = name[: -len(suffix)]
    return name


def labels_for_file(path: str | Path, cmu_index: Mapping[str, str] | None = None) -> ClipLabels:
    """Read the labels of a motion file from its name.

    Args:
        path: a ``.bvh`` / ``.bvh.gz`` path (only the name is used).
        cmu_index: trial id -> description (:func:`parse_cmu_index`); a CMU-style name that is
            not in it is treated as ``"other"``.
    """
    stem = file_stem(path)
    m = BANDAI_FILE_NAME.match(stem)
    if m:
        return ClipLabels("bandai", stem, m.group(2).lower(), style=m.group(3).lower())
    m = CMU_FILE_NAME.match(stem)
    if m and cmu_index and m.group(1) in cmu_index:
        description = cmu_index[m.group(1)]
        return ClipLabels("cmu", stem, description_label(description), description=description)
    words = " ".join(w for w in re.split(r"[\s_\-.]+", stem.lower()) if w and not w.isdigit())
    return ClipLabels("other", stem, words or "unlabelled", description=words)


def captions_for(labels: ClipLabels, n: int = DEFAULT_NUM_CAPTIONS, seed: int = 0) -> list[str]:
    """``n`` varied captions for a clip with these labels (deterministic given ``seed``).

    Bandai: :func:`captions_for_bandai`; CMU: :func:`captions_for_description`; other:
    :func:`captions_for_file_name`. The take id is mixed into the seed, so that the forty takes
    of one (content, style) pair do not all get the same six sentences.
    """
    key = f"{seed}|{labels.take}"
    if labels.source == "bandai":
        return captions_for_bandai(labels.label, labels.style, n=n, seed=key)
    if labels.source == "cmu":
        return captions_for_description(labels.description, n=n, seed=key)
    return captions_for_file_name(labels.take, n=n, seed=key)


# --------------------------------------------------------------------------------------------
# Mirroring and tokens.
# --------------------------------------------------------------------------------------------

# The mirrored Bandai contents are the mirror images of their left-hand versions.
for _left, _right in (
    ("walk-turn-left", "walk-turn-right"),
    ("walk-left", "walk-right"),
    ("wave-left-hand", "wave-right-hand"),
    ("raise-up-left-hand", "raise-up-right-hand"),
):
    BANDAI_CONTENTS[_right] = tuple(mirror_caption(p) for p in BANDAI_CONTENTS[_left])
del _left, _right

_POS_WORDS: dict[str, str] = {}
for _pos, _words in {
    "DET": "a an the their his her its this that each every some another both all",
    "PRON": "someone somebody they them themselves it he she something someone's who",
    "ADP": "to on in with for at over under into onto from of off against around like above "
    "behind through along without across by toward towards",
    "CCONJ": "and or but",
    "SCONJ": "while as if because",
    "AUX": "is are was were be been being",
    "PART": "not",
    "ADV": "forward backward backwards sideways away up down back then again very straight ahead "
    "together briefly first high fast",
    "ADJ": "left right other small long short big open one few many",
    "NOUN": "person human figure giant thug punk youngster senior hand hands arm arms leg legs "
    "head way manner mood style movements path line steps step turn turns goodbye farewell wave "
    "bow pride energy anger joy confidence posture chest air sword blade fist kick punch dance "
    "routine moves move moment while gesture attention response language performer motion",
}.items():
    for _w in _words.split():
        _POS_WORDS.setdefault(_w, _pos)
for _style in BANDAI_STYLES.values():
    for _w in _style.adjectives:
        for _part in [*_w.split(), _w.replace(" ", "").replace("-", "")]:
            _POS_WORDS.setdefault(_part, "ADJ")
del _pos, _words, _w, _style, _part


# Verbs of the phrase lists above that the description reader does not need.
_TAGGER_VERBS = VERBS | frozenset(
    "answer back beckon call curve do gesture guide have keep look make perform practice react "
    "reply respond rush say seem show sprint throw veer dash".split()
)


def _tagger_verb_lemma(word: str) -> str | None:
    if word in _TAGGER_VERBS:
        return word
    for suffix, repl in (("ies", "y"), ("es", ""), ("s", "")):
        if word.endswith(suffix) and word[: -len(suffix)] + repl in _TAGGER_VERBS:
            return word[: -len(suffix)] + repl
    if word.endswith("ing") and len(word) > 4:
        stem = word[:-3]
        for cand in (stem, stem + "e", stem[:-1], stem[:-1] + "ie"):
            if cand in _TAGGER_VERBS:
                return cand
        return stem
    return None


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
        closed = pos in ("DET", "PRON", "ADP", "CCONJ", "SCONJ", "AUX", "PART")
        lemma = None if closed else _tagger_verb_lemma(word)
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
