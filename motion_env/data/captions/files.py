"""One entry point for the dataset builder: a motion file's name -> its labels -> captions.

- Bandai Namco takes are named ``dataset-N_{content}_{style}_{take}`` (:mod:`.bandai`);
- CMU trials by their id (``02_01``), looked up in the CMU index (:mod:`.cmu`);
- any other file by its words: :func:`captions_for_file_name` drops digits and take numbers and
  reads the rest like a CMU description (``jump_forward_03.bvh`` -> "a person jumps forward").
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from motion_env.data.captions.bandai import BANDAI_STYLES, captions_for_bandai
from motion_env.data.captions.cmu import captions_for_description, description_label
from motion_env.data.captions.sentences import DEFAULT_NUM_CAPTIONS

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
        cmu_index: trial id -> description (:func:`.cmu.parse_cmu_index`); a CMU-style name that
            is not in it is treated as ``"other"``.
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


def captions_for_file_name(stem: str, n: int = DEFAULT_NUM_CAPTIONS, seed: int | str = 0) -> list[str]:
    """Captions for a BVH file with no labels, from the words of its file name.

    ``"Jump_Forward_03"`` -> "a person jumps forward", ...: underscores, hyphens and camelCase
    split words; digits and words like "take" are dropped; a word that names a Bandai style
    ("happy", "tired", ...) is used as the style (:func:`.bandai.captions_for_bandai`); the words
    are otherwise read as a description (:func:`.cmu.captions_for_description`). A name with no
    words left gives "a person moves".
    """
    text = re.sub(r"([a-z])([A-Z])", r"\1 \2", stem)
    words = [w for w in re.split(r"[\s_\-.]+", text.lower()) if w and not any(c.isdigit() for c in w)]
    words = [w for w in words if w not in ("take", "clip", "motion", "mocap", "bvh")]
    styles = [w for w in words if w in BANDAI_STYLES]
    rest = [w for w in words if w not in BANDAI_STYLES]
    if styles and rest:  # "walk_happy" -> "a happy person walks"
        return captions_for_bandai("-".join(rest), styles[0], n=n, seed=seed)
    return captions_for_description(" ".join(words) if words else "move", n=n, seed=seed)


def captions_for(labels: ClipLabels, n: int = DEFAULT_NUM_CAPTIONS, seed: int = 0) -> list[str]:
    """``n`` varied captions for a clip with these labels (deterministic given ``seed``).

    Bandai: :func:`.bandai.captions_for_bandai`; CMU: :func:`.cmu.captions_for_description`;
    other: :func:`captions_for_file_name`. The take id is mixed into the seed, so that the forty
    takes of one (content, style) pair do not all get the same six sentences.
    """
    key = f"{seed}|{labels.take}"
    if labels.source == "bandai":
        return captions_for_bandai(labels.label, labels.style, n=n, seed=key)
    if labels.source == "cmu":
        return captions_for_description(labels.description, n=n, seed=key)
    return captions_for_file_name(labels.take, n=n, seed=key)
