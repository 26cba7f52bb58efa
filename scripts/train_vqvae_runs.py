"""Several VQ-VAE trainings side by side inside one wall-clock budget: for a lent GPU machine.

A GPU is lent for minutes, and the VQ-VAE's steps are too small to fill one: several runs share it
as separate processes. Each run is a name and its settings (``VQVAETrainConfig`` and
``VQVAEConfig`` fields as JSON). A short probe of every run, all at once, measures each one's
time per step as they will run together; each run's ``steps`` is then set so that its
learning-rate schedule ends inside the budget (``max_minutes`` stays as a guard). Every minute,
and at the end, each run's latest checkpoint is written to ``--out`` as it would ship (float16
weights with the Mean/Std and its training record, no optimizer state: a few MB), together with
``runs.json`` (settings, steps, seconds per step, the val reconstruction error).

The dataset is a folder, or a pack made by ``scripts/pack_takes.py`` (unpacked first):

    python scripts/train_vqvae_runs.py --pack gpu/takes.npz --device cuda --budget 6 --out $OUT \\
        --run 'long={"batch_size": 64}' --run 'batch256={"batch_size": 256, "lr": 6e-4}'

Every run starts from session 13's tokenizer recipe (``RECIPE``; width 256 and the smoothness
losses of the model card's Training section), which a run's JSON overrides field by field (the
tokenizer shipped since session 20 is the run
``cb1024L={"batch_size": 256, "lr": 6e-4, "codebook_size": 1024}`` with ``--steps 13000``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import multiprocessing as mp
import os
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path
from typing import Any

from pack_takes import unpack  # this folder's: the script's own folder is on sys.path

RECIPE: dict[str, Any] = {
    "window": 48, "lr": 4e-4, "vel_weight": 0.5, "acc_weight": 1.0, "jerk_weight": 0.5,
    "smooth_joints": "upper", "read_weight": 4.0, "seed": 11, "width": 256,
}  # fmt: skip
PROBE_STEPS = 40
# The probe's first steps start the device (context, kernels, allocations) and take several times
# a later step: they are run first, as a checkpoint the timed probe steps resume from.
PROBE_WARMUP = 10


def _configs(settings: dict[str, Any], device: str) -> tuple[Any, Any]:
    """(VQVAETrainConfig, VQVAEConfig) of a run's settings (each key goes to the config that has it)."""
    from motion_env.models.vqvae import VQVAEConfig
    from motion_env.training.vqvae import VQVAETrainConfig

    model_fields = {f.name for f in dataclasses.fields(VQVAEConfig)}
    train = {k: v for k, v in settings.items() if k not in model_fields}
    model = {k: v for k, v in settings.items() if k in model_fields}
    unknown = set(train) - {f.name for f in dataclasses.fields(VQVAETrainConfig)}
    if unknown:
        raise SystemExit(
            f"unknown setting(s) {sorted(unknown)}: neither VQVAETrainConfig nor VQVAEConfig has them"
        )
    config = VQVAETrainConfig(**{"progress": False, "device": device, "log_every": 200, **train})
    return config, VQVAEConfig(**model)


def _train(data: str, out: str, settings: dict[str, Any], device: str, result: Any) -> None:
    """One run in its own process; its final metrics (or its error) go to `result`. A probe
    (``"warmup"`` steps in `settings`) runs those steps first and times only the rest."""
    import torch

    from motion_env.training.vqvae import train_vqvae

    torch.set_num_threads(1)
    try:
        settings = dict(settings)
        warmup = settings.pop("warmup", 0)
        if warmup:
            config, model_config = _configs({**settings, "steps": warmup, "resume": False}, device)
            train_vqvae(data, out, config, model_config)
            settings["resume"] = True
        config, model_config = _configs(settings, device)
        result.put(train_vqvae(data, out, config, model_config))
    except Exception:  # noqa: BLE001  (reported by the parent with the run's name)
        result.put({"error": traceback.format_exc()})


def _run_all(data: Path, folder: Path, runs: dict[str, dict[str, Any]], device: str) -> dict[str, dict]:
    """Train every run at once, each in a process; their final metrics by name."""
    ctx = mp.get_context("spawn")  # CUDA cannot be used in forked children
    queues = {name: ctx.Queue() for name in runs}
    procs = {
        name: ctx.Process(
            target=_train, args=(str(data), str(folder / f"{name}.pt"), s, device, queues[name])
        )
        for name, s in runs.items()
    }  # fmt: skip
    for p in procs.values():
        p.start()
    results = {name: queues[name].get() for name in runs}
    for p in procs.values():
        p.join()
    for name, r in results.items():
        if "error" in r:
            print(f"{name}: ERROR\n{r['error']}", flush=True)
    return results


