"""Where does a character stand at the end of an untimed route: on its last waypoint?

Routes of two untimed waypoints: 2.9 m ahead (slightly to the left), then 3.5 m on after a turn
of 0°, 60°, 120° or 160° (the sharp ones: the last waypoint is almost behind the character),
for a walk, a jog and a run caption, 300 frames (15 s: time to arrive and stand). Per clip: the
end gap (the pelvis's floor distance to the last waypoint at the last frame), the closest
approach to it, the foot skating (``docs/metrics.md``) and the MuJoCo replay's verdict. Prints
each clip, then the median and largest gap, the clips standing over 25 cm off, the mean skating
and the plausible count.

    python scripts/measure_stop_gap.py --seeds 3
    python scripts/measure_stop_gap.py --seeds 3 --stage streamed
"""

from __future__ import annotations

import argparse
import warnings

import numpy as np
import torch

from motion_env.evaluation.metrics import foot_skating_ratio
from motion_env.generation.generator import MotionGenerator
from motion_env.motion.skeleton import FPS
from motion_env.motion.types import Motion
from motion_env.replay import evaluate

CAPTIONS = ("a person walks forward", "a person jogs", "a person runs")
TURNS = (0.0, 60.0, 120.0, 160.0)
FIRST = np.array([0.8, 2.8])
SECOND_LEG = 3.5  # metres
FRAMES = 300


def route_with_turn(degrees: float) -> np.ndarray:
    """(2, 3) untimed waypoints: FIRST, then SECOND_LEG on after turning `degrees` left."""
    a = np.radians(degrees)
    ahead = FIRST / np.linalg.norm(FIRST)
    turned = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]]) @ ahead
    second = FIRST + SECOND_LEG * turned
    return np.array([[*FIRST, np.nan], [*second, np.nan]], np.float32)


def make(
    gen: MotionGenerator, caption: str, route: np.ndarray, seed: int, stage: str, frames: int
) -> np.ndarray:
    """(frames, 22, 3) joints of `caption` along `route`, as a whole clip or streamed."""
    if stage == "streamed":
        stream = gen.stream([caption], waypoints=[route], seed=seed)
        return np.stack([np.asarray(stream.step())[0] for _ in range(frames)])
    return gen.generate(caption, waypoints=route, num_frames=frames, seed=seed).joints


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="seeds per caption and turn (default 3)")
    parser.add_argument("--stage", choices=("generated", "streamed"), default="generated")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default 1)")
    parser.add_argument("--captions", nargs="+", default=list(CAPTIONS), help="captions to make")
    parser.add_argument("--turns", nargs="+", type=float, default=list(TURNS), help="turns in degrees")
    parser.add_argument("--frames", type=int, default=FRAMES, help=f"frames per clip (default {FRAMES})")
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, got {args.seeds}")
    if args.frames < 20:
        parser.error(f"--frames must be at least 20 (one second), got {args.frames}")
    torch.set_num_threads(args.threads)
    warnings.simplefilter("ignore")  # the captions' own notes are not what is measured
    gen = MotionGenerator.from_pretrained()
    gaps, skating, plausible = [], [], []
    for caption in args.captions:
        for degrees in args.turns:
            route = route_with_turn(degrees)
            for seed in range(args.seeds):
                joints = make(gen, caption, route, seed, args.stage, args.frames)
                pelvis = joints[:, 0, [0, 2]]
                off = np.linalg.norm(pelvis - route[-1, :2], axis=1)
                gaps.append(float(off[-1]))
                skating.append(foot_skating_ratio(joints))
                plausible.append(bool(evaluate(Motion(joints=joints, fps=FPS))["plausible"]))
                print(
                    f"{caption:24s} turn {degrees:3.0f}° seed {seed}: end gap {off[-1]:.3f} m, "
                    f"closest {off.min():.3f} m, skating {skating[-1]:.3f}, plausible {plausible[-1]}",
                    flush=True,
                )
    g = np.array(gaps)
    print(
        f"{args.stage}: end gap median {np.median(g):.3f} m, largest {g.max():.3f} m, "
        f"{int((g > 0.25).sum())} of {len(g)} over 25 cm; skating {np.mean(skating):.4f}; "
        f"plausible {sum(plausible)} of {len(plausible)}"
    )


if __name__ == "__main__":
    main()
