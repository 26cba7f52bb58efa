"""The compiled loops' first-use note: one line on stderr when numba's cache has no copy yet."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from motion_env.models import jit_cache


def _dispatcher(name: str, index: Path) -> SimpleNamespace:
    cache = SimpleNamespace(_cache_file=SimpleNamespace(_index_path=str(index)))
    return SimpleNamespace(__qualname__=name, _cache=cache)


def test_a_cold_cache_is_announced_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cold = _dispatcher("test.cold", tmp_path / "missing.nbi")
    jit_cache.note_first_compile(cold, "the cold loop")
    jit_cache.note_first_compile(cold, "the cold loop")
    assert capsys.readouterr().err.count("compiling the cold loop") == 1


def test_a_cached_loop_is_silent(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    index = tmp_path / "there.nbi"
    index.write_text("")
    jit_cache.note_first_compile(_dispatcher("test.warm", index), "the warm loop")
    jit_cache.note_first_compile(SimpleNamespace(__qualname__="test.odd"), "a loop numba lays out otherwise")
    assert capsys.readouterr().err == ""


def test_without_numba_the_models_run_numpy_operations(monkeypatch: pytest.MonkeyPatch) -> None:
    """numba missing or NUMBA_DISABLE_JIT set: the controller's roll-out and step inputs and the
    GPT's step take numpy's operations (the compiled loops would not import, or would run as
    Python; the generation stages' compiled loops are switched alike, tests/generation's
    `both_ways`)."""
    import numpy as np
    import torch

    from motion_env.models import controller_jit, gpt_jit
    from motion_env.models.controller import ControllerConfig, PathController
    from motion_env.models.gpt import GPTConfig, TokenGPT

    monkeypatch.setattr(jit_cache, "_enabled", None)
    monkeypatch.setenv("NUMBA_DISABLE_JIT", "1")
    assert not jit_cache.jit_enabled()
    monkeypatch.setattr(controller_jit, "rollout", lambda *a: pytest.fail("the compiled roll-out ran"))
    monkeypatch.setattr(controller_jit, "step_inputs", lambda *a: pytest.fail("the compiled inputs ran"))
    monkeypatch.setattr(gpt_jit, "step", lambda *a: pytest.fail("the compiled step ran"))
    torch.manual_seed(0)
    controller = PathController(ControllerConfig(text_dim=8, text_proj=4, hidden=8, mlp=8)).eval()
    gpt = TokenGPT(GPTConfig(vocab_size=16, block_size=8, n_layer=1, n_head=2, n_embd=8, text_dim=8)).eval()
    with torch.no_grad():
        state = controller.init_state(torch.zeros(1, 8), None, np.zeros((1, 3)))
        assert controller.run(state, 3)[1].roots.shape == (1, 3, 3)
        inputs = controller.step_inputs(state, controller.frame_ops(1))
        assert inputs.shape == (1, controller.config.input_dim)
        path = torch.zeros(1, 3, gpt.config.path_dim)
        assert gpt.generate(torch.zeros(1, 8), path, 3, [torch.Generator()]).shape == (1, 3)
    monkeypatch.setattr(jit_cache, "_enabled", None)
    monkeypatch.delenv("NUMBA_DISABLE_JIT")
    assert jit_cache.jit_enabled()
