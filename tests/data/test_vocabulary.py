"""The vocabulary stored beside the shipped weights is what motion_env.data.vocabulary writes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from motion_env.data.vocabulary import action_examples, build_vocabulary, style_examples
from motion_env.generation.generator import DEFAULT_WEIGHTS
from motion_env.text.vocabulary import example_texts, load_vocabulary

DATASET = Path(__file__).resolve().parents[2] / "data" / "mocap"  # the build the weights came from
STORED = json.loads((DEFAULT_WEIGHTS / "vocabulary.json").read_text(encoding="utf-8"))


def test_examples_are_the_phrase_tables() -> None:
    for label, entry in STORED["actions"].items():
        if "bandai" in entry["sources"]:
            assert entry["examples"] == action_examples(label), label
    for label, entry in STORED["styles"].items():
        assert entry["examples"] == style_examples(label), label


def test_same_as_a_build_of_the_dataset() -> None:
    if not (DATASET / "index.csv").is_file():
        pytest.skip(f"no built dataset at {DATASET} (motion-env data build ... --out data/mocap)")
    assert build_vocabulary(DATASET) == STORED


def test_embeddings_are_the_encoders() -> None:
    from motion_env.text.encoders import load_text_encoder

    vocab = load_vocabulary()
    texts = [text for _, _, text in example_texts(STORED)]
    assert vocab.texts == texts and vocab.embeddings.shape == (len(texts), 384)
    rows = np.linspace(0, len(texts) - 1, 12).astype(int)
    emb = load_text_encoder(vocab.encoder).encode([texts[i] for i in rows]).numpy()
    cos = np.sum(emb * vocab.embeddings[rows], axis=1)
    assert cos.min() > 0.999, cos
