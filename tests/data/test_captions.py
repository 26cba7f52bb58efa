"""Captions from labels (motion_env.data.captions): variety, determinism, left/right mirroring, CMU
descriptions, file names, tokens, and the phrase tables they are drawn from."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import pytest

from motion_env.data.captions import (
    BANDAI_CONTENTS,
    BANDAI_STYLES,
    ClipLabels,
    canonical_style,
    caption_tokens,
    captions_for,
    captions_for_bandai,
    captions_for_description,
    captions_for_file_name,
    labels_for_file,
    parse_cmu_index,
)
from motion_env.text.mirror import mirror_caption


def _words(text: str) -> set[str]:
    return set(re.findall(r"[a-z]+", text.lower()))


def test_bandai_captions_are_varied_and_deterministic() -> None:
    caps = captions_for_bandai("walk-turn-left", "exhausted", n=6, seed=0)
    assert len(caps) == 6 and len(set(caps)) == 6
    assert caps == captions_for_bandai("walk-turn-left", "exhausted", n=6, seed=0)
    assert caps != captions_for_bandai("walk-turn-left", "exhausted", n=6, seed=1)
    exhausted = set().union(*(_words(w) for w in BANDAI_STYLES["exhausted"].adjectives))
    exhausted |= {"wearily", "tiredly", "sluggishly", "exhausted", "tired"}
    for c in caps:
        words = _words(c)
        assert "left" in words and "right" not in words, c
        assert words & {"walk", "walks", "walking"}, c
        assert words & exhausted, c  # the style is said in every caption, one way or another
    # several sentence shapes, not one template with synonyms swapped
    assert len({c.split()[0] for c in caps}) >= 3


@pytest.mark.parametrize("content", sorted(BANDAI_CONTENTS))
def test_every_bandai_label_pair_gives_five_distinct_captions(content: str) -> None:
    for style in BANDAI_STYLES:
        caps = captions_for_bandai(content, style, n=6, seed=3)
        assert len(set(caps)) >= 5, (content, style, caps)
        for c in caps:
            assert c == c.strip() and "  " not in c and "#" not in c and "^" not in c, c
            if "left" in content:
                assert "left" in _words(c), c
            if "right" in content:
                assert "right" in _words(c), c


def test_normal_style_often_says_nothing_about_style() -> None:
    caps = captions_for_bandai("run", "normal", n=6, seed=0)
    style_words = {"normally", "casually", "naturally", "normal", "ordinary"}
    assert any(not (_words(c) & style_words) for c in caps)


def test_unknown_labels_still_get_captions() -> None:
    caps = captions_for_bandai("jump-rope", "sleepy", n=5, seed=0)
    assert len(set(caps)) == 5
    assert all("sleepy" in c for c in caps)


def test_mirror_caption_swaps_sides_and_is_an_involution() -> None:
    assert mirror_caption("a person turns left, then raises the right hand") == (
        "a person turns right, then raises the left hand"
    )
    assert (
        mirror_caption("Left foot forward, spins clockwise") == "Right foot forward, spins counterclockwise"
    )
    assert mirror_caption("wave-left-hand") == "wave-right-hand"
    assert (
        mirror_caption("he stops right away and says all right") == "he stops right away and says all right"
    )
    text = "someone walks leftward and turns to the right"
    assert mirror_caption(mirror_caption(text)) == text
    # the right-hand Bandai contents are the left-hand ones mirrored
    assert BANDAI_CONTENTS["wave-right-hand"] == tuple(
        mirror_caption(p) for p in BANDAI_CONTENTS["wave-left-hand"]
    )
    for c in captions_for_bandai("walk-turn-right", "giant", n=6, seed=0):
        assert "right" in _words(c) and "left" not in _words(c), c


def test_cmu_descriptions_read_naturally() -> None:
    caps = captions_for_description("playground - climb, sit, dangle legs, jump down", n=6, seed=0)
    assert len(set(caps)) == 6
    for c in caps:
        assert "climbs" in c and "dangles their legs" in c and "jumps down" in c, c
        assert "playground" in c or "jungle gym" in c, c
    assert any("walks slowly" in c for c in captions_for_description("slow walk", seed=0))
    assert any("jogs" in c for c in captions_for_description("run/jog", n=6, seed=0))
    assert any("runs" in c for c in captions_for_description("run/jog", n=6, seed=0))
    caps = captions_for_description("soccer - kick ball", n=6, seed=0)
    assert all("kick" in c and "a ball" in c for c in caps), caps
    caps = captions_for_description("basketball - forward dribble, 90-degree left turns", n=6, seed=0)
    assert all("dribbles forward" in c and "left turns" in c for c in caps), caps


def test_parse_cmu_index_format() -> None:
    text = "Subject #2 (various)\n\n02_01  walk\n\n02_03  run/jog\n13_29\tjumping jacks\nnot an entry\n"
    assert parse_cmu_index(text) == {"02_01": "walk", "02_03": "run/jog", "13_29": "jumping jacks"}


def test_every_real_cmu_description_gives_five_captions(require_data: Callable[[str], Path]) -> None:
    index = parse_cmu_index(require_data("cmu/CMU-INDEX.md").read_text(encoding="utf-8"))
    assert len(index) > 2000 and index["02_01"] == "walk"
    for trial, description in index.items():
        caps = captions_for_description(description, n=5, seed=0)
        assert len(set(caps)) >= 5 or len(description.split()) <= 1, (trial, description, caps)
        assert all(c and "^" not in c and "#" not in c for c in caps), (trial, caps)


def test_labels_and_captions_from_file_names() -> None:
    index = {"02_03": "run/jog"}
    bandai = labels_for_file("x/dataset-2_walk-turn-left_exhausted_001.bvh.gz", index)
    assert bandai == ClipLabels(
        "bandai", "dataset-2_walk-turn-left_exhausted_001", "walk-turn-left", "exhausted"
    )
    cmu = labels_for_file("/data/cmu/02_03.bvh.gz", index)
    assert (cmu.source, cmu.take, cmu.label, cmu.description) == ("cmu", "02_03", "run", "run/jog")
    other = labels_for_file("/data/99_99.bvh", index)  # a CMU-like name missing from the index
    assert other.source == "other"
    assert captions_for(bandai, n=5) == captions_for_bandai(
        "walk-turn-left", "exhausted", n=5, seed=f"0|{bandai.take}"
    )
    other_take = ClipLabels("bandai", "dataset-2_walk-turn-left_exhausted_002", "walk-turn-left", "exhausted")
    assert captions_for(other_take, n=5) != captions_for(bandai, n=5)  # takes get different wording
    caps = captions_for_file_name("Jump_Forward_03", n=5, seed=0)
    assert len(set(caps)) == 5 and all("jump" in c and "forward" in c for c in caps)
    caps = captions_for_file_name("walkHappy", n=5, seed=0)  # a Bandai style word becomes the style
    happy = {"happy", "happily", "cheerful", "cheerfully", "joyful", "joyfully", "joy"}
    assert all(_words(c) & happy for c in caps), caps
    assert captions_for_file_name("take_001", n=2) == captions_for_description("move", n=2)


def test_caption_tokens_follow_humanml3d() -> None:
    assert caption_tokens("a person walks forward.") == "a/DET person/NOUN walk/VERB forward/ADV"
    tokens = caption_tokens("someone worn-out waves the left hands, veering left")
    assert tokens.split() == [
        "someone/PRON",
        "wornout/ADJ",
        "wave/VERB",
        "the/DET",
        "left/ADJ",
        "hand/NOUN",
        "veer/VERB",
        "left/ADV",
    ]
    for caption in captions_for_bandai("raise-up-both-hands", "happy", n=6):
        for token in caption_tokens(caption).split():
            word, pos = token.split("/")
            assert word.isalpha() and pos.isupper(), token


def test_phrase_tables_are_well_formed() -> None:
    # The JSON tables of motion_env/data/captions/phrases: every content phrase starts with a verb
    # to inflect, every style can be said, and another name for a style is that very style.
    for content, phrases in BANDAI_CONTENTS.items():
        assert phrases and all(p.startswith("^") and p == p.strip() for p in phrases), content
    for label, style in BANDAI_STYLES.items():
        assert style.adverbs and style.phrases and (style.adjectives or style.neutral), label
    for alias, label in [("old", "elderly"), ("tired", "exhausted"), ("children", "childish")]:
        assert BANDAI_STYLES[alias] is BANDAI_STYLES[label]
        assert canonical_style(alias) == canonical_style(label) == label
    assert canonical_style("exhausted") == "exhausted" and canonical_style("gliding") == "gliding"
    assert {"walk", "run", "wave-right-hand", "dance-short"} <= set(BANDAI_CONTENTS)
