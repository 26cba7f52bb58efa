"""`motion-env generate`, `train` and `bench` on tiny untrained models."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from motion_env.args import parse_waypoints
from motion_env.cli import main
from motion_env.motion.types import Motion

_ENCODERS: dict[str, object] = {}


@pytest.fixture(autouse=True)
def _shared_text_encoder(monkeypatch, tmp_path) -> None:
    """Every command of this file loads the same (real) MiniLM encoder once, not once per call,
    and keeps its embedding cache in the test's folder."""
    import motion_env.text.encoders as encoders

    monkeypatch.setenv("MOTION_ENV_CACHE", str(tmp_path / "cache"))
    load = encoders.load_text_encoder
    cache = _ENCODERS
    monkeypatch.setattr(
        encoders,
        "load_text_encoder",
        lambda name="minilm", *args, **kw: cache.setdefault(name, load(name, *args, **kw)),
    )


def test_parse_waypoints_mixes_timed_and_untimed() -> None:
    rows = np.array(parse_waypoints("0,2,40; 2,4 ;"))
    np.testing.assert_array_equal(rows[0], [0, 2, 40])
    assert rows[1, :2].tolist() == [2, 4] and np.isnan(rows[1, 2])
    for bad in ("0,2,x", "1,2,3,4", " ; "):
        with pytest.raises(ValueError, match="--waypoints"):
            parse_waypoints(bad)


def test_generate_writes_npz_video_and_plot(tmp_path, capsys) -> None:
    out, video, plot = tmp_path / "walk.npz", tmp_path / "walk.gif", tmp_path / "walk.png"
    args = ["generate", "--random-model", "--text", "a person walks", "--waypoints", "0,1,10;1,2"]
    args += ["--frames", "24", "--seed", "3", "--start", "0.5,0,0", "--out", str(out)]
    args += ["--video", str(video), "--plot", str(plot)]
    assert main(args) == 0
    m = Motion.load(out)
    assert m.joints.shape == (24, 22, 3) and m.fps == 20 and m.text == "a person walks"
    assert m.meta["seed"] == "3" and "untrained" in m.meta
    np.testing.assert_allclose(m.joints[0, 0, [0, 2]], [0.5, 0.0], atol=1e-5)
    np.testing.assert_allclose(m.joints[10, 0, [0, 2]], [0.0, 1.0], atol=1e-4)
    assert video.stat().st_size > 0 and plot.stat().st_size > 0
    assert "wrote" in capsys.readouterr().out
    # Same seed, same motion.
    assert main([*args[:-4], "--out", str(tmp_path / "again.npz")]) == 0
    np.testing.assert_array_equal(Motion.load(tmp_path / "again.npz").joints, m.joints)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--waypoints", "0,nan,10"], "NaN"),
        (["--waypoints", "0,1,50;1,1,10"], "increasing"),
        (["--frames", "0"], "num_frames"),
        (["--start", "0,1"], "start"),
        (["--model", "/nonexistent/weights"], "no generator weights"),
    ],
)
def test_generate_reports_bad_input(tmp_path, capsys, extra: list[str], message: str) -> None:
    args = ["generate", "--text", "a person walks", "--out", str(tmp_path / "x.npz"), *extra]
    if "--model" not in extra:
        args.append("--random-model")
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "motion-env generate: error:" in err and message in err
    assert not (tmp_path / "x.npz").exists()


def test_train_reports_a_missing_dataset(tmp_path, capsys) -> None:
    assert main(["train", "vqvae", "--data", str(tmp_path / "none"), "--out", str(tmp_path / "v.pt")]) == 2
    assert "no dataset directory" in capsys.readouterr().err
    (tmp_path / "data").mkdir()
    assert main(["train", "gpt", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "g.pt")]) == 2
    assert "--vqvae" in capsys.readouterr().err


def test_bench_runs_and_writes_json(tmp_path, capsys) -> None:
    out = tmp_path / "bench.json"
    args = ["bench", "--random-model", "--runs", "2", "--frames", "20", "--batch-sizes", "1,3"]
    args += ["--stream-frames", "8", "--env-steps", "8", "--num-envs", "1,3", "--vector-steps", "3"]
    assert main([*args, "--json", str(out)]) == 0
    results = json.loads(out.read_text())
    env = results["env_step_ms"]
    assert env["steps"] == 8 and env["p99"] >= env["median"] > 0
    learner = results["env_step_ms_learner"]
    assert learner["agent"] == "learner" and learner["steps"] == 8
    # every speed also as its quiet-machine equivalent (each part scaled by the calibrations beside
    # it: tests/evaluation/test_bench_cpu_time.py)
    for row, key in ((results["clip_latency_ms"], "median"), (results["stream"][0], "step_ms_median")):
        assert row["quiet"][key] > 0 and row["calibration_ms"] > 0
    clip, stream = results["clip_latency_ms"], results["stream"][0]
    assert set(clip["quiet"]) == {"median", "p90", "min", "mean"}
    assert set(stream["quiet"]) == {"frames_per_s", "step_ms_median", "step_ms_p99", "first_step_ms"}
    assert results["env_step_ms_learner_4"]["agent"] == "learner_4"
    assert [(r["agent"], r["num_envs"]) for r in results["vector_env"]] == [
        ("route", 1), ("route", 3), ("learner", 1), ("learner", 3), ("learner_4", 1), ("learner_4", 3)
    ]  # fmt: skip
    assert all(r["steps_per_s"] > 0 for r in results["vector_env"])
    # at the learning default of 4 frames a step, frames are 4x the steps; at one frame, the same
    for r in results["vector_env"]:
        frames = 4 if r["agent"] == "learner_4" else 1
        assert r["frames_per_s"] == pytest.approx(frames * r["steps_per_s"])
    assert results["untrained"] is True
    assert results["clip_latency_ms"]["runs"] == 2 and results["clip_latency_ms"]["median"] > 0
    assert [s["batch"] for s in results["stream"]] == [1, 3]
    assert all(s["frames_per_s"] > 0 for s in results["stream"])
    printed = capsys.readouterr().out
    assert "clip latency" in printed and "vector env, N=3, new targets" in printed
    assert "vector env, N=3, new targets, 4 frames a step" in printed and "frames/s" in printed
    assert "quiet equiv." in printed


