"""Tests of `motion-env show` (a stick-figure video and a path plot of a file)."""

from __future__ import annotations

import imageio.v3 as iio

from motion_env.cli import main


def test_cli_show_npz(tmp_path, capsys, walker):
    src = walker(10).save(tmp_path / "walk.npz")
    out, plot = tmp_path / "walk.mp4", tmp_path / "walk.png"
    assert main(["show", str(src), "--out", str(out), "--plot", str(plot)]) == 0
    assert iio.imread(out, index=None).shape[0] == 10
    assert iio.imread(plot).ndim == 3
    assert "wrote" in capsys.readouterr().out
    assert main(["show", str(src), "--out", str(tmp_path / "walk.avi")]) == 2
    assert "unknown video type" in capsys.readouterr().err
    assert main(["show", str(tmp_path / "missing.npz"), "--out", str(tmp_path / "new.mp4")]) == 2
    assert (
        capsys.readouterr().err.strip()
        == f"motion-env show: error: no motion file at {tmp_path / 'missing.npz'}"
    )


def test_cli_show_refuses_to_replace_outputs(tmp_path, capsys, walker, monkeypatch):
    """`show walk.npz` writes walk.mp4 here, where `generate --video walk.mp4` may have put one."""
    monkeypatch.chdir(tmp_path)
    src = walker(4).save(tmp_path / "walk.npz")
    (tmp_path / "walk.mp4").write_bytes(b"from generate")
    assert main(["show", "walk.npz"]) == 2
    assert capsys.readouterr().err.strip() == (
        "motion-env show: error: walk.mp4 exists: nothing was written (pass --overwrite to replace it)"
    )
    assert (tmp_path / "walk.mp4").read_bytes() == b"from generate"
    assert main(["show", str(src), "--overwrite"]) == 0
    assert iio.imread(tmp_path / "walk.mp4", index=None).shape[0] == 4


def test_cli_show_real_bvh(tmp_path, require_data):
    bvh = require_data("bandai/dataset-2/bvh/dataset-2_walk-turn-left_normal_001.bvh.gz")
    out = tmp_path / "turn.gif"
    assert main(["show", str(bvh), "--out", str(out), "--fps", "5", "--plot", str(tmp_path / "t.png")]) == 0
    assert iio.imread(out, index=None).shape[0] > 10
