"""The caption adapter: any wording of a known action -> the embedding the generator learnt for it.

The GPT and the path controller were trained on captions written from labels with a few hundred
words (``motion_env/data/captions``). A sentence in other words lands elsewhere in the text
encoder's space, and the models, which only ever saw the template captions, answer it with
whatever is nearest: often a plain walk. The adapter sits between the text encoder and both
models (stage 1 of :class:`motion_env.generation.pipeline.Pipeline`) and moves such a caption to
the point the models know for its meaning.

It reads the caption's embedding with a small MLP and two label heads: the action (plus one
class, "unlabelled", for captions of motion without labels, such as the CMU descriptions) and
the style. Its output is a mixture of

- the *prototypes* of the known (action, style) pairs: the mean embedding of each pair's template
  captions, which is where the models answer with that action in that style, weighted by the
  heads' probability of the pair (``p(action) * p(style)``, over the pairs the training data has,
  sharpened by ``temperature``), with the weight ``1 - p(unlabelled)``;
- and, with the weight ``p(unlabelled)``, a regression of the caption's own embedding (a residual
  MLP, zero at initialisation, when the adapter reads the models' own encoder; the MLP alone for
  another encoder), trained to leave unlabelled captions where they were.

Trained on text alone (``motion-env train caption-adapter``,
:mod:`motion_env.training.caption_adapter`): template captions and thousands of paraphrases in
other words (:mod:`motion_env.data.captions.paraphrases`) with their labels and prototypes.

An adapter reads one text encoder (``config.encoder``); the two together are a *caption reader*,
what ``caption_reader=`` picks (:mod:`motion_env.generation.caption_readers`). The adapter is the
model and its file; the reader is the adapter plus its encoder.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import torch
from torch import nn

from motion_env.motion.validation import CheckedConfig, PositiveFloat, PositiveInt

__all__ = ["UNLABELLED", "CaptionAdapter", "CaptionAdapterConfig"]

UNLABELLED = "(unlabelled)"  # the action class of captions without labels (the last action)


@dataclass
class CaptionAdapterConfig(CheckedConfig):
    """Shape of a :class:`CaptionAdapter`.

    Attributes:
        in_dim: width of the text encoder's embedding the adapter reads.
        out_dim: width of the embedding the GPT and the controller read (their ``text_dim``).
        hidden: width of the MLP's hidden layers.
        layers: hidden layers of the MLP (>= 1).
        dropout: dropout on the hidden layers while training.
        actions: the action labels of the action head (in order; :data:`UNLABELLED` is added last).
        styles: the style labels of the style head (in order).
        pairs: the known ``"action|style"`` pairs, one per prototype (in order).
        temperature: sharpness of the pair weights (1: the heads' probabilities; lower: sharper).
        encoder: name of the text encoder the adapter reads ("minilm+sides", ...).
    """

    in_dim: PositiveInt = 768
    out_dim: PositiveInt = 768
    hidden: PositiveInt = 512
    layers: PositiveInt = 2
    dropout: Annotated[float, "[0, 1)"] = 0.1
    actions: tuple[str, ...] = ()
    styles: tuple[str, ...] = ()
    pairs: tuple[str, ...] = ()
    temperature: PositiveFloat = 1.0
    encoder: str = "minilm+sides"

    def __post_init__(self) -> None:
        super().__post_init__()
        self.actions, self.styles, self.pairs = tuple(self.actions), tuple(self.styles), tuple(self.pairs)
        for pair in self.pairs:
            action, _, style = pair.partition("|")
            if action not in self.actions or style not in self.styles:
                raise ValueError(f"pair {pair!r} is not 'action|style' of the known actions and styles")

    @property
    def action_classes(self) -> tuple[str, ...]:
        """The action head's classes: the actions, then :data:`UNLABELLED`."""
        return (*self.actions, UNLABELLED)


class CaptionAdapter(nn.Module):
    """Caption embedding -> the embedding the generator's models read, plus action/style logits."""

    def __init__(self, config: CaptionAdapterConfig) -> None:
        super().__init__()
        self.config = c = config
        blocks: list[nn.Module] = []
        width = c.in_dim
        for _ in range(c.layers):
            blocks += [nn.Linear(width, c.hidden), nn.GELU(), nn.Dropout(c.dropout)]
            width = c.hidden
        self.body = nn.Sequential(*blocks)
        self.out = nn.Linear(c.hidden, c.out_dim)
        # Same space in and out: the regression is residual and starts as the identity. Another
        # encoder: the MLP alone maps into the models' space (only unlabelled captions need it).
        self.residual = c.in_dim == c.out_dim
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)
        self.action_head = nn.Linear(c.hidden, len(c.action_classes))
        self.style_head = nn.Linear(c.hidden, max(1, len(c.styles)))
        index = [pair.partition("|") for pair in c.pairs]
        self.register_buffer("prototypes", torch.zeros(len(c.pairs), c.out_dim))
        self.register_buffer(
            "pair_actions", torch.tensor([c.actions.index(a) for a, _, _ in index], dtype=torch.long)
        )
        self.register_buffer(
            "pair_styles", torch.tensor([c.styles.index(s) for _, _, s in index], dtype=torch.long)
        )

    def _check(self, emb: torch.Tensor) -> None:
        if emb.ndim != 2 or emb.shape[1] != self.config.in_dim:
            raise ValueError(
                f"the caption adapter reads (N, {self.config.in_dim}) embeddings of "
                f"{self.config.encoder}, got {tuple(emb.shape)}"
            )

    def set_prototypes(self, prototypes: torch.Tensor) -> None:
        """Store the (pairs, out_dim) prototype embeddings, in the order of ``config.pairs``."""
        if prototypes.shape != self.prototypes.shape:
            raise ValueError(
                f"prototypes must be {tuple(self.prototypes.shape)}, got {tuple(prototypes.shape)}"
            )
        self.prototypes.copy_(prototypes)

    def train_outputs(self, emb: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(regressed embedding, action logits (N, A + 1), style logits (N, S)) of (N, in_dim) captions."""
        self._check(emb)
        h = self.body(emb)
        regressed = emb + self.out(h) if self.residual else self.out(h)
        return regressed, self.action_head(h), self.style_head(h)

    def forward(self, emb: torch.Tensor) -> torch.Tensor:
        """(N, in_dim) caption embeddings -> (N, out_dim) embeddings for the GPT and the controller."""
        return self.mix(*self.train_outputs(emb))

    def mix(self, regressed: torch.Tensor, a_logits: torch.Tensor, s_logits: torch.Tensor) -> torch.Tensor:
        """The output from :meth:`train_outputs`: the prototypes weighted by the pairs' probability,
        and the regression weighted by p(unlabelled)."""
        if not self.config.pairs:
            return regressed
        a_logp, s_logp = a_logits.log_softmax(-1), s_logits.log_softmax(-1)
        pair_logp = a_logp[:, self.pair_actions] + s_logp[:, self.pair_styles]
        weights = (pair_logp / self.config.temperature).softmax(-1)
        p_unlabelled = a_logp[:, -1:].exp()
        return p_unlabelled * regressed + (1.0 - p_unlabelled) * (weights @ self.prototypes)

    def labels(self, emb: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(N, in_dim) caption embeddings -> (action logits (N, A + 1), style logits (N, S))."""
        _, a_logits, s_logits = self.train_outputs(emb)
        return a_logits, s_logits

    @torch.no_grad()
    def read_labels(self, emb: torch.Tensor, top: int = 3) -> list[dict[str, list[tuple[str, float]]]]:
        """What the adapter reads in each caption: its `top` actions and styles with probabilities.

        Returns:
            per row ``{"actions": [(label, p), ...], "styles": [(label, p), ...]}``, most likely
            first (an action may be :data:`UNLABELLED`).
        """
        a_logits, s_logits = self.labels(emb)
        out = []
        for a_row, s_row in zip(a_logits.softmax(-1), s_logits.softmax(-1), strict=True):
            reading = {}
            for key, names, probs in (
                ("actions", self.config.action_classes, a_row),
                ("styles", self.config.styles, s_row),
            ):
                order = probs.argsort(descending=True)[: min(top, len(names))]
                reading[key] = [(names[int(i)], float(probs[i])) for i in order]
            out.append(reading)
        return out
