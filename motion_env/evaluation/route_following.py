"""Route following: the routes a generator is asked to follow, and how well it follows them.

Two sets of routes (definitions of the numbers in ``docs/metrics.md``):

- held-out takes: the test split's own root paths, with timed waypoints every 2-3 s taken from
  the take (and its last frame), the character starting where the take starts; captions are
  written here from the take's labels in words the training captions do not use;
- synthetic routes: lines, arcs, zigzags and S-curves at walking (1.0-1.5 m/s) and running
  (2.5-3.5 m/s) pace, timed waypoints every 2-3 s, with new walking / running captions.

Per set: root error, location error, trajectory error and the largest miss
(:func:`~motion_env.evaluation.metrics.route_summary`), for the final motions, for the
controller's path alone (before the path is bent through the waypoints) and, on the synthetic
routes, for streaming (:meth:`MotionGenerator.stream`); foot skating of every generated clip.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.data.dataset import read_index
from motion_env.evaluation.captions import RUN_CAPTIONS, WALK_CAPTIONS, heldout_caption
from motion_env.evaluation.metrics import foot_skating_ratio, route_summary
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import root_path_from_joints, waypoint_errors


@dataclass
class Case:
    """One route to follow: caption, (K, 3) timed waypoints, start (x, z, heading), frames."""

    name: str
    text: str
    waypoints: np.ndarray
    start: np.ndarray
    num_frames: int
    group: str


def _waypoint_frames(num_frames: int, rng: np.random.Generator) -> list[int]:
    """Frames every 2-3 s (40-60 frames) after the start, and the last frame."""
    frames, f = [], 0
    while True:
        f += int(rng.integers(40, 61))
        if f >= num_frames - 10:
            break
        frames.append(f)
    return frames + [num_frames - 1]


def synthetic_path(
    kind: str, speed: float, num_frames: int, rng: np.random.Generator, corners: list[int] | None = None
) -> np.ndarray:
    """A (T, 2) XZ path from the origin, heading +Z, at constant `speed` (m/s).

    Shapes are scaled by time, so that a run is the same shape as a walk, only larger:
    "line"; "arc": turning 11-19 deg/s to one side; "zigzag": legs at +-30-50 deg that change
    at the `corners` frames (default: every 2-3 s); "scurve": the heading swinging +-30-50 deg
    with a period of 6-9 s.
    """
    t = np.arange(num_frames) / FPS
    side = rng.choice([-1.0, 1.0])
    if kind == "line":
        heading = np.zeros_like(t)
    elif kind == "arc":
        heading = side * t / rng.uniform(3.0, 5.0)
    elif kind == "zigzag":
        corners = corners if corners is not None else _waypoint_frames(num_frames, rng)
        leg = np.searchsorted(np.asarray(corners), np.arange(num_frames), side="right")
        heading = side * np.deg2rad(rng.uniform(30, 50)) * np.where(leg % 2 == 0, 1.0, -1.0)
    elif kind == "scurve":
        heading = side * np.deg2rad(rng.uniform(30, 50)) * np.sin(2 * np.pi * t / rng.uniform(6.0, 9.0))
    else:
        raise ValueError(f"unknown synthetic path kind {kind!r}")
    step = np.stack([np.sin(heading), np.cos(heading)], axis=1) * speed / FPS
    return np.concatenate([np.zeros((1, 2)), np.cumsum(step[:-1], axis=0)])


def synthetic_cases(num_frames: int = 200, repeats: int = 2, seed: int = 0) -> list[Case]:
    """Lines, arcs, zigzags, S-curves at walking and running pace, timed waypoints every 2-3 s."""
    rng = np.random.default_rng(seed)
    cases = []
    for kind in ("line", "arc", "zigzag", "scurve"):
        for pace, (lo, hi), captions in (
            ("walk", (1.0, 1.5), WALK_CAPTIONS),
            ("run", (2.5, 3.5), RUN_CAPTIONS),
        ):
            for r in range(repeats):
                speed = float(rng.uniform(lo, hi))
                frames = _waypoint_frames(num_frames, rng)
                path = synthetic_path(kind, speed, num_frames, rng, corners=frames[:-1])
                wp = np.array([[*path[f], f] for f in frames], np.float32)
                text = captions[int(rng.integers(len(captions)))]
                cases.append(Case(f"{kind}-{pace}-{r}", text, wp, np.zeros(3, np.float32), num_frames, pace))
    return cases


def heldout_cases(
    data_dir: str | Path, max_clips: int = 64, min_frames: int = 60, seed: int = 0, split: str = "test"
) -> tuple[list[Case], list[np.ndarray]]:
    """Routes of a held-out split's takes: (cases, the takes' real joints (T, 22, 3)).

    split: "test" for reporting; "val" for choosing between models or settings.
    """
    from motion_env.data.dataset import read_split

    data_dir = Path(data_dir)
    index = read_index(data_dir)
    clips = [c for c in read_split(data_dir, split) if len(c.joints) >= min_frames and ":" not in c.name]
    rng = np.random.default_rng(seed)
    if len(clips) > max_clips:
        clips = [clips[i] for i in sorted(rng.choice(len(clips), max_clips, replace=False))]
    cases, real = [], []
    for clip in clips:
        joints = np.asarray(clip.joints, np.float32)
        path = root_path_from_joints(joints)
        frames = _waypoint_frames(len(joints), rng)
        wp = np.array([[path[f, 0], path[f, 1], f] for f in frames], np.float32)
        row = index.get(clip.name, {})
        label = row.get("label", "")
        moving = np.linalg.norm(path[-1, :2] - path[0, :2]) > 1.0
        text = heldout_caption(label, row.get("style", ""), clip.captions[0])
        cases.append(
            Case(clip.name, text, wp, path[0].copy(), len(joints), "moving" if moving else "in place")
        )
        real.append(joints)
    return cases, real


def _generate(
    gen: Any, cases: list[Case], seed: int, batch: int = 16
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Final joints and the controller-only root paths of every case (batched)."""
    joints, raw = [], []
    for first in range(0, len(cases), batch):
        chunk = cases[first : first + batch]
        frames = max(c.num_frames for c in chunk)
        args = ([c.text for c in chunk], [c.waypoints for c in chunk], frames, seed + first)
        starts = np.stack([c.start for c in chunk])
        motions = gen.generate_batch(*args, starts=starts)
        paths = gen.root_paths(*args, starts=starts, snap=False)
        for c, m, p in zip(chunk, motions, paths, strict=True):
            joints.append(m.joints[: c.num_frames])
            raw.append(p[: c.num_frames])
    return joints, raw


