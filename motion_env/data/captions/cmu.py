"""Captions from terse action descriptions: CMU's one-line trial descriptions, file-name words.

A description is an optional context and comma-separated actions (``"playground - climb, sit,
dangle legs, jump down"``, ``"02_03  run/jog"`` in ``CMU-INDEX.md``). Each action becomes a verb
phrase with the articles and possessives a terse description leaves out, and the sentences vary
the subject, the conjunctions, the slash alternatives and where the context goes. The word lists
are in ``phrases/cmu_descriptions.json``.

- :func:`parse_cmu_index`: trial id -> description, from ``CMU-INDEX.md``;
- :func:`captions_for_description`: the captions;
- :func:`description_label`: a short label to group clips in summaries;
- :func:`description_verb_phrases`: one verb phrase for a whole description (the fallback for
  unknown Bandai contents).
"""

from __future__ import annotations

import random
import re
from collections.abc import Sequence

from motion_env.data.captions.grammar import VERBS, article, gerund, inflect, join, third_person, verb_lemma
from motion_env.data.captions.phrases import load
from motion_env.data.captions.sentences import DEFAULT_NUM_CAPTIONS, PEOPLE, draw

_TABLES = load("cmu_descriptions")
# "slow walk" -> "walks slowly": modifiers that become adverbs after the verb.
_MODIFIER_ADVERBS: dict[str, str] = _TABLES["modifier_adverbs"]
_BODY_PARTS = frozenset(_TABLES["body_parts"])  # get "their" ("dangle legs" -> "dangles their legs")
_COUNTABLE = frozenset(_TABLES["countable"])  # get "a" ("kick ball" -> "kicks a ball")
_DEFINITE = frozenset(_TABLES["definite"])  # get "the" ("touch ground" -> "touches the ground")
_DETERMINERS = frozenset(_TABLES["determiners"])
_PREPOSITIONS = frozenset(_TABLES["prepositions"])
_RESPELL: dict[str, str] = _TABLES["respell"]
# Activities named by a noun that read best with a specific verb.
_ACTIVITY_PHRASES = {k: tuple(v) for k, v in _TABLES["activity_phrases"].items()}
# Context labels before " - " in CMU descriptions.
_SPORTS = frozenset(_TABLES["sports"])
_PLACES = {k: tuple(v) for k, v in _TABLES["places"].items()}
_DANCE_WORDS = frozenset(_TABLES["dance_words"])
_NUMBER = re.compile(r"^\d|^(one|two|three|four|five|six|seven|eight|nine|ten)$")


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
            out.insert(np_start, article(first))
        out.append(_RESPELL.get(lower, word))
        if lower in _BODY_PARTS or lower in _COUNTABLE or lower in _DEFINITE:
            np_start = len(out)
    return out


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
    lemma = verb_lemma(last)
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
    if verb_lemma(last) == last and len(words) > 1 and first not in _DETERMINERS:
        return (f"^do {article(first)} {action}",)  # "crossover dribble" -> "does a crossover dribble"
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


def description_verb_phrases(description: str) -> tuple[str, ...]:
    """Base-form verb phrases for a whole description without slashes (a Bandai fallback)."""
    _, actions = _split_description(description)
    phrases = [p for a in actions for p in _action_phrases(a)[:1]]
    return (join(phrases),) if phrases else ("^move",)


def _dance_moves(actions: Sequence[str]) -> str:
    moves = []
    for move in actions:
        first = move.split()[0]
        plural = any(w.endswith("s") for w in move.split())
        plain = plural or first.endswith("ing") or _NUMBER.match(first) or first in _DETERMINERS
        moves.append(move if plain else f"{article(first)} {move}")
    return join(moves)


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
        subject = rng.choice(PEOPLE)
        if ctx is not None and ctx.split()[0] in _DANCE_WORDS:
            lead = rng.choice(("^dance", "^perform a dance", "^dance ballet"))
            moves = _dance_moves(actions)
            vp = f"{lead} with {moves}" if moves else lead
            return f"{subject} {inflect(vp, third_person)}"
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
            body = join(phrases[:-1]) + ", then " + phrases[-1]
            body = ("first " if rng.random() < 0.5 else "") + body
        else:
            body = join(phrases, rng.choice(("and", "and", "and then")))
        vp = inflect(body, third_person)
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
        vp = inflect(rng.choice(_action_phrases(actions[0])), gerund)
        if vp.startswith("being "):
            return sentence()
        return f"{rng.choice(PEOPLE)} is {vp}"

    return draw(rng, [sentence, sentence, progressive], n)


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
        lemma = verb_lemma(word.split("/")[0])
        if lemma:
            return lemma
    return actions[0]
