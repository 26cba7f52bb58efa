"""The shared training loop: the learning-rate schedule, the bookkeeping of each step, resuming."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from motion_env.models.checkpoint import read_checkpoint
from motion_env.models.controller import ControllerConfig, PathController
from motion_env.training.controller import ControllerTrainConfig
from motion_env.training.loop import lr_at, restore, resume_checkpoint, run_loop, save_training_checkpoint


def test_lr_warms_up_linearly_then_decays_by_cosine_to_a_tenth() -> None:
    peak, total, warmup = 2.0, 110, 10
    assert [lr_at(s, total, peak, warmup) for s in range(3)] == [0.2, 0.4, peak * 3 / 10]
    assert lr_at(warmup, total, peak, warmup) == peak
    assert lr_at(warmup + 50, total, peak, warmup) == pytest.approx(peak * (0.1 + 0.9 * 0.5))
    assert lr_at(total, total, peak, warmup) == pytest.approx(0.1 * peak)
    assert lr_at(total + 5, total, peak, warmup) == pytest.approx(0.1 * peak)  # stays there
    after = [lr_at(s, total, peak, warmup) for s in range(warmup, total + 1)]
    assert all(a >= b for a, b in zip(after, after[1:]))
    assert lr_at(0, total, peak, 0) == peak  # no warm-up


def _toy() -> tuple[torch.nn.Parameter, torch.optim.Optimizer]:
    param = torch.nn.Parameter(torch.zeros(1))
    return param, torch.optim.SGD([param], lr=1.0)


def test_run_loop_sets_the_lr_logs_validates_and_saves(capsys: pytest.CaptureFixture[str]) -> None:
    _, opt = _toy()
    config = ControllerTrainConfig(steps=7, lr=0.5, log_every=3, save_every=3, eval_every=2, progress=False)
    lrs, saves, evals = [], [], []

    def step(i: int) -> dict[str, float]:
        lrs.append(opt.param_groups[0]["lr"])
        return {"loss": float(i)}

    def evaluate() -> dict[str, float]:
        evals.append(len(lrs))
        return {"score": 1.0}

    def save(n: int, metrics: dict[str, float]) -> None:
        saves.append((n, metrics))

    result = run_loop("toy", config, opt, step, warmup=2, start=1, save=save, evaluate=evaluate)
    assert (result.step, result.done, result.last) == (7, 6, {"loss": 6.0})
    assert lrs == [lr_at(s, 7, 0.5, 2) for s in range(1, 7)]
    assert evals == [1, 3, 5]  # after steps 2, 4 and 6 of 7
    assert saves == [(3, {"loss": 2.0, "val_score": 1.0}), (6, {"loss": 5.0, "val_score": 1.0}),
                     (7, {"loss": 6.0, "val_score": 1.0})]  # fmt: skip
    out = capsys.readouterr().out
    assert "toy step 3/7 loss 2.0000" in out and "toy step 6/7 loss 5.0000" in out
    assert "toy step 2 val score 1.0000" in out


def test_run_loop_stops_on_request_and_at_the_time_limit(capsys: pytest.CaptureFixture[str]) -> None:
    _, opt = _toy()
    saves: list[int] = []

    def save(n: int, metrics: dict[str, float]) -> None:
        saves.append(n)

    config = ControllerTrainConfig(steps=10, save_every=4, progress=False)
    result = run_loop(
        "toy", config, opt, lambda i: {"loss": 1.0}, warmup=1, save=save, on_step=lambda n, _: n == 5
    )
    assert result.step == 5 and saves == [4]
    timed = ControllerTrainConfig(steps=10, save_every=4, max_minutes=0, progress=False)
    result = run_loop("toy", timed, opt, lambda i: {"loss": 1.0}, warmup=1, start=2, save=save)
    assert (result.step, result.done) == (3, 1) and saves == [4, 3]  # a checkpoint where it stopped
    assert "toy: stopping at step 3 after 0 minutes" in capsys.readouterr().out
    nothing = run_loop("toy", config, opt, lambda i: {"loss": 1.0}, warmup=1, start=10)
    assert (nothing.step, nothing.done, nothing.last) == (10, 0, {})


def test_running_averages_in_the_log(capsys: pytest.CaptureFixture[str]) -> None:
    _, opt = _toy()
    config = ControllerTrainConfig(steps=2, log_every=2, progress=False)
    run_loop("toy", config, opt, lambda i: {"loss": float(i)}, warmup=1, smoothing=0.5)
    assert "toy step 2/2 loss 0.5000" in capsys.readouterr().out


def test_checkpoint_round_trip_and_resume(tmp_path: Path) -> None:
    path = tmp_path / "c.pt"
    config = ControllerTrainConfig(steps=3, progress=False)
    model = PathController(ControllerConfig(text_dim=8, text_proj=8, hidden=16, mlp=16))
    opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
    model(model.init_state(torch.zeros(1, 8), [None], torch.zeros(1, 3)), 2)[0].sum().backward()
    opt.step()
    assert resume_checkpoint(path, "controller", True) is None  # nothing to resume
    save_training_checkpoint(path, kind="controller", model=model, optimizer=opt, step=3, settings=config,
                             metrics={"loss": 1.5}, text_encoder={"name": "x", "dim": 8})  # fmt: skip
    ckpt = read_checkpoint(path, "controller")
    assert ckpt["settings"] == config.to_dict() and ckpt["metrics"] == {"loss": 1.5}
    assert resume_checkpoint(path, "controller", False) is None
    assert resume_checkpoint(path, "controller", True, model.config)["step"] == 3
    fresh = PathController(model.config)
    fresh_opt = torch.optim.AdamW(fresh.parameters(), lr=1e-3)
    assert restore(ckpt, fresh, fresh_opt) == 3 and restore(None, fresh, fresh_opt) == 0
    for a, b in zip(model.state_dict().values(), fresh.state_dict().values()):
        torch.testing.assert_close(a, b)
    assert fresh_opt.state_dict()["state"][0]["step"] == 1
    other = ControllerConfig(text_dim=8, text_proj=8, hidden=16, mlp=32)
    with pytest.raises(ValueError, match="cannot resume"):
        resume_checkpoint(path, "controller", True, other)
    with pytest.raises(ValueError, match="expected 'gpt'"):
        resume_checkpoint(path, "gpt", True)