def _tiny_dataset(root: Path, clips: int = 6, frames: int = 61) -> Path:
    """A HumanML3D-layout dataset of synthetic walks (a rest pose swinging its hips along a curve)."""
    from motion_env.motion.features import joints_to_features
    from motion_env.motion.kinematics import bone_offsets, forward_kinematics
    from motion_env.motion.rotations import quat_from_yaw

    for sub in ("new_joints", "new_joint_vecs", "texts"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    height = -float(bone_offsets()[[2, 5, 8], 1].sum())
    names = []
    for c in range(clips):
        speed, turn = rng.uniform(0.5, 2.0), rng.uniform(-0.5, 0.5)
        t = np.arange(frames) / 20
        yaw = turn * t
        pos = np.cumsum(np.stack([np.sin(yaw), np.zeros_like(t), np.cos(yaw)], 1) * speed / 20, axis=0)
        pos[:, 1] = height
        rots = np.zeros((frames, 22, 4))
        rots[..., 0] = 1.0
        rots[:, 0] = quat_from_yaw(yaw)
        swing = 0.4 * np.sin(2 * np.pi * speed * t)
        for joint, sign in ((1, 1), (2, -1)):  # hips swing about x
            rots[:, joint, 0], rots[:, joint, 1] = np.cos(sign * swing / 2), np.sin(sign * swing / 2)
        joints = forward_kinematics(pos, rots)
        name = f"clip{c:02d}"
        np.save(root / "new_joints" / f"{name}.npy", joints[:-1].astype(np.float32))
        np.save(root / "new_joint_vecs" / f"{name}.npy", joints_to_features(joints))
        (root / "texts" / f"{name}.txt").write_text(f"a person walks {'fast' if speed > 1.2 else 'slowly'}\n")
        names.append(name)
    for split, part in (("train", names[:4]), ("val", names[4:5]), ("test", names[5:])):
        (root / f"{split}.txt").write_text("\n".join(part) + "\n")
    feats = np.concatenate([np.load(root / "new_joint_vecs" / f"{n}.npy") for n in names])
    np.save(root / "Mean.npy", feats.mean(0))
    np.save(root / "Std.npy", feats.std(0) + 1e-2)
    return root


@pytest.mark.slow
def test_train_vqvae_and_gpt_then_generate_from_the_checkpoints(tmp_path, capsys) -> None:
    from motion_env.generation.generator import MotionGenerator
    from motion_env.models.checkpoint import save_checkpoint

    data, weights = _tiny_dataset(tmp_path / "data"), tmp_path / "weights"
    common = ["--data", str(data), "--steps", "2", "--batch-size", "4"]
    assert main(["train", "vqvae", *common, "--window", "16", "--out", str(weights / "vqvae.pt")]) == 0
    out = capsys.readouterr().out
    metrics = json.loads(out[out.index('{\n  "model"') :])
    assert metrics["model"] == "vqvae" and metrics["step"] == 2 and "val_mpjpe_cm" in metrics
    assert (
        main(
            [
                "train",
                "gpt",
                *common,
                "--vqvae",
                str(weights / "vqvae.pt"),
                "--out",
                str(weights / "gpt.pt"),
                "--encoder",
                "minilm",
            ]
        )
        == 0
    )
    # The controller's trainer is the slowest (its final evaluation); an untrained one stands in.
    ctrl = MotionGenerator.random().controller
    record = {"name": "minilm", "dim": 384}
    save_checkpoint(
        weights / "controller.pt", kind="controller", config=ctrl.config, model=ctrl, text_encoder=record
    )
    gen = MotionGenerator.from_pretrained(weights)
    assert gen.training_info["vqvae"]["step"] == 2 and gen.training_info["gpt"]["step"] == 2
    m = gen.generate("a person walks fast", waypoints=[[0.0, 1.0, 20]], num_frames=30, seed=0)
    assert m.joints.shape == (30, 22, 3) and np.isfinite(m.joints).all()


def test_captions_lists_the_vocabulary_and_checks_a_caption(capsys) -> None:
    assert main(["captions", "--examples", "1"]) == 0
    out = capsys.readouterr().out
    assert "actions (training clips" in out and "walk-turn-left" in out and "a person walks" in out
    assert "styles (training clips" in out and "exhausted (also tired)" in out
    assert main(["captions", "--check", "a person jogs along happily"]) == 0
    out = capsys.readouterr().out
    assert "nearest actions: run" in out and "no warning" in out
    assert "the caption adapter reads actions: run" in out
    assert main(["captions", "--check", "une personne court très vite", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert "French" in report["warning"] and report["similarity"] < report["far_below"]
    assert "caption adapter reads it as" in report["warning"] and report["adapter_reads"]["actions"]
    assert main(["captions", "--check", "  "]) == 2
    assert "--check is empty" in capsys.readouterr().err
