"""motion_env.objectives: the costs, their violations and their checks."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import motion_env
from motion_env.objectives import HeightLimit, KeepOut, StayInside, joint_index


def _still(x: float = 0.0, z: float = 0.0, height: float = 1.0) -> np.ndarray:
    j = np.zeros((10, 22, 3), np.float32)
    j[..., 0], j[..., 1], j[..., 2] = x, np.linspace(0, height, 22), z
    return j


def test_keep_out_cost_and_violation() -> None:
    k = KeepOut(center=(0.0, 0.0), radius=0.5)
    inside, outside = _still(0.2, 0.0), _still(1.0, 0.0)
    assert k.violation(inside).max() == pytest.approx(0.3)
    assert k.violation(outside).max() == 0.0
    assert float(k(torch.as_tensor(inside))) > 0 and float(k(torch.as_tensor(outside))) == 0.0


def test_height_limit_by_name_and_frames() -> None:
    h = HeightLimit("head", max_height=0.5, frames=(2, 5))
    j = _still(height=1.0)
    v = h.violation(j)
    assert v[:2].max() == 0 and v[2:5].min() > 0 and v[5:].max() == 0
    assert HeightLimit(15, min_height=2.0).violation(j).min() > 0
    t = torch.tensor(j, requires_grad=True)
    h(t).backward()
    assert t.grad[2:5, 15, 1].min() > 0


def test_stay_inside_either_winding() -> None:
    square = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    for poly in (square, square[::-1]):
        s = StayInside(poly)
        assert s.violation(_still(0.0, 0.0)).max() == 0.0
        assert s.violation(_still(1.5, 0.0)).max() == pytest.approx(0.5)


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: HeightLimit("hed", max_height=1.0), "unknown joint name 'hed'"),
        (lambda: HeightLimit(22, max_height=1.0), "joint name or an index"),
        (lambda: HeightLimit("head"), "max_height, min_height or both"),
        (lambda: HeightLimit("head", max_height=1.0, min_height=2.0), "above max_height"),
        (lambda: KeepOut(center=(0, 0), radius=-1), "radius must be > 0"),
        (lambda: KeepOut(center=(0, np.inf), radius=1), "finite"),
        (lambda: KeepOut(center=(0, 0), radius=1, joints=["left_hand"]), "unknown joint name"),
        (lambda: StayInside([(0, 0), (1, 1)]), "K >= 3"),
        (lambda: StayInside([(0, 0), (1, 1), (2, 2)]), "no area"),
        (lambda: HeightLimit("head", max_height=1.0, frames=(5, 2)), "start < stop"),
    ],
)
def test_bad_objectives(make, match) -> None:
    with pytest.raises(ValueError, match=match):
        make()


def test_joint_index_and_package_access() -> None:
    assert joint_index("right_wrist") == 21 and joint_index(0) == 0
    assert motion_env.objectives.KeepOut is KeepOut
