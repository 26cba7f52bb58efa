"""The caption vocabulary of a trained model: the actions and styles of its training split, with
example wordings, written beside the weights for :mod:`motion_env.text.vocabulary` to read.

Run time never imports ``data/`` (docs/architecture.md), so the vocabulary is built here, once,
from a built dataset (``index.csv`` and ``texts/``) and the phrase tables, and stored as two files
in the weights folder: ``vocabulary.json`` (labels, clip counts, example wordings) and
``vocabulary.npy`` (the MiniLM embedding of every example wording, float16, in the JSON's order).
``tests/data/test_vocabulary.py`` checks that the stored files are what this module writes::

    python -c "from motion_env.data.vocabulary import *; write_vocabulary('data/mocap', 'motion_env/weights')"

Example wordings: a Bandai action is said by every verb phrase of its phrase table ("a person
walks and turns left", ...); a CMU-only action by its clips' training captions; a style by every
adjective, adverb, phrase and subject of its table, on a plain walk ("an exhausted person walks",
"a person walks wearily", ...). Style labels that are other names of one style ("old", "elderly")
are counted as one.
"""

from __future__ import annotations

import csv
import json
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.data.captions.bandai import BANDAI_CONTENTS, BANDAI_STYLES, canonical_style
from motion_env.data.captions.grammar import article, inflect, third_person
from motion_env.data.dataset import read_captions

__all__ = ["VOCABULARY_ENCODER", "action_examples", "build_vocabulary", "style_examples", "write_vocabulary"]

VOCABULARY_ENCODER = "minilm"
"""The encoder of the stored embeddings: the base of the shipped models' ``minilm+sides``."""
_CMU_EXAMPLES = 8  # training captions kept per CMU-only action


def action_examples(label: str) -> list[str]:
    """Every verb phrase of a Bandai content label as a sentence ("a person walks backward")."""
    return [f"a person {inflect(vp, third_person)}" for vp in BANDAI_CONTENTS[label]]


def style_examples(style: str) -> list[str]:
    """Every way the phrase tables say a Bandai style, on a plain walk."""
    sty = BANDAI_STYLES[style]
    out = [f"{article(a.replace(' ', '-'))} {a.replace(' ', '-')} person walks" for a in sty.adjectives]
    out += [f"a person walks {adverb}" for adverb in sty.adverbs]
    out += [f"a person walks {phrase}" for phrase in sty.phrases]
    out += [f"{subject} walks" for subject in sty.subjects]
    return list(dict.fromkeys(out))


def build_vocabulary(dataset: str | Path) -> dict[str, Any]:
    """The vocabulary of a model trained on the train split of a built dataset.

    Args:
        dataset: a folder written by ``motion-env data build`` (``index.csv``, ``texts/``).
    Returns:
        ``{"encoder", "dataset", "actions": {label: {"clips", "sources", "examples"}},
        "styles": {label: {"clips", "also", "examples"}}}``, labels by clips, most first.
    """
    root = Path(dataset)
    with open(root / "index.csv", newline="", encoding="utf-8") as f:
        rows = [r for r in csv.DictReader(f) if r["split"] == "train"]
    action_clips = Counter(r["label"] for r in rows)
    sources: dict[str, set[str]] = {}
    for r in rows:
        sources.setdefault(r["label"], set()).add(r["source"])
    actions: dict[str, Any] = {}
    for label, clips in sorted(action_clips.items(), key=lambda kv: (-kv[1], kv[0])):
        if label in BANDAI_CONTENTS:
            examples = action_examples(label)
        else:
            captions = {
                c for r in rows if r["label"] == label for c, _, _ in read_captions(_text_file(root, r))
            }
            examples = sorted(captions)[:_CMU_EXAMPLES]
        actions[label] = {"clips": clips, "sources": sorted(sources[label]), "examples": examples}
    style_clips: Counter[str] = Counter()
    aliases: dict[str, set[str]] = {}
    for r in rows:
        if r["style"] in BANDAI_STYLES:
            name = canonical_style(r["style"])
            style_clips[name] += 1
            if r["style"] != name:
                aliases.setdefault(name, set()).add(r["style"])
    styles = {
        name: {"clips": clips, "also": sorted(aliases.get(name, ())), "examples": style_examples(name)}
        for name, clips in sorted(style_clips.items(), key=lambda kv: (-kv[1], kv[0]))
    }
    return {"encoder": VOCABULARY_ENCODER, "dataset": root.name, "actions": actions, "styles": styles}


def _text_file(root: Path, row: dict[str, str]) -> Path:
    return root / "texts" / f"{row['name']}.txt"


def write_vocabulary(dataset: str | Path, folder: str | Path) -> tuple[Path, Path]:
    """Build the vocabulary of `dataset` and write ``vocabulary.json`` and ``vocabulary.npy``
    (the examples' MiniLM embeddings, (N, 384) float16, actions then styles) into `folder`."""
    from motion_env.text.encoders import load_text_encoder
    from motion_env.text.vocabulary import example_texts

    vocab = build_vocabulary(dataset)
    texts = [text for _, _, text in example_texts(vocab)]
    emb = load_text_encoder(VOCABULARY_ENCODER).encode(texts).numpy().astype(np.float16)
    folder = Path(folder)
    json_path, npy_path = folder / "vocabulary.json", folder / "vocabulary.npy"
    json_path.write_text(json.dumps(vocab, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    np.save(npy_path, emb)
    return json_path, npy_path
