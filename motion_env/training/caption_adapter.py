"""Training of the caption adapter (:mod:`motion_env.models.caption_adapter`) on text alone.

A caption reader is a text encoder plus the caption adapter trained for it; this trains the
adapter for any encoder :func:`~motion_env.text.encoders.load_text_encoder` knows
(``motion-env train caption-adapter --encoder minilm+sides|mpnet+sides|clip``), with the targets
in the space of the encoder the generator's models read (``--target-encoder``, ``minilm+sides``).

The examples (:func:`adapter_examples`):

- every (action, style) pair of the train split's Bandai Namco takes: its template captions (the
  wording the generator was trained on, :func:`~motion_env.data.captions.captions_for_bandai`) and
  its paraphrases (other words, :func:`~motion_env.data.captions.paraphrases.paraphrases_for_bandai`),
  all with one target: the pair's *prototype*, the mean embedding of its template captions (the
  sentence half renormalised to unit length, the side half averaged), which is where the
  generator's models answer with that action in that style; the heads learn the pair's labels;
- the captions of the train split's clips without those labels (CMU descriptions): the action
  head learns "unlabelled" and the target is the caption's own embedding, so the adapter leaves
  what it does not know where it was.

A batch draws pairs in proportion to ``clips ** prior`` (0: every pair as often, 1: as often as
the data has it; the unlabelled captions count as one more pair), then captions within them. The
loss: the squared distance of the adapter's output to the target, the same for the regression
branch alone, and ``label_weight`` times the cross-entropy of the action and style heads; the
embeddings get the generator's training jitter (:func:`~motion_env.text.encoders.jitter_embeddings`).
Validation: paraphrases of another seed, not among the training captions.

Encoding 30k captions takes minutes (MiniLM, one thread); the embeddings are kept next to the
checkpoint (``<out>.embeddings.pt``, per encoder), so a second run encodes only new captions.
"""

from __future__ import annotations

import csv
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn import functional as F
from tqdm.auto import tqdm

from motion_env.data.captions import BANDAI_STYLES, captions_for_bandai
from motion_env.data.captions.paraphrases import paraphrases_for_bandai
from motion_env.data.dataset import read_captions
from motion_env.models.caption_adapter import CaptionAdapter, CaptionAdapterConfig
from motion_env.models.checkpoint import atomic_torch_save
from motion_env.motion.validation import NonNegativeFloat, PositiveFloat, PositiveInt
from motion_env.text.encoders import DEFAULT_TEXT_ENCODER, TextEncoder, jitter_embeddings
from motion_env.training import loop
from motion_env.training.config import TrainConfig

CHECKPOINT_KIND = "caption_adapter"
TEMPLATES_PER_PAIR = 40  # template captions per (action, style): the prototype's sample
VAL_SEED = 10_000  # the paraphrase seed of the validation captions (training draws `seed`)


@dataclass(kw_only=True)
class CaptionAdapterTrainConfig(TrainConfig):
    """Settings of :func:`train_caption_adapter` (each is a ``motion-env train`` option)."""

    steps: PositiveInt = 3000  # optimisation steps
    batch_size: PositiveInt = 256  # captions per step
    lr: PositiveFloat = 1e-3  # peak learning rate (linear warm-up, cosine decay)
    paraphrases: PositiveInt = 120  # paraphrases drawn per (action, style) pair
    prior: NonNegativeFloat = 0.5  # pairs are drawn in proportion to their training clips ** prior
    text_noise: NonNegativeFloat = 0.3  # jitter of the input embeddings (expected norm)
    label_weight: NonNegativeFloat = 0.1  # weight of the action and style cross-entropies
    hidden: PositiveInt = 512  # width of the adapter's hidden layers
    layers: PositiveInt = 2  # hidden layers
    dropout: NonNegativeFloat = 0.1  # dropout on the hidden layers
    temperature: PositiveFloat = 1.0  # sharpness of the pair weights at use (stored in the model config)
    encoder: str = DEFAULT_TEXT_ENCODER  # the text encoder the adapter reads: minilm, mpnet, clip (+sides)
    encoder_weights: str | None = None  # weights of --encoder on disk (none: the encoder's own search)
    target_encoder: str = DEFAULT_TEXT_ENCODER  # the encoder the generator's models read (the targets)
    save_every: PositiveInt = 500
    log_every: PositiveInt = 250


