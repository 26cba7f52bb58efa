"""Tests of motion_env.render.plot (plot_path)."""

from __future__ import annotations

import imageio.v3 as iio
import numpy as np
import pytest

from motion_env.render import plot_path


def test_plot_path_writes_png(tmp_path, walker):
    a, b = walker(45), walker(45, heading=1.0)
    b.text = "a person glides to the left"
    wps = [[0.0, 1.0, 20.0], [1.5, 2.0, 40.0], [0.0, 3.0, np.nan]]
    out = plot_path([a, b], tmp_path / "paths.png", waypoints=wps, obstacles=[[1, 1, 0.3]], title="two")
    img = iio.imread(out)
    assert img.ndim == 3 and img.shape[0] > 300 and img.std() > 10
    dense = np.stack([np.zeros(50), np.linspace(0, 2, 50)], -1)  # a waypoint every frame: a line
    assert plot_path(a, tmp_path / "dense.png", waypoints=dense).is_file()
    with pytest.raises(ValueError, match=r"\.png"):
        plot_path(a, tmp_path / "paths.jpg")
    with pytest.raises(ValueError, match="at least one"):
        plot_path([], tmp_path / "none.png")


def test_plot_path_labels_timed_waypoints_in_frames(tmp_path, walker, monkeypatch):
    import motion_env.render.plot as plot_module

    figures = []
    save = plot_module.Figure.savefig
    monkeypatch.setattr(
        plot_module.Figure, "savefig", lambda fig, *a, **k: (figures.append(fig), save(fig, *a, **k))
    )
    plot_path(
        walker(45), tmp_path / "p.png", waypoints=[[0.0, 1.0, 20.0], [1.5, 2.0, 40.0], [0.0, 3.0, np.nan]]
    )
    texts = [t.get_text() for t in figures[0].axes[0].texts]
    assert "f20 (1.0 s)" in texts and "f40 (2.0 s)" in texts
    assert not any(t.startswith("t=") for t in texts)


def test_plot_path_names_bad_input(tmp_path, walker):
    a, b = walker(10), walker(10)
    b.joints[4, 0, 2] = np.inf
    with pytest.raises(
        ValueError, match=r"motion_or_motions\[1\]\.joints has NaN or infinite values at frames \[4\]"
    ):
        plot_path([a, b], tmp_path / "p.png")
    with pytest.raises(TypeError, match=r"motion_or_motions\[0\] must be a motion_env.Motion, got ndarray"):
        plot_path([a.joints], tmp_path / "p.png")
    a.fps = -1.0
    with pytest.raises(ValueError, match=r"motion_or_motions\.fps must be a positive finite number"):
        plot_path(a, tmp_path / "p.png")
    with pytest.raises(ValueError, match="waypoints have infinite or negative times"):
        plot_path(walker(10), tmp_path / "p.png", waypoints=[[0.0, 1.0, -1.0]])
    assert not list(tmp_path.iterdir())
