"""The rules every `motion-env` command follows: one-line user errors (exit 2, no traceback), checks
before any model loads, no output replaced without --overwrite, --version, the device check,
one torch thread by default, warnings as one line."""

from __future__ import annotations

import importlib.metadata
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from motion_env.cli import main
from motion_env.generation.generator import MotionGenerator
from motion_env.motion.types import Motion

_ENCODERS: dict[str, object] = {}
GEN = ["generate", "--random-model", "--text", "a person walks", "--frames", "12"]


@pytest.fixture(autouse=True)
def _shared_text_encoder(monkeypatch, tmp_path) -> None:
    """One (real) MiniLM encoder for the whole file; its disk cache in the test's folder."""
    import motion_env.text.encoders as encoders

    monkeypatch.setenv("MOTION_ENV_CACHE", str(tmp_path / "cache"))
    load = encoders.load_text_encoder
    monkeypatch.setattr(
        encoders,
        "load_text_encoder",
        lambda name="minilm", *args, **kw: _ENCODERS.setdefault(name, load(name, *args, **kw)),
    )


@pytest.fixture
def no_model(monkeypatch) -> None:
    """Loading a generator fails the test: the command must have stopped before."""

    def refuse(*args, **kwargs):
        raise AssertionError("a model was loaded")

    monkeypatch.setattr(MotionGenerator, "from_pretrained", classmethod(refuse))
    monkeypatch.setattr(MotionGenerator, "random", classmethod(refuse))


def _error(capsys) -> str:
    """The command's stderr: exactly one line, an error, no traceback."""
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err.strip()