@dataclass
class AdapterExamples:
    """Captions with their targets, labels and sampling weights.

    Attributes:
        texts: N captions.
        targets: (N, out_dim) float32 embeddings the adapter should output.
        actions: N action-head classes (the last class: unlabelled).
        styles: N style indices (-1: no style).
        weights: N sampling probabilities (summing to 1).
    """

    texts: list[str]
    targets: np.ndarray
    actions: np.ndarray
    styles: np.ndarray
    weights: np.ndarray

    def subset(self, keep: np.ndarray) -> AdapterExamples:
        """The examples where `keep` is True (weights renormalised)."""
        w = self.weights[keep]
        return AdapterExamples(
            [t for t, k in zip(self.texts, keep, strict=True) if k], self.targets[keep],
            self.actions[keep], self.styles[keep], w / max(float(w.sum()), 1e-12),
        )  # fmt: skip


@dataclass
class LabelTable:
    """The labels the adapter learns: actions, styles, the known pairs with their training clips
    and their prototypes ((pairs, out_dim), in the order of `pairs`)."""

    actions: list[str]
    styles: list[str]
    pairs: list[tuple[str, str]]
    clips: list[int]
    prototypes: torch.Tensor


def canonical_style(style: str) -> str:
    """The style label another label names ("old" -> "elderly"); itself otherwise."""
    spec = BANDAI_STYLES.get(style)
    for name, other in BANDAI_STYLES.items():
        if other is spec:
            return name
    return style


def _index_rows(data_dir: Path) -> list[dict[str, str]]:
    path = Path(data_dir) / "index.csv"
    if not path.is_file():
        raise FileNotFoundError(f"{data_dir}: no index.csv (build the dataset with motion-env data build)")
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def labelled_pairs(data_dir: Path) -> dict[tuple[str, str], int]:
    """(action, style) -> clips, of the train split's Bandai takes (styles by their canonical name)."""
    rows = [
        r for r in _index_rows(data_dir)
        if r.get("source") == "bandai" and r.get("label") and r.get("split") == "train"
    ]  # fmt: skip
    if not rows:
        raise ValueError(
            f"{data_dir}/index.csv: no Bandai Namco takes with labels; the adapter learns from them"
        )
    counts = Counter((r["label"], canonical_style(r.get("style") or "normal")) for r in rows)
    return dict(sorted(counts.items()))


def unlabelled_captions(data_dir: Path) -> tuple[list[str], int]:
    """The captions of the train split's clips that are not Bandai takes (CMU descriptions), and
    the number of those clips."""
    rows = [r for r in _index_rows(data_dir) if r.get("source") != "bandai" and r.get("split") == "train"]
    texts: set[str] = set()
    for r in rows:
        path = Path(data_dir) / "texts" / f"{r['name']}.txt"
        if path.is_file():
            texts.update(text for text, _, _ in read_captions(path))
    return sorted(texts), len(rows)


def prototype(emb: torch.Tensor, sides: bool) -> torch.Tensor:
    """The mean of (N, D) template embeddings: each half's mean, the sentence half at unit length."""
    mean = emb.mean(0)
    if not sides:
        return F.normalize(mean, dim=0)
    half = mean.shape[0] // 2
    return torch.cat([F.normalize(mean[:half], dim=0), mean[half:]])


def label_table(data_dir: Path, target_encoder: TextEncoder) -> LabelTable:
    """The pairs of the data and their prototypes in the models' embedding space."""
    counts = labelled_pairs(data_dir)
    sides = target_encoder.name.endswith("+sides")
    protos = [
        prototype(target_encoder.encode(captions_for_bandai(a, s, n=TEMPLATES_PER_PAIR, seed=0)), sides)
        for a, s in tqdm(counts, desc="prototypes", mininterval=5.0)
    ]
    return LabelTable(
        sorted({a for a, _ in counts}), sorted({s for _, s in counts}), list(counts), list(counts.values()),
        torch.stack(protos),
    )  # fmt: skip