def _stream(gen: Any, cases: list[Case], seed: int) -> list[np.ndarray]:
    """Every case streamed frame by frame in one batch (the environment's path)."""
    stream = gen.stream(
        [c.text for c in cases], [c.waypoints for c in cases], np.stack([c.start for c in cases]), seed
    )
    frames = max(c.num_frames for c in cases)
    out = np.stack([stream.step() for _ in range(frames)], axis=1)  # (B, T, 22, 3)
    return [out[i, : c.num_frames] for i, c in enumerate(cases)]


def evaluate_routes(
    gen: Any, cases: list[Case], seed: int, stream: bool
) -> tuple[dict[str, Any], list[np.ndarray]]:
    """Route metrics of the final motions, the controller alone and (optionally) streaming."""
    joints, raw = _generate(gen, cases, seed)
    final = [waypoint_errors(j[:, 0, [0, 2]], c.waypoints) for j, c in zip(joints, cases, strict=True)]
    ctrl = [waypoint_errors(p[:, :2], c.waypoints) for p, c in zip(raw, cases, strict=True)]
    out: dict[str, Any] = {
        "final": route_summary(final),
        "controller_only": route_summary(ctrl),
        "groups": {},
        "foot_skating": float(np.mean([foot_skating_ratio(j) for j in joints])),
    }
    for group in sorted({c.group for c in cases}):
        idx = [i for i, c in enumerate(cases) if c.group == group]
        out["groups"][group] = {
            "final": route_summary([final[i] for i in idx]),
            "controller_only": route_summary([ctrl[i] for i in idx]),
            "foot_skating": float(np.mean([foot_skating_ratio(joints[i]) for i in idx])),
        }
    if stream:
        streamed = _stream(gen, cases, seed)
        out["stream"] = route_summary(
            [waypoint_errors(j[:, 0, [0, 2]], c.waypoints) for j, c in zip(streamed, cases, strict=True)]
        )
        out["stream_foot_skating"] = float(np.mean([foot_skating_ratio(j) for j in streamed]))
        joints = joints + streamed
    return out, joints
