"""The caption adapter: identity at the start, shapes checked, a checkpoint round trip."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from motion_env.models.caption_adapter import CaptionAdapter, CaptionAdapterConfig
from motion_env.models.checkpoint import load_checkpoint, save_checkpoint


def _config(**kw) -> CaptionAdapterConfig:
    base = dict(in_dim=8, out_dim=8, hidden=16, actions=("walk", "run"), styles=("normal",), encoder="hash")
    return CaptionAdapterConfig(**{**base, **kw})


def test_an_untrained_adapter_of_one_space_changes_nothing() -> None:
    torch.manual_seed(0)
    adapter = CaptionAdapter(_config()).eval()
    x = torch.randn(5, 8)
    assert torch.equal(adapter(x), x)
    actions, styles = adapter.labels(x)
    assert actions.shape == (5, 3) and styles.shape == (5, 1)  # + "unlabelled"


def test_another_encoder_is_mapped_into_the_models_space() -> None:
    adapter = CaptionAdapter(_config(in_dim=12, out_dim=8)).eval()
    out = adapter(torch.randn(3, 12))
    assert out.shape == (3, 8) and torch.isfinite(out).all()


def test_a_wrong_embedding_names_the_encoder_and_shape() -> None:
    adapter = CaptionAdapter(_config())
    with pytest.raises(ValueError, match=r"\(N, 8\) embeddings of hash, got \(3, 5\)"):
        adapter(torch.randn(3, 5))
    with pytest.raises(ValueError, match="got \\(8,\\)"):
        adapter.labels(torch.randn(8))


@pytest.mark.parametrize(("field", "value"), [("layers", 0), ("hidden", 0), ("dropout", 1.0), ("in_dim", -1)])
def test_bad_config_values_are_refused(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=field):
        _config(**{field: value})


def test_checkpoint_round_trip(tmp_path: Path) -> None:
    torch.manual_seed(1)
    adapter = CaptionAdapter(_config())
    torch.nn.init.normal_(adapter.out.weight)  # not the identity any more
    path = save_checkpoint(tmp_path / "a.pt", kind="caption_adapter", config=adapter.config, model=adapter)
    loaded, ckpt = load_checkpoint(path, "caption_adapter", CaptionAdapterConfig, CaptionAdapter)
    assert loaded.config == adapter.config and loaded.config.actions == ("walk", "run")
    x = torch.randn(4, 8)
    torch.testing.assert_close(loaded(x), adapter.eval()(x))