def adapter_examples(
    data_dir: Path, table: LabelTable, target_encoder: TextEncoder, paraphrases: int, seed: int, prior: float
) -> AdapterExamples:
    """The training (or, with another `seed`, validation) examples of the label `table`.

    Args:
        target_encoder: the generator models' encoder (the unlabelled captions' targets).
    """
    texts: list[str] = []
    targets: list[torch.Tensor] = []
    act: list[int] = []
    sty: list[int] = []
    weights: list[float] = []
    for (action, style), clips, proto in zip(table.pairs, table.clips, table.prototypes, strict=True):
        templates = captions_for_bandai(action, style, n=TEMPLATES_PER_PAIR, seed=0)
        batch = list(dict.fromkeys(templates + paraphrases_for_bandai(action, style, paraphrases, seed)))
        texts += batch
        targets += [proto] * len(batch)
        act += [table.actions.index(action)] * len(batch)
        sty += [table.styles.index(style)] * len(batch)
        weights += [clips**prior / len(batch)] * len(batch)
    free, clips = unlabelled_captions(data_dir)
    if free:
        texts += free
        targets += list(target_encoder.encode(free))
        act += [len(table.actions)] * len(free)  # the "unlabelled" class
        sty += [-1] * len(free)
        weights += [clips**prior / len(free)] * len(free)  # as one more pair
    w = np.asarray(weights, np.float64)
    return AdapterExamples(
        texts, torch.stack(targets).numpy(), np.asarray(act, np.int64), np.asarray(sty, np.int64), w / w.sum()
    )


def encode_all(
    encoder: TextEncoder, texts: list[str], cache: Path | None = None, chunk: int = 1024
) -> torch.Tensor:
    """(N, dim) embeddings of many captions, in chunks, with a progress bar (minutes for 30k).

    `cache`: a file of ``{caption: embedding}`` of this encoder; captions found there are not
    encoded again, and the new ones are added to it.
    """
    stored: dict[str, torch.Tensor] = {}
    if cache is not None and cache.is_file():
        data = torch.load(cache, map_location="cpu", weights_only=True)
        if data.get("encoder") == encoder.name:
            stored = dict(zip(data["texts"], data["embeddings"], strict=True))
    missing = [t for t in dict.fromkeys(texts) if t not in stored]
    for i in tqdm(range(0, len(missing), chunk), desc="encoding", mininterval=10.0):
        part = missing[i : i + chunk]
        stored.update(zip(part, encoder.encode(part), strict=True))
    if cache is not None and missing:
        keys = sorted(stored)
        atomic_torch_save(
            {"encoder": encoder.name, "texts": keys, "embeddings": torch.stack([stored[k] for k in keys])},
            cache,
        )
    return torch.stack([stored[t] for t in texts]) if texts else torch.zeros(0, int(encoder.dim))


def adapter_loss(
    model: CaptionAdapter,
    emb: torch.Tensor,
    target: torch.Tensor,
    actions: torch.Tensor,
    styles: torch.Tensor,
    label_weight: float,
) -> dict[str, torch.Tensor]:
    """The loss terms of one batch: the output's and the regression's squared distance to the
    targets, and the cross-entropy of the two label heads."""
    regressed, a_logits, s_logits = model.train_outputs(emb)
    terms = {
        "out": (model.mix(regressed, a_logits, s_logits) - target).pow(2).sum(-1).mean(),
        "dist": (regressed - target).pow(2).sum(-1).mean(),
        "action": F.cross_entropy(a_logits, actions),
    }
    has_style = styles >= 0
    terms["style"] = (
        F.cross_entropy(s_logits[has_style], styles[has_style]) if has_style.any() else emb.new_zeros(())
    )
    terms["loss"] = terms["out"] + terms["dist"] + label_weight * (terms["action"] + terms["style"])
    return terms


@torch.no_grad()
def evaluate_adapter(model: CaptionAdapter, emb: torch.Tensor, ex: AdapterExamples) -> dict[str, float]:
    """Squared distance of the output to the targets, and label accuracy (labelled captions)."""
    was_training = model.training
    model.eval()
    regressed, a_logits, s_logits = model.train_outputs(emb)
    out = model.mix(regressed, a_logits, s_logits)
    model.train(was_training)
    target = torch.from_numpy(ex.targets)
    lab = torch.from_numpy(ex.styles) >= 0
    actions, styles = torch.from_numpy(ex.actions), torch.from_numpy(ex.styles)
    return {
        "dist": float((out - target).pow(2).sum(-1).mean()),
        "cosine": float(F.cosine_similarity(out[lab], target[lab]).mean()),
        "action_acc": float((a_logits[lab].argmax(1) == actions[lab]).float().mean()),
        "style_acc": float((s_logits[lab].argmax(1) == styles[lab]).float().mean()),
    }


