"""The trainers' config dataclasses: their checks, their defaults, and `motion-env train`'s options."""

from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest

import motion_env.training.caption_adapter as adapter_trainer
import motion_env.training.classifier as classifier_trainer
import motion_env.training.controller as controller_trainer
import motion_env.training.gpt as gpt_trainer
import motion_env.training.vqvae as vqvae_trainer
from motion_env.cli import main
from motion_env.training.caption_adapter import CaptionAdapterTrainConfig
from motion_env.training.classifier import ClassifierTrainConfig
from motion_env.training.config import TrainConfig
from motion_env.training.controller import ControllerTrainConfig
from motion_env.training.gpt import GPTTrainConfig
from motion_env.training.vqvae import VQVAETrainConfig

CONFIGS = {
    "vqvae": VQVAETrainConfig,
    "gpt": GPTTrainConfig,
    "controller": ControllerTrainConfig,
    "caption-adapter": CaptionAdapterTrainConfig,
    "classifier": ClassifierTrainConfig,
}
TRAINERS = {
    "vqvae": (vqvae_trainer, "train_vqvae"),
    "gpt": (gpt_trainer, "train_gpt"),
    "controller": (controller_trainer, "train_controller"),
    "caption-adapter": (adapter_trainer, "train_caption_adapter"),
    "classifier": (classifier_trainer, "train_classifier"),
}

# The options `motion-env train MODEL` took before its trainer had a config (--data, --out and
# --vqvae aside; the classifier's: those of the script that trained it before), and for each: the
# text given, the field it sets, the value that field must get.
FLAGS_BEFORE = {
    "vqvae": ["steps", "batch-size", "lr", "window", "device", "seed", "max-minutes", "no-resume"],
    "gpt": [
        "steps", "batch-size", "lr", "encoder", "text-noise", "device", "seed", "max-minutes", "no-resume",
    ],
    "controller": [
        "steps", "batch-size", "lr", "window", "encoder", "text-noise", "device", "seed", "max-minutes",
        "no-resume",
    ],
    "caption-adapter": ["steps", "batch-size", "lr", "encoder", "text-noise", "device", "seed", "no-resume"],
    "classifier": ["epochs", "width", "seed"],
}  # fmt: skip
VALUES = {
    "steps": ("7", "steps", 7),
    "epochs": ("5", "epochs", 5),
    "width": ("32", "width", 32),
    "batch-size": ("5", "batch_size", 5),
    "lr": ("0.01", "lr", 0.01),
    "window": ("16", "window", 16),
    "encoder": ("minilm", "encoder", "minilm"),
    "text-noise": ("0.5", "text_noise", 0.5),
    "device": ("cuda:1", "device", "cuda:1"),
    "seed": ("3", "seed", 3),
    "max-minutes": ("1.5", "max_minutes", 1.5),
    "no-resume": (None, "resume", False),
}