def test_version(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"motion-env {importlib.metadata.version('motion-env')}"


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--waypoints", "0,2,x"], "--waypoints item 0 '0,2,x'"),
        (["--waypoints", "0,2,1;100,2,5"], "--infeasible warn"),  # 100 m in 4 frames
        (["--frames", "0"], "num_frames"),
        (["--frames", "99999999"], "num_frames"),
        (["--seed", "-1"], "seed"),
        (["--start", "0,1,x"], "--start"),
        (["--out", "walk.mp4"], "must end in .npz"),
        (["--video", "walk.avi"], "unknown video type '.avi'"),
        (["--plot", "walk.jpg"], "--plot"),
        (["--model", "somewhere"], "give either --model or --random-model"),
    ],
)
def test_generate_checks_everything_before_loading_a_model(
    tmp_path, monkeypatch, capsys, no_model, extra: list[str], message: str
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main([*GEN, *extra]) == 2
    err = _error(capsys)
    assert err.startswith("motion-env generate: error: ") and message in err
    assert not list(tmp_path.glob("*.*")), "nothing may be written"


def test_a_typo_fails_fast_without_importing_torch(tmp_path) -> None:
    code = (
        "import sys, time; t = time.perf_counter(); from motion_env.cli import main; "
        "rc = main(['generate', '--text', 'x', '--waypoints', '0,2;1,x', "
        f"'--out', {str(tmp_path / 'x.npz')!r}]); "
        "print(rc, 'torch' in sys.modules, time.perf_counter() - t)"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    rc, torch_loaded, seconds = run.stdout.split()
    assert (rc, torch_loaded) == ("2", "False")
    assert (
        run.stderr.strip()
        == "motion-env generate: error: --waypoints item 1 '1,x' is not 'x,z' or 'x,z,t' numbers"
    )
    assert float(seconds) < 3.0  # about 0.3 s on the 2-core machine; generous for a busy one


def test_user_errors_are_one_line(tmp_path, capsys, no_model) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    cases = [
        (["generate", "--text", "x", "--out", str(a_file / "x.npz")], "is a file, not a folder"),
        (["generate", "--text", "x", "--out", str(tmp_path)], "must end in .npz"),
        (["generate", "--text", "  ", "--out", str(tmp_path / "x.npz")], "--text is empty"),
        (["show", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "m.mp4")], "no motion file"),
        (["show", str(a_file), "--out", str(tmp_path / "m.mp4")], "a_file"),
        (["replay", str(tmp_path / "missing.npz")], "no motion file"),
        (["replay", str(a_file), "--mass", "-3"], "--mass"),
        (["bench", "--random-model", "--batch-sizes", "1,x"], "--batch-sizes"),
    ]
    for argv, message in cases:
        assert main(argv) == 2, argv
        err = _error(capsys)
        assert err.startswith(f"motion-env {argv[0]}: error: ") and message in err, err


def test_a_bad_argument_is_one_line(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["generate", "--text", "x", "--frames", "2OO"])
    assert exc.value.code == 2
    err = _error(capsys)
    assert err == (
        "motion-env generate: error: argument --frames: invalid int value: '2OO' "
        "(see motion-env generate --help)"
    )


def test_cuda_on_a_cpu_only_torch(monkeypatch, capsys, no_model, tmp_path) -> None:
    monkeypatch.setattr(torch.version, "cuda", None)
    monkeypatch.setattr(torch.version, "hip", None, raising=False)
    assert main([*GEN, "--device", "cuda", "--out", str(tmp_path / "x.npz")]) == 2
    err = _error(capsys)
    assert "has no CUDA here (CPU build): use --device cpu" in err
    assert main([*GEN, "--device", "gpu", "--out", str(tmp_path / "x.npz")]) == 2
    assert "--device 'gpu' is not a torch device" in _error(capsys)
    assert main(["bench", "--random-model", "--device", "cuda:0"]) == 2
    assert "no CUDA here" in _error(capsys)


def test_generate_refuses_to_overwrite_unless_told(tmp_path, capsys) -> None:
    out, video, plot = tmp_path / "w.npz", tmp_path / "w.gif", tmp_path / "w.png"
    argv = [*GEN, "--out", str(out), "--video", str(video), "--plot", str(plot)]
    assert main(argv) == 0
    stamps = [p.stat().st_mtime_ns for p in (out, video, plot)]
    capsys.readouterr()
    for existing in (out, video, plot):  # any one output in the way stops the whole command
        others = [p for p in (out, video, plot) if p != existing]
        for p in others:
            p.rename(p.with_name("moved-" + p.name))
        assert main(argv) == 2
        assert _error(capsys) == (
            f"motion-env generate: error: {existing} exists: nothing was written "
            "(pass --overwrite to replace it)"
        )
        assert not any(p.exists() for p in others)
        for p in others:
            p.with_name("moved-" + p.name).rename(p)
    assert [p.stat().st_mtime_ns for p in (out, video, plot)] == stamps
    assert main([*argv, "--overwrite", "--seed", "5"]) == 0
    assert Motion.load(out).meta["seed"] == "5"


def test_show_replay_and_bench_refuse_to_overwrite(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    clip = Motion(np.zeros((4, 22, 3), np.float32) + np.linspace(0, 1, 22)[None, :, None], fps=20)
    src = clip.save(tmp_path / "walk.npz")
    (tmp_path / "walk.mp4").write_bytes(b"the video generate wrote")
    assert main(["show", str(src)]) == 2  # default output: walk.mp4, here
    assert "walk.mp4 exists: nothing was written" in _error(capsys)
    assert (tmp_path / "walk.mp4").read_bytes() == b"the video generate wrote"
    (tmp_path / "p.png").write_bytes(b"png")
    assert main(["show", str(src), "--out", "new.gif", "--plot", "p.png"]) == 2
    assert "p.png exists" in _error(capsys) and not (tmp_path / "new.gif").exists()
    assert main(["replay", str(src), "--video", "walk.mp4"]) == 2
    assert "walk.mp4 exists" in _error(capsys)
    (tmp_path / "b.json").write_text("{}")
    assert main(["bench", "--random-model", "--json", "b.json"]) == 2
    assert "b.json exists" in _error(capsys)


def test_data_build_overwrites_only_a_dataset(tmp_path, capsys, monkeypatch) -> None:
    import motion_env.data.build as build

    out = tmp_path / "data"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    assert main(["data", "build", str(tmp_path), "--out", str(out)]) == 2
    assert "not empty: nothing was written (pass --overwrite" in _error(capsys)
    assert main(["data", "build", str(tmp_path), "--out", str(out), "--overwrite"]) == 2
    assert "not a dataset written by `motion-env data build`" in _error(capsys)
    # A dataset: replaced by a new build; when the build fails, the old one is put back.
    (out / "summary.json").write_text("{}")
    (out / "new_joint_vecs").mkdir()

    def fail(sources, out, **kwargs):
        assert not Path(out).exists()  # the old one is out of the way while the new one is built
        raise ValueError("no .bvh or .bvh.gz files")

    monkeypatch.setattr(build, "build_dataset", fail)
    assert main(["data", "build", str(tmp_path), "--out", str(out), "--overwrite"]) == 2
    assert (out / "mine.txt").read_text() == "keep" and "no .bvh" in _error(capsys)

    def succeed(sources, out, **kwargs):
        Path(out).mkdir()
        (Path(out) / "summary.json").write_text("{}")
        return type("Summary", (), {"format": lambda self: "built"})()

    monkeypatch.setattr(build, "build_dataset", succeed)
    assert main(["data", "build", str(tmp_path), "--out", str(out), "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_one_torch_thread_unless_told(tmp_path, monkeypatch, capsys) -> None:
    calls: list[int] = []
    monkeypatch.setattr(torch, "set_num_threads", calls.append)
    assert main([*GEN, "--out", str(tmp_path / "a.npz")]) == 0
    assert main([*GEN, "--out", str(tmp_path / "b.npz"), "--threads", "2"]) == 0
    assert calls == [1, 2]
    assert main([*GEN, "--out", str(tmp_path / "c.npz"), "--threads", "0"]) == 2
    assert "--threads must be >= 1" in _error(capsys)


def test_warnings_are_one_line_each_once(tmp_path, capsys) -> None:
    # 100 m in 4 frames: retimed, with one warning (the request is checked twice: once before the
    # model loads, once by the generator).
    argv = [*GEN, "--waypoints", "0,2,1;100,2,5", "--infeasible", "warn", "--out", str(tmp_path / "x.npz")]
    assert main(argv) == 0
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) >= 1 and all(line.startswith("motion-env generate: warning: ") for line in lines)
    assert len(set(lines)) == len(lines) and "retimed to frame" in lines[0]


def test_the_cache_makes_no_difference(tmp_path, monkeypatch, capsys) -> None:
    """The same command with the embedding cache empty, filled and off: the same motion, bit for bit."""
    import motion_env.text.encoders as encoders

    fresh = encoders.MiniLMEncoder  # a new encoder per command: no embedding kept in memory
    monkeypatch.setattr(encoders, "load_text_encoder", lambda name="minilm", *args, **kw: fresh())
    embedded: list[str] = []
    embed = fresh._embed
    monkeypatch.setattr(fresh, "_embed", lambda self, texts: embedded.extend(texts) or embed(self, texts))
    for name, cache in (("a", str(tmp_path / "c")), ("b", str(tmp_path / "c")), ("off", "off")):
        monkeypatch.setenv("MOTION_ENV_CACHE", cache)
        assert (
            main([*GEN, "--text", "a person waves the left hand", "--out", str(tmp_path / f"{name}.npz")])
            == 0
        )
    # Encoded by the first command, read from the disk by the second, encoded again with the cache off.
    assert embedded == ["a person waves the left hand"] * 2
    assert len(list((tmp_path / "c").rglob("*.emb"))) == 1
    joints = [Motion.load(tmp_path / f"{n}.npz").joints for n in ("a", "b", "off")]
    np.testing.assert_array_equal(joints[0], joints[1])
    np.testing.assert_array_equal(joints[0], joints[2])


def test_json_report_of_bench_is_unchanged_by_the_rules(tmp_path, capsys) -> None:
    """`bench --json` still writes where it is told (the overwrite rule only guards existing files)."""
    out = tmp_path / "deep" / "b.json"
    argv = ["bench", "--random-model", "--runs", "1", "--frames", "8", "--batch-sizes", "1"]
    argv += ["--stream-frames", "4", "--env-steps", "0", "--vector-steps", "0", "--json", str(out)]
    assert main(argv) == 0
    assert json.loads(out.read_text())["untrained"] is True


@pytest.mark.parametrize(
    ("command", "extra", "message"),
    [
        ("control", ["--max-clips", "0"], "ControlSettings.max_clips must be an integer >= 1, got 0"),
        ("captions", ["--seeds", "0"], "RecognitionSettings.seeds must be an integer >= 1, got 0"),
        ("natural", ["--per-action", "1"], "NaturalnessSettings.per_action must be an integer >= 2"),
        ("natural", ["--weights", "nowhere"], "--model/--weights nowhere: no generator weights directory"),
        ("captions", ["--weights", "nowhere"], "--model/--weights nowhere: no generator weights directory"),
        ("natural", ["--split", "val"], "--split val: no val.txt"),
    ],
)
def test_eval_checks_its_settings_before_loading_a_model(
    tmp_path, capsys, no_model, command: str, extra: list[str], message: str
) -> None:
    (tmp_path / "index.csv").write_text("name\n")
    (tmp_path / "test.txt").write_text("")
    assert main(["eval", command, "--data", str(tmp_path), *extra]) == 2
    assert message in _error(capsys)