def train_caption_adapter(
    data_dir: str | Path,
    out_path: str | Path,
    config: CaptionAdapterTrainConfig | None = None,
    encoder: TextEncoder | None = None,
    target_encoder: TextEncoder | None = None,
) -> dict[str, Any]:
    """Train the caption adapter of a caption reader (the text encoder ``config.encoder`` plus this
    adapter) and checkpoint it (resumes from `out_path` when it exists).

    The adapter maps `encoder`'s embeddings into `target_encoder`'s, where the generator's models
    answer; saved as ``caption_adapter.<name>.pt`` in a weights folder, it is the caption reader
    ``<name>`` there (:mod:`motion_env.generation.caption_readers`).

    Args:
        data_dir: the HumanML3D-layout dataset the generator was trained on (its ``index.csv``
            labels and the train split's captions).
        out_path: checkpoint file.
        config: training settings (default CaptionAdapterTrainConfig()).
        encoder: an already loaded encoder for ``config.encoder`` (its name replaces it).
        target_encoder: an already loaded encoder for ``config.target_encoder``, the one the
            generator's models read (the shipped models: ``minilm+sides``); its name replaces it.

    Returns:
        The final metrics (``val_*`` on the validation paraphrases) and the step.
    """
    config = config or CaptionAdapterTrainConfig()
    torch.manual_seed(config.seed)
    data_dir, out_path = Path(data_dir), Path(out_path)
    config, encoder = loop.with_text_encoder(config, encoder, weights=config.encoder_weights)
    if target_encoder is None and config.target_encoder == encoder.name:
        target_encoder = encoder  # the adapter reads the models' own encoder: load it once
    config, target_encoder = loop.with_text_encoder(config, target_encoder, "target_encoder")
    table = label_table(data_dir, target_encoder)
    train = adapter_examples(data_dir, table, target_encoder, config.paraphrases, config.seed, config.prior)
    val = adapter_examples(
        data_dir, table, target_encoder, max(8, config.paraphrases // 8), VAL_SEED, config.prior
    )
    seen = set(train.texts)
    val = val.subset(np.array([t not in seen for t in val.texts]))
    cache = out_path.with_name(f"{out_path.stem}.embeddings.pt")
    x_train, x_val = encode_all(encoder, train.texts, cache), encode_all(encoder, val.texts, cache)
    tqdm.write(f"caption adapter: {len(train.texts)} training captions, {len(val.texts)} validation captions")
    model_config = CaptionAdapterConfig(
        in_dim=int(encoder.dim), out_dim=int(target_encoder.dim), hidden=config.hidden, layers=config.layers,
        dropout=config.dropout, actions=tuple(table.actions), styles=tuple(table.styles),
        pairs=tuple(f"{a}|{s}" for a, s in table.pairs), temperature=config.temperature, encoder=encoder.name,
    )  # fmt: skip
    model = CaptionAdapter(model_config).to(config.device)
    model.set_prototypes(table.prototypes)
    optimizer = torch.optim.AdamW(model.parameters(), lr=config.lr, weight_decay=1e-4)
    ckpt = loop.resume_checkpoint(out_path, CHECKPOINT_KIND, config.resume, model_config)
    start = loop.restore(ckpt, model, optimizer)
    targets = torch.from_numpy(train.targets)
    a_all, s_all = torch.from_numpy(train.actions), torch.from_numpy(train.styles)
    record = {"name": target_encoder.name, "dim": int(target_encoder.dim)}

    def train_step(step: int) -> dict[str, float]:
        rng = np.random.default_rng([config.seed, step])
        idx = torch.from_numpy(rng.choice(len(train.texts), config.batch_size, p=train.weights))
        emb = jitter_embeddings(x_train[idx], config.text_noise, rng).to(config.device)
        terms = adapter_loss(model, emb, targets[idx], a_all[idx], s_all[idx], config.label_weight)
        optimizer.zero_grad(set_to_none=True)
        terms["loss"].backward()
        optimizer.step()
        return {k: float(v.detach()) for k, v in terms.items()}

    def save(step: int, metrics: dict[str, float]) -> None:
        loop.save_training_checkpoint(
            out_path, kind=CHECKPOINT_KIND, model=model, optimizer=optimizer, step=step, settings=config,
            metrics=metrics, text_encoder=record,
        )  # fmt: skip

    result = loop.run_loop(
        "caption adapter", config, optimizer, train_step, warmup=min(200, config.steps // 10), start=start,
        save=save, evaluate=lambda: evaluate_adapter(model, x_val, val), postfix={"loss": ".4f"},
    )  # fmt: skip
    metrics = loop.final_metrics(result, ckpt, {"val": evaluate_adapter(model, x_val, val)})
    save(result.step, metrics)
    return metrics