def test_defaults_are_the_trainers_defaults() -> None:
    assert VQVAETrainConfig().to_dict() == {
        "seed": 0, "device": "cpu", "resume": True, "log_every": 50, "save_every": 250, "eval_every": 0,
        "max_minutes": math.inf, "progress": True, "steps": 3000, "batch_size": 64, "lr": 4e-4, "window": 64,
        "init": None, "freeze_encoder": False, "vel_weight": 0.0, "acc_weight": 0.0, "jerk_weight": 0.0,
        "ripple_weight": 0.0, "height_acc_weight": 0.0, "smooth_joints": "all", "leg_weight": 1.0,
        "read_weight": 1.0, "context": 0, "start_weight": 1.0,
    }  # fmt: skip
    assert GPTTrainConfig().to_dict() == {
        "seed": 0, "device": "cpu", "resume": True, "log_every": 50, "save_every": 100, "eval_every": 0,
        "max_minutes": math.inf, "progress": True, "steps": 1500, "batch_size": 64, "lr": 3e-4,
        "text_drop": 0.1, "start_crop": 0.3, "text_noise": 0.3, "token_keep": 1.0, "token_keep_random": False,
        "token_offsets": 1, "action_balance": 0.0, "time_stretch": 0.0,
        "encoder": "minilm+sides", "init": None,
    }  # fmt: skip
    assert ControllerTrainConfig().to_dict() == {
        "seed": 0, "device": "cpu", "resume": True, "log_every": 25, "save_every": 50, "eval_every": 0,
        "max_minutes": math.inf, "progress": True, "steps": 2000, "batch_size": 64, "lr": 1e-3, "window": 100,
        "warmup": 50, "grad_clip": 1.0, "text_noise": 0.3, "untimed_by": "time", "encoder": "minilm+sides",
        "eval_windows": 256,
    }  # fmt: skip
    assert CaptionAdapterTrainConfig().to_dict() == {
        "seed": 0, "device": "cpu", "resume": True, "log_every": 250, "save_every": 500, "eval_every": 0,
        "max_minutes": math.inf, "progress": True, "steps": 3000, "batch_size": 256, "lr": 1e-3,
        "paraphrases": 120, "prior": 0.5, "text_noise": 0.3, "label_weight": 0.1, "hidden": 512, "layers": 2,
        "dropout": 0.1, "temperature": 1.0, "encoder": "minilm+sides", "encoder_weights": None,
        "target_encoder": "minilm+sides",
    }  # fmt: skip
    assert ClassifierTrainConfig().to_dict() == {
        "seed": 0, "device": "cpu", "resume": True, "log_every": 1, "save_every": 1, "eval_every": 1,
        "max_minutes": math.inf, "progress": True, "epochs": 15, "batch_size": 64, "lr": 2e-3,
        "weight_decay": 1e-2, "min_takes": 100, "window": 80, "width": 96, "layers": 3, "kernel": 5,
        "dropout": 0.1,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("cls", "changes", "message"),
    [
        (VQVAETrainConfig, {"steps": 0}, "VQVAETrainConfig.steps must be >= 1, got 0"),
        (VQVAETrainConfig, {"steps": 2.5}, "steps must be an integer"),
        (VQVAETrainConfig, {"batch_size": True}, "batch_size must be an integer"),
        (VQVAETrainConfig, {"lr": 0.0}, "lr must be > 0"),
        (VQVAETrainConfig, {"lr": float("nan")}, "lr must be a number, got nan"),
        (VQVAETrainConfig, {"window": 0}, "window must be >= 1"),
        (VQVAETrainConfig, {"seed": -1}, "seed must be >= 0"),
        (VQVAETrainConfig, {"log_every": 0}, "log_every must be >= 1"),
        (VQVAETrainConfig, {"max_minutes": -1.0}, "max_minutes must be >= 0"),
        (VQVAETrainConfig, {"max_minutes": None}, "max_minutes must be a number, got None"),
        (VQVAETrainConfig, {"device": "gpu0"}, "device 'gpu0' is not a torch device"),
        (VQVAETrainConfig, {"resume": "yes"}, "resume must be True or False"),
        (GPTTrainConfig, {"text_drop": 1.5}, "text_drop must be in [0, 1]"),
        (GPTTrainConfig, {"start_crop": -0.1}, "start_crop must be in [0, 1]"),
        (GPTTrainConfig, {"text_noise": -0.3}, "text_noise must be >= 0"),
        (GPTTrainConfig, {"encoder": " "}, "encoder must be a non-empty string"),
        (ControllerTrainConfig, {"window": 1}, "window must be >= 2"),
        (ControllerTrainConfig, {"grad_clip": 0.0}, "grad_clip must be > 0"),
        (ControllerTrainConfig, {"eval_windows": 0}, "eval_windows must be >= 1"),
        (ControllerTrainConfig, {"steps": None}, "steps must be an integer, got None"),
        (ControllerTrainConfig, {"warmup": -1}, "warmup must be >= 0"),
    ],
)
def test_bad_settings_are_clear_errors(cls: type, changes: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        cls(**changes)


def test_settings_are_keywords_only() -> None:
    with pytest.raises(TypeError):
        VQVAETrainConfig(10)  # type: ignore[misc]


def _capture(monkeypatch: pytest.MonkeyPatch, model: str) -> list[tuple]:
    """Replace the trainer that `motion-env train MODEL` calls; returns the list of its calls."""
    calls: list[tuple] = []
    module, name = TRAINERS[model]
    monkeypatch.setattr(module, name, lambda *args: calls.append(args) or {"step": 0.0})
    return calls


@pytest.mark.parametrize("model", list(CONFIGS))
def test_every_old_flag_reaches_its_field(
    model: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _capture(monkeypatch, model)
    argv = ["train", model, "--data", str(tmp_path), "--out", str(tmp_path / "m.pt")]
    argv += ["--vqvae", str(tmp_path / "vq.pt")] if model == "gpt" else []
    expected = {}
    for flag in FLAGS_BEFORE[model]:
        text, field, value = VALUES[flag]
        argv += [f"--{flag}"] + ([text] if text is not None else [])
        expected[field] = value
    assert main(argv) == 0
    (args,) = calls
    paths = (str(tmp_path), str(tmp_path / "vq.pt"), str(tmp_path / "m.pt"))
    assert args[:-1] == (paths if model == "gpt" else paths[::2])
    assert args[-1] == CONFIGS[model](**expected)


@pytest.mark.parametrize("model", list(CONFIGS))
def test_every_field_is_an_option(model: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Each field of the config, set to a value other than its default from the command line."""
    calls = _capture(monkeypatch, model)
    cls = CONFIGS[model]
    argv = ["train", model, "--data", str(tmp_path), "--out", str(tmp_path / "m.pt"), "--vqvae", "v.pt"]
    argv = argv if model == "gpt" else argv[:-2]
    expected = {}
    # The legs' weight applies to smooth_joints with leg joints, not to the value below ("upper"),
    # and the start's weight to windows without context: each is checked on its own below.
    apart = {"leg_weight", "start_weight"}
    for f in fields(cls):
        flag = "--" + f.name.replace("_", "-")
        if f.name in apart:
            continue
        if isinstance(f.default, bool):
            argv.append(flag if not f.default else "--no-" + flag[2:])
            expected[f.name] = not f.default
        elif f.default == math.inf:
            argv += [flag, "2.5"]
            expected[f.name] = 2.5
        elif f.default is None:  # an optional path
            argv += [flag, "x.pt"]
            expected[f.name] = "x.pt"
        elif isinstance(f.default, str):
            value = {
                "device": "cuda:1",
                "encoder": "clip",
                "untimed_by": "distance",
                "target_encoder": "mpnet",
                "smooth_joints": "upper",
            }[f.name]
            argv += [flag, value]
            expected[f.name] = value
        else:
            value = (f.default / 2 or 0.5) if isinstance(f.default, float) else f.default + 1
            value += 1 if f.name == "kernel" else 0  # kernels are odd
            value += 3 if f.name == "context" else 0  # frames of history come in whole tokens
            argv += [flag, str(value)]
            expected[f.name] = value
    assert main(argv) == 0
    assert calls[0][-1] == cls(**expected)
    assert all(getattr(calls[0][-1], f.name) != f.default for f in fields(cls) if f.name not in apart)
    if model == "vqvae":
        calls.clear()
        assert main([*argv[:6], "--leg-weight", "0.3"]) == 0
        assert calls[0][-1].leg_weight == 0.3
        calls.clear()
        assert main([*argv[:6], "--start-weight", "4"]) == 0
        assert calls[0][-1].start_weight == 4.0


def test_bad_values_on_the_command_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["--data", str(tmp_path), "--out", str(tmp_path / "m.pt")]
    assert main(["train", "vqvae", *base, "--steps", "0"]) == 2
    assert "motion-env train: error: VQVAETrainConfig.steps must be >= 1, got 0" in capsys.readouterr().err
    assert main(["train", "controller", *base, "--device", "gpu0"]) == 2
    assert "device 'gpu0' is not a torch device" in capsys.readouterr().err
    assert main(["train", "gpt", *base, "--text-drop", "2"]) == 2
    assert "text_drop must be in [0, 1], got 2.0" in capsys.readouterr().err
    assert main(["train", "vqvae", *base, "--smooth-joints", "upper", "--leg-weight", "0.5"]) == 2
    assert "leg_weight=0.5 with smooth_joints='upper'" in capsys.readouterr().err
    assert main(["train", "vqvae", *base, "--start-weight", "4", "--context", "8", "--freeze-encoder"]) == 2
    assert "start_weight=4.0 with context=8" in capsys.readouterr().err
    for argv, message in [
        (["vqvae", *base, "--steps", "many"], "argument --steps: invalid int value: 'many'"),
        (["gpt", *base, "--window", "16"], "unrecognized arguments: --window 16"),  # gpt has no window
        (["vqvae", *base, "--encoder", "minilm"], "unrecognized arguments: --encoder minilm"),
        (["vqvae", "--out", "x.pt"], "the following arguments are required: --data"),
    ]:
        with pytest.raises(SystemExit) as exc:
            main(["train", *argv])
        assert exc.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("model", list(CONFIGS))
def test_help_lists_every_option_with_its_default(model: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["train", model, "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for f in fields(CONFIGS[model]):
        assert "--" + f.name.replace("_", "-") in text
    length = CONFIGS[model]().epochs if model == "classifier" else CONFIGS[model]().steps
    assert f"(default: {length})" in text and "--no-resume" in text


def test_the_cli_imports_no_trainer_until_train_runs() -> None:
    code = (
        "import sys; from motion_env.cli import build_parser; "
        "build_parser().parse_args(['generate', '--text', 'x']); "
        "print(sorted(m for m in sys.modules if m.startswith('motion_env.training')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_every_config_is_a_train_config() -> None:
    assert all(issubclass(cls, TrainConfig) for cls in CONFIGS.values())
