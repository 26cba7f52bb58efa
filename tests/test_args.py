"""motion_env.args: settings dataclasses as command lines, and the waypoint text form."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest

from motion_env.args import field_comments, parse_dataclass, parse_waypoints


@dataclass
class _Settings:
    out: str = "runs/x"  # output folder
    steps: int = 10  # training steps
    rate: float = 0.5
    fast: bool = False  # skip the slow part
    limit: float | None = None  # stop after this share (in %) of the steps


def test_parse_dataclass_maps_every_field() -> None:
    assert parse_dataclass(_Settings, []) == _Settings()
    got = parse_dataclass(_Settings, ["--out", "o", "--steps", "3", "--rate", "2", "--fast", "--limit", "50"])
    assert got == _Settings(out="o", steps=3, rate=2.0, fast=True, limit=50.0)
    assert parse_dataclass(_Settings, ["--limit", "none"]).limit is None
    assert parse_dataclass(_Settings, ["--no-fast"]).fast is False
    with pytest.raises(SystemExit):
        parse_dataclass(_Settings, ["--steps", "three"])


def test_field_comments_become_help(capsys) -> None:
    assert field_comments(_Settings) == {
        "out": "output folder",
        "steps": "training steps",
        "fast": "skip the slow part",
        "limit": "stop after this share (in %) of the steps",
    }
    with pytest.raises(SystemExit):
        parse_dataclass(_Settings, ["--help"], description="what it does")
    out = capsys.readouterr().out
    assert "what it does" in out and "training steps (default: 10)" in out and "(in %)" in out


def test_parse_waypoints() -> None:
    rows = parse_waypoints("0,2,40; 2,4")
    assert rows[0] == [0.0, 2.0, 40.0] and rows[1][:2] == [2.0, 4.0] and math.isnan(rows[1][2])
    with pytest.raises(ValueError, match=r"--route item 1 'a,b'"):
        parse_waypoints("0,1;a,b", "--route")
    with pytest.raises(ValueError, match="has 1 numbers"):
        parse_waypoints("0")
    with pytest.raises(ValueError, match="empty"):
        parse_waypoints(" ; ")
