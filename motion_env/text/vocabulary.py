"""What the shipped model knows about captions, and the warning a caption gets when it falls outside.

The model learnt from captions written from action and style labels (``motion_env/data/captions``),
in English only. :func:`load_vocabulary` reads those labels with example wordings and their MiniLM
embeddings from the weights folder (``vocabulary.json``, ``vocabulary.npy``, written by
:func:`motion_env.data.vocabulary.write_vocabulary`). :func:`caption_warning` is the check the
generator makes once per distinct caption; it warns, it never changes the caption:

- **not English** (:func:`language_problem`, offline, microseconds): no letters at all (emoji,
  digits), two or more letters outside the Latin script (Chinese, Cyrillic, ...), or at least two
  words of the French / German / Spanish lists below and no more English words than those. The
  encoder still reads the caption: its vocabulary is English word pieces, so other scripts
  become mostly unknown tokens, accents are stripped, and the motion is what that embedding
  lands nearest (the warning names it);
- **far from anything known**: the caption's cosine similarity to the nearest example wording is
  below :data:`FAR_SIMILARITY` (measured on the shipped vocabulary: training captions 0.57 or
  more, the evaluation's held-out English wordings 0.37 or more, unrelated sentences 0.31 or
  less; see the model card, "Caption vocabulary");
- **too long**: more than :data:`MAX_CAPTION_CHARS` characters. MiniLM reads at most 256 word
  pieces (about 1,000-1,400 characters of English) and ignores the rest.

Every warning names the nearest known actions (when the embedding is known). numpy only.
"""

from __future__ import annotations

import json
import re
import unicodedata
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "FAR_SIMILARITY",
    "MAX_CAPTION_CHARS",
    "Nearest",
    "Vocabulary",
    "caption_warning",
    "example_texts",
    "language_problem",
    "load_vocabulary",
    "reading_text",
]

FAR_SIMILARITY = 0.35
"""A caption whose best cosine similarity to the known example wordings is below this is "far"."""
MAX_CAPTION_CHARS = 1000
"""Longer captions are cut by the encoder (256 word pieces); they get a warning."""
WEIGHTS = Path(__file__).resolve().parents[1] / "weights"

# Common words of captions. A caption is foreign when it has at least two words of one foreign list
# and no more English words than those. Words shared with English ("a", "in", "die", "son",
# "person", "con", "pie") are left out of the foreign lists.
_ENGLISH = frozenset(
    "a an the and or but then while with without to of in on at by for from into up down is are "
    "was his her their its he she they it someone somebody person man woman people forward "
    "backward left right very slowly quickly fast slow walks runs turns waves raises steps".split()
)
_FOREIGN = {
    "French": frozenset(
        "une un le la les des du et est avec dans sur très vite lentement personne homme femme qui "
        "marche court tourne gauche droite main mains lève salue puis en avant arrière".split()
    ),
    "German": frozenset(
        "eine ein einer der das den dem und mit ist sehr schnell langsam läuft geht rennt mann frau "
        "jemand links rechts hand hände dann nach vorne zurück hebt winkt sich".split()
    ),
    "Spanish": frozenset(
        "una el los las y es muy rápido rápidamente lento persona hombre mujer alguien camina corre "
        "gira izquierda derecha mano manos luego hacia adelante atrás levanta saluda".split()
    ),
}
_WORD = re.compile(r"[^\W\d_]+", re.UNICODE)


def language_problem(text: str) -> str:
    """Why `text` does not look like English ('' when it does).

    Rules (offline, no model): no letters at all; two or more letters outside the Latin script;
    at least two words of one of the French / German / Spanish lists and at least as many of them
    as English words. One foreign word ("a person walks to the café") does not count.
    """
    letters = [c for c in text if c.isalpha()]
    if not letters:
        return "it has no words (no letters at all)"
    other = [c for c in letters if not unicodedata.name(c, "").startswith("LATIN")]
    if len(other) >= 2:
        share = len(other) / len(letters)
        return f"{share:.0%} of its letters are not in the Latin script"
    words = [w.lower() for w in _WORD.findall(text)]
    english = sum(w in _ENGLISH for w in words)
    language, hits = max(
        ((name, sum(w in v for w in words)) for name, v in _FOREIGN.items()), key=lambda x: x[1]
    )
    if hits >= 2 and hits >= english:
        return f"it reads as {language} ({hits} {language} words, {english} English)"
    return ""


def example_texts(vocab: dict[str, Any]) -> Iterator[tuple[str, str, str]]:
    """(``"action"`` or ``"style"``, label, example wording) of a vocabulary, in the stored order."""
    for kind in ("action", "style"):
        for label, entry in vocab[f"{kind}s"].items():
            for text in entry["examples"]:
                yield kind, label, text


@dataclass(frozen=True)
class Nearest:
    """Where a caption lands among the known wordings.

    Attributes:
        similarity: cosine similarity to the nearest example wording of all.
        actions, styles: (label, best cosine similarity among its wordings), most similar first.
        example: the nearest example wording.
    """

    similarity: float
    actions: tuple[tuple[str, float], ...]
    styles: tuple[tuple[str, float], ...]
    example: str

    def names(self, k: int = 3) -> str:
        """The nearest `k` actions as ``"walk (0.61), run (0.55), ..."``."""
        return ", ".join(f"{label} ({sim:.2f})" for label, sim in self.actions[:k])


