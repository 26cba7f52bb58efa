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
