"""Which way the body faces while it travels: forwards, sideways or backwards, per route shape.

The path controller learned its heading from real takes, in which a waypoint behind is a backward
walk's: it went backwards to a waypoint behind whatever the caption said, until walks were given a
U-turn (``route_planning.turn_round``; runs and jogs still go backwards: the model card's
Limitations). This measures it. For each caption and route (a waypoint ahead, to the side, behind,
behind on the right, and a route out and back), whole clips
(``MotionGenerator.generate``) and the stream as ``motion_env/Waypoints-v0`` emits it (absolute
actions, one frame a step, the agent sending the route target): of the frames where the pelvis
moves faster than ``--min-speed``, the share whose facing (hips and shoulders,
:func:`~motion_env.motion.kinematics.heading_from_joints`) is within 60° of the direction of
travel (forwards), 60-120° from it (sideways) and over 120° from it (backwards), over the seeds;
and, so that a body turned round is seen to stay a body, how many clips the MuJoCo replay
(:func:`motion_env.replay.evaluate`) judges plausible and the joints' acceleration (99th percentile
over joints and frames, the median clip's).

    python scripts/walk_direction.py --seeds 3
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import torch

import motion_env  # noqa: F401  (registers the environments)
from motion_env.motion.kinematics import heading_from_joints
from motion_env.motion.skeleton import FPS
from motion_env.motion.types import Motion
from motion_env.replay import evaluate

# Route shapes from the start (origin, facing +Z), untimed waypoints (x, z) in metres.
ROUTES = {
    "ahead": [[0.0, 4.0]],
    "side": [[4.0, 0.0]],
    "behind": [[0.0, -4.0]],
    "behind right": [[-2.83, -2.83]],
    "out and back": [[0.0, 4.0], [0.0, 0.0]],
}
CAPTIONS = ("a person walks", "a person jogs", "a person walks backwards")


def directions(joints: np.ndarray, min_speed: float) -> np.ndarray:
    """(moving frames,) angle in degrees between the facing and the pelvis's travel of a (T, 22, 3) motion."""
    travel = np.diff(joints[:, 0, [0, 2]], axis=0) * FPS  # (T - 1, 2) x, z
    speed = np.linalg.norm(travel, axis=1)
    theta = heading_from_joints(joints[1:])
    facing = np.stack([np.sin(theta), np.cos(theta)], axis=1)
    cos = (facing * travel).sum(1) / np.maximum(speed, 1e-9)
    return np.degrees(np.arccos(np.clip(cos[speed > min_speed], -1.0, 1.0)))


def acceleration_p99(joints: np.ndarray) -> float:
    """The 99th percentile over joints and frames of a (T, 22, 3) motion's joint acceleration (m/s^2)."""
    if len(joints) < 3:
        return 0.0
    return float(np.percentile(np.linalg.norm(np.diff(joints, 2, axis=0), axis=-1) * FPS**2, 99))


def summary(motions: list[np.ndarray], min_speed: float) -> str:
    """One line for the (T, 22, 3) motions of every seed: facing shares, replay, acceleration."""
    plausible = sum(bool(evaluate(Motion(joints=j, fps=FPS)).get("plausible")) for j in motions)
    accel = np.median([acceleration_p99(j) for j in motions])
    facing = shares([directions(j, min_speed) for j in motions])
    return f"{facing}; plausible {plausible}/{len(motions)}, acceleration p99 {accel:.1f} m/s^2"


def shares(angles: list[np.ndarray]) -> str:
    """Forwards / sideways / backwards shares of the moving frames of every seed."""
    a = np.concatenate(angles) if angles else np.zeros(0)
    if not len(a):
        return "no moving frames"
    forwards, sideways, backwards = (a < 60).mean(), ((a >= 60) & (a <= 120)).mean(), (a > 120).mean()
    return (
        f"forwards {forwards:4.0%}  sideways {sideways:4.0%}  backwards {backwards:4.0%}  "
        f"({len(a)} moving frames)"
    )


def streamed(env: gym.Env, text: str, route: list[list[float]], seed: int, steps: int) -> np.ndarray:
    """(T, 22, 3) joints of one episode of the environment following `route`."""
    _, info = env.reset(seed=seed, options={"text": text, "waypoints": route})
    frames = [info["joints"].copy()]
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(info["route_target"].astype(np.float32))
        frames.append(info["joints"].copy())
        if terminated or truncated:
            break
    return np.stack(frames)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="clips (and episodes) per caption and route")
    parser.add_argument("--frames", type=int, default=160, help="frames of a whole clip; steps of an episode")
    parser.add_argument(
        "--text", action="append", default=None, help="a caption (repeatable; default: CAPTIONS)"
    )
    parser.add_argument("--min-speed", type=float, default=0.4, help="m/s: slower frames are not counted")
    parser.add_argument(
        "--weights", default=None, help="generator weights (default: shipped; random: the test model)"
    )
    args = parser.parse_args()
    if args.seeds < 1 or args.frames < 2 or args.min_speed < 0:
        parser.error("--seeds >= 1, --frames >= 2 and --min-speed >= 0, please")
    torch.set_num_threads(1)
    from motion_env.generation.generator import MotionGenerator

    gen = MotionGenerator.from_pretrained(args.weights)
    env = gym.make("motion_env/Waypoints-v0", generator=gen, action_mode="absolute", frames_per_step=1)
    for text in args.text or CAPTIONS:
        for name, route in ROUTES.items():
            clips, episodes = [], []
            for seed in range(args.seeds):
                motion = gen.generate(text, waypoints=np.array(route), num_frames=args.frames, seed=seed)
                clips.append(np.asarray(motion.joints))
                episodes.append(streamed(env, text, route, seed, args.frames))
            print(f"{text!r:28} {name:13} clip:   {summary(clips, args.min_speed)}")
            print(f"{'':28} {'':13} stream: {summary(episodes, args.min_speed)}")
    env.close()


if __name__ == "__main__":
    main()