class Vocabulary:
    """The actions and styles a model was trained on, with example wordings and their embeddings.

    Attributes:
        encoder: the text encoder of the embeddings ("minilm").
        actions, styles: label -> ``{"clips", "examples", ...}`` as stored.
        embeddings: (N, D) float32, unit rows, one per example wording (:func:`example_texts`).
    """

    def __init__(self, vocab: dict[str, Any], embeddings: np.ndarray) -> None:
        self._stored = vocab  # as read, for save()
        self.encoder = str(vocab["encoder"])
        self.actions: dict[str, Any] = vocab["actions"]
        self.styles: dict[str, Any] = vocab["styles"]
        rows = list(example_texts(vocab))
        if embeddings.shape[0] != len(rows):
            raise ValueError(f"vocabulary: {len(rows)} example wordings but {embeddings.shape[0]} embeddings")
        self._kinds = np.array([kind for kind, _, _ in rows])
        self._labels = np.array([label for _, label, _ in rows])
        self.texts = [text for _, _, text in rows]
        emb = np.asarray(embeddings, np.float32)
        self.embeddings = emb / np.linalg.norm(emb, axis=1, keepdims=True)

    @property
    def dim(self) -> int:
        return int(self.embeddings.shape[1])

    def save(self, folder: str | Path) -> tuple[Path, Path]:
        """Write ``vocabulary.json`` and ``vocabulary.npy`` into a weights folder (as
        :func:`load_vocabulary` reads them; the embeddings as float16, as shipped)."""
        folder = Path(folder)
        json_path, npy_path = folder / "vocabulary.json", folder / "vocabulary.npy"
        json_path.write_text(json.dumps(self._stored, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        np.save(npy_path, self.embeddings.astype(np.float16))
        return json_path, npy_path

    def nearest(self, embedding: np.ndarray) -> Nearest:
        """Where a caption's embedding ((D,), the `encoder`'s) lands among the known wordings."""
        e = np.asarray(embedding, np.float32)[: self.dim]
        sims = self.embeddings @ (e / max(float(np.linalg.norm(e)), 1e-12))  # (N,)

        def best(kind: str) -> tuple[tuple[str, float], ...]:
            mask = self._kinds == kind
            per = {}
            for label, sim in zip(self._labels[mask], sims[mask], strict=True):
                per[str(label)] = max(per.get(str(label), -1.0), float(sim))
            return tuple(sorted(per.items(), key=lambda kv: -kv[1]))

        i = int(np.argmax(sims))
        return Nearest(float(sims[i]), best("action"), best("style"), self.texts[i])


@lru_cache(maxsize=4)
def load_vocabulary(folder: str | Path = WEIGHTS) -> Vocabulary | None:
    """The vocabulary stored in a weights folder (default: the shipped model's); None if it has none."""
    folder = Path(folder)
    json_path, npy_path = folder / "vocabulary.json", folder / "vocabulary.npy"
    if not (json_path.is_file() and npy_path.is_file()):
        return None
    return Vocabulary(json.loads(json_path.read_text(encoding="utf-8")), np.load(npy_path))


def _quoted(text: str, limit: int = 60) -> str:
    return repr(text if len(text) <= limit else text[: limit - 3] + "...")


def reading_text(reading: dict[str, list[tuple[str, float]]]) -> str:
    """A caption adapter's reading (:meth:`CaptionAdapter.read_labels` row) as the warnings say it:
    ``"run 0.62, dash 0.20; style normal 0.41, active 0.30"``."""
    actions = ", ".join(f"{label} {p:.2f}" for label, p in reading.get("actions", []))
    styles = ", ".join(f"{label} {p:.2f}" for label, p in reading.get("styles", []))
    return f"{actions}; style {styles}" if styles else actions


def caption_warning(
    text: str,
    embedding: np.ndarray | None = None,
    vocabulary: Vocabulary | None = None,
    reading: Callable[[], str] | None = None,
) -> str:
    """The warning a caption gets ('' for none): not English, too long, or far from every known
    wording (the last needs `embedding`, the caption's embedding by ``vocabulary.encoder``).

    Args:
        text: a checked caption (non-empty, stripped).
        embedding: (D,) the caption's embedding (a longer row, e.g. a ``+sides`` one, is cut to D);
            None: only the checks on the text itself.
        vocabulary: what the model knows (None: no similarity check).
        reading: gives what the caption adapter reads in the caption ("run 0.62, dash 0.20;
            style normal 0.41"), which the motion follows; called only for a caption that warns.
            None: there is no adapter.
    """
    nearest = None
    if embedding is not None and vocabulary is not None:
        nearest = vocabulary.nearest(embedding)
    problems = []
    language = language_problem(text)
    if language:
        problems.append(f"does not look like English: {language}; the model knows English captions only")
    if len(text) > MAX_CAPTION_CHARS:
        problems.append(
            f"is {len(text):,} characters long: the text encoder reads about the first "
            f"{MAX_CAPTION_CHARS:,} characters (256 word pieces) and ignores the rest"
        )
    if nearest is not None and nearest.similarity < FAR_SIMILARITY:
        problems.append(
            f"is far from every caption the model was trained on (similarity {nearest.similarity:.2f}, "
            f"below {FAR_SIMILARITY:.2f})"
        )
    if not problems:
        return ""
    message = f"caption {_quoted(text)} " + "; it ".join(problems)
    if reading is not None:
        message += f". The caption adapter reads it as {reading()}, and the motion follows that"
        if nearest is not None:
            message += f" (nearest known actions: {nearest.names()})"
    elif nearest is not None:
        message += f". The motion follows the nearest known actions: {nearest.names()}"
    return message + " (motion-env captions lists what the model knows)"
