"""`motion-env captions`: the actions and styles the shipped model was trained on, with example
wordings; ``--check CAPTION`` says where a caption lands among them and whether it would warn."""

from __future__ import annotations

import argparse
import json
from typing import Any

from motion_env.cli.common import CommandError, add_threads, set_threads

__all__ = ["add_captions"]


def add_captions(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "captions",
        help="list the actions and styles the model knows; --check a caption against them",
        description=(
            "List the actions and styles the shipped model was trained on (clips in its training split, "
            "example wordings), or, with --check, the known actions and styles a caption lands nearest "
            "to (cosine similarity of MiniLM embeddings) and the warning generating from it would give."
        ),
    )
    p.add_argument("--check", metavar="CAPTION", default=None, help="a caption to place among the known ones")
    p.add_argument("--examples", type=int, default=3, help="example wordings shown per label (default 3)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_threads(p)
    p.set_defaults(run=run_captions)


def run_captions(args: argparse.Namespace) -> int:
    from motion_env.generation.request import check_text
    from motion_env.text.vocabulary import load_vocabulary

    if args.examples < 0:
        raise CommandError(f"--examples must be >= 0, got {args.examples}")
    text = None if args.check is None else check_text(args.check, "--check")
    if text is not None:
        set_threads(args.threads)
    vocab = load_vocabulary()
    if vocab is None:
        raise CommandError("the shipped weights have no vocabulary.json / vocabulary.npy")
    if text is None:
        _print_vocabulary(vocab, args.examples, args.json)
    else:
        _print_check(vocab, text, args)
    return 0


def _print_vocabulary(vocab: Any, examples: int, as_json: bool) -> None:
    if as_json:
        print(json.dumps({"actions": vocab.actions, "styles": vocab.styles}, indent=1))
        return
    for kind, table in (("actions", vocab.actions), ("styles", vocab.styles)):
        print(f"{kind} (training clips, example wordings):")
        for label, entry in table.items():
            also = f" (also {', '.join(entry['also'])})" if entry.get("also") else ""
            print(f"  {label}{also}: {entry['clips']} clips")
            for example in entry["examples"][:examples]:
                print(f"      {example}")


def _print_check(vocab: Any, text: str, args: argparse.Namespace) -> None:
    from motion_env.generation.caption_readers import load_caption_reader
    from motion_env.generation.generator import DEFAULT_WEIGHTS
    from motion_env.text.encoders import load_text_encoder
    from motion_env.text.vocabulary import FAR_SIMILARITY, caption_warning, reading_text

    adapter, _ = load_caption_reader(DEFAULT_WEIGHTS, None)
    # One encoder when the adapter reads the vocabulary's ("minilm+sides" starts with "minilm").
    shared = adapter is not None and adapter.config.encoder.split("+")[0] == vocab.encoder
    encoder = load_text_encoder(adapter.config.encoder if shared else vocab.encoder)
    row = encoder.encode([text])
    embedding = row[0].numpy()
    nearest = vocab.nearest(embedding)
    reading = None
    if adapter is not None:
        row = row if shared else load_text_encoder(adapter.config.encoder).encode([text])
        reading = adapter.read_labels(row)[0]
    top2 = None if reading is None else {k: v[:2] for k, v in reading.items()}
    warning = caption_warning(
        text, embedding, vocab, reading=None if top2 is None else lambda: reading_text(top2)
    )
    if args.json:
        report = {
            "caption": text, "similarity": nearest.similarity, "far_below": FAR_SIMILARITY,
            "nearest_example": nearest.example, "actions": dict(nearest.actions[:5]),
            "styles": dict(nearest.styles[:5]), "warning": warning,
            "adapter_reads": None if reading is None else {k: dict(v) for k, v in reading.items()},
        }  # fmt: skip
        print(json.dumps(report, indent=1, ensure_ascii=False))
        return
    print(f"caption: {text!r}")
    print(
        f"nearest known wording: {nearest.example!r} "
        f"(similarity {nearest.similarity:.2f}; far below {FAR_SIMILARITY:.2f})"
    )
    print("nearest actions: " + ", ".join(f"{label} {sim:.2f}" for label, sim in nearest.actions[:5]))
    print("nearest styles: " + ", ".join(f"{label} {sim:.2f}" for label, sim in nearest.styles[:5]))
    if reading is not None:
        for key in ("actions", "styles"):
            probs = ", ".join(f"{label} {p:.2f}" for label, p in reading[key])
            print(f"the caption adapter reads {key}: {probs}")
    print(f"warning: {warning}" if warning else "no warning")