def export(ckpt_path: Path, out: Path) -> dict[str, Any] | None:
    """Write the checkpoint at `ckpt_path` as it would ship (float16, no optimizer state)."""
    from motion_env.models.checkpoint import load_checkpoint, save_checkpoint
    from motion_env.models.normalizer import Normalizer
    from motion_env.models.vqvae import VQVAE, VQVAEConfig

    if not ckpt_path.is_file():
        return None
    vq, ck = load_checkpoint(ckpt_path, "vqvae", VQVAEConfig, VQVAE, "cpu")
    training = {k: ck[k] for k in ("step", "metrics", "settings") if k in ck}
    save_checkpoint(
        out, kind="vqvae", config=vq.config, model=vq, half=True,
        **Normalizer.from_checkpoint(ck, ckpt_path).checkpoint_entries(), training=training,
    )  # fmt: skip
    return {
        "step": int(ck.get("step", 0)),
        **{k: v for k, v in ck.get("metrics", {}).items() if k.startswith("val_")},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--data", type=Path, help="a HumanML3D-layout dataset folder")
    parser.add_argument(
        "--pack", type=Path, help="a pack of scripts/pack_takes.py (unpacked to a new temp folder)"
    )
    parser.add_argument("--run", action="append", required=True, help="NAME=JSON settings over the recipe")
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--budget", type=float, required=True, help="minutes for the whole script")
    parser.add_argument("--work", type=Path, default=Path("/tmp/vq_runs"), help="training checkpoints")
    parser.add_argument("--out", type=Path, required=True, help="exported checkpoints and runs.json")
    parser.add_argument(
        "--steps", type=int, help="steps of every run, without the probe (max_minutes still guards)"
    )
    args = parser.parse_args(argv)
    t0 = time.time()
    runs: dict[str, dict[str, Any]] = {}
    for spec in args.run:
        name, _, text = spec.partition("=")
        if not name.isidentifier() or name in runs:
            raise SystemExit(f"--run {spec!r}: give each run a distinct name, NAME=JSON")
        runs[name] = {**RECIPE, **json.loads(text or "{}")}
        _configs(runs[name], args.device)  # a bad setting is reported before any work
    if args.data is not None:
        _train_all(args, args.data, runs, t0)
    elif args.pack is None:
        raise SystemExit("give --data or --pack")
    else:
        with tempfile.TemporaryDirectory(prefix="mocap_unpacked_") as folder:
            unpack(args.pack, Path(folder), workers=os.cpu_count() or 1)
            _train_all(args, Path(folder), runs, t0)
    return 0


def _train_all(args: argparse.Namespace, data: Path, runs: dict[str, dict[str, Any]], t0: float) -> None:
    """The probe, then every run side by side until ``t0 + args.budget`` minutes, exporting as they go."""
    print(f"data ready after {time.time() - t0:.0f} s", flush=True)
    args.work.mkdir(parents=True, exist_ok=True)
    args.out.mkdir(parents=True, exist_ok=True)

    # The probe: every run for PROBE_STEPS steps, all at once, as they will share the device.
    probe = (
        {}
        if args.steps
        else _run_all(
            data,
            args.work / "probe",
            {n: {**s, "steps": PROBE_STEPS, "warmup": PROBE_WARMUP} for n, s in runs.items()},
            args.device,
        )
    )
    left = t0 + args.budget * 60 - time.time() - 45  # the last exports and the final evaluations
    record: dict[str, Any] = {"budget_min": args.budget, "runs": {}}
    for name, s in runs.items():
        per_step = probe.get(name, {}).get("seconds_per_step", float("nan"))
        steps = args.steps or (
            PROBE_STEPS if math.isnan(per_step) else max(PROBE_STEPS, int(0.9 * left / per_step))
        )
        # max_minutes only guards the budget; a probe that took all of it still leaves a minute.
        runs[name] = {
            **s,
            "steps": steps,
            "max_minutes": max(left, 60) / 60,
            "save_every": 250,
            "resume": False,
        }
        record["runs"][name] = {"settings": runs[name], "probe_seconds_per_step": per_step}
        print(f"{name}: {per_step * 1000:.1f} ms/step in the probe -> {steps} steps", flush=True)

    stop = threading.Event()

    def export_all() -> None:
        for name in runs:
            try:
                record["runs"][name]["latest"] = export(args.work / f"{name}.pt", args.out / f"{name}.pt")
            except Exception as exc:  # noqa: BLE001  (a checkpoint mid-write: the next round takes it)
                print(f"{name}: export skipped ({exc})", flush=True)
        (args.out / "runs.json").write_text(json.dumps(record, indent=1) + "\n")

    def exporter() -> None:
        while not stop.wait(60):
            export_all()

    thread = threading.Thread(target=exporter, daemon=True)
    thread.start()
    final = _run_all(data, args.work, runs, args.device)
    stop.set()
    thread.join()
    for name, metrics in final.items():
        record["runs"][name]["final"] = metrics
    export_all()
    print(json.dumps({n: r.get("latest") for n, r in record["runs"].items()}, indent=1))
    print(f"done in {time.time() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    sys.exit(main())
