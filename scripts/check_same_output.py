"""Same requests, same motion: record the shipped model's output on a fixed set of requests, or
compare against a recording (used to show that a refactor changed no behaviour).

    python scripts/check_same_output.py --record out/reference.npz   # before a change
    python scripts/check_same_output.py --compare out/reference.npz  # after it

Covers whole clips (``generate``, ``generate_batch``, ``root_paths``), the stream with a caption
and a route change mid-rollout, and ``Waypoints-v0`` / the native vector env stepped with fixed
actions. Only public names are used, so the script runs unchanged on either side of a refactor.
"""

from __future__ import annotations

import argparse
import sys

import gymnasium as gym
import numpy as np
import torch

import motion_env

ROUTE = [[0, 2, 40], [2, 4, 100], [4, 4, 160]]
REQUESTS = [
    ("a person walks forward and turns left", ROUTE, 200, 0),
    ("a person jogs", [[0, 3], [3, 6]], 120, 1),
    ("an elderly person walks slowly", None, 80, 2),
    ("a person waves with the right hand", None, 60, 3),
    ("a person runs", [[0, 5, 40], [5, 10, 80]], 97, 4),
]


def _clips(gen: motion_env.MotionGenerator) -> dict[str, np.ndarray]:
    """Whole clips: single requests, a batch and the root paths."""
    out: dict[str, np.ndarray] = {}
    for n, (text, wp, frames, seed) in enumerate(REQUESTS):
        out[f"generate_{n}"] = gen.generate(text, waypoints=wp, num_frames=frames, seed=seed).joints
    batch = gen.generate_batch(["a person walks", "a person jogs"], [ROUTE, None], num_frames=64, seed=7)
    for n, m in enumerate(batch):
        out[f"batch_{n}"] = m.joints
    out["root_paths"] = gen.root_paths(["a person walks"], ROUTE, num_frames=100, seed=3, snap=False)
    return out


def _controlled(gen: motion_env.MotionGenerator) -> dict[str, np.ndarray]:
    """Controlled clips: joint targets (a wrist and the pelvis) and objectives, and a batch where
    one row has no control."""
    out: dict[str, np.ndarray] = {}
    targets = np.full((80, 22, 3), np.nan, np.float32)
    targets[40, 21] = [0.3, 1.6, 1.2]
    targets[60, 0] = [0.5, 0.9, 2.0]
    out["controlled"] = gen.generate(
        "a person walks", waypoints=None, num_frames=80, seed=6, joint_targets=targets
    ).joints
    objectives = [
        motion_env.objectives.KeepOut(center=(0.0, 2.0), radius=0.5),
        motion_env.objectives.HeightLimit(joint="head", max_height=1.4, frames=(20, 50)),
    ]
    out["objectives"] = gen.generate(
        "a person walks", waypoints=[[0, 4, 80]], num_frames=80, seed=8, objectives=objectives
    ).joints
    mixed = gen.generate_batch(
        ["a person walks", "a person jogs"], None, num_frames=60, seed=9, joint_targets=[targets[:60], None]
    )
    for n, m in enumerate(mixed):
        out[f"mixed_{n}"] = m.joints
    return out


def _stream(gen: motion_env.MotionGenerator) -> np.ndarray:
    """The stream with a caption, a route, joint targets and objectives changed mid-rollout."""
    stream = gen.stream(["a person walks", "a person jogs"], waypoints=[ROUTE, None], seed=5)
    frames = []
    for t in range(90):
        if t == 30:
            stream.set_text("a person runs", index=1)
        if t == 50:
            stream.set_waypoints([[1, 6], [-2, 8]], index=0)
        if t == 70:
            stream.reset(1, "a person waves", start=[1.0, 1.0, 0.5])
        if t == 12:
            hand = np.full((30, 22, 3), np.nan, np.float32)
            hand[20, 21] = [0.4, 1.5, 1.5]
            stream.set_joint_targets(hand, index=0)
            stream.set_objectives(
                [motion_env.objectives.HeightLimit(joint="head", max_height=1.5, frames=(40, 60))], index=1
            )
        frames.append(stream.step())
    return np.stack(frames)


def _envs(gen: motion_env.MotionGenerator) -> dict[str, np.ndarray]:
    """Waypoints-v0 stepped with fixed actions, then the native vector env, then a learner's."""
    out: dict[str, np.ndarray] = {}
    env = gym.make("motion_env/Waypoints-v0", generator=gen, frames_per_step=2, action_mode="absolute")
    obs, info = env.reset(seed=0, options={"text": "a person jogs", "waypoints": [[0, 3], [3, 6]]})
    joints = []
    for t in range(60):
        action = info["route_target"] if t % 20 < 10 else np.array([2.0, 1.0], np.float32)
        obs, _, term, trunc, info = env.step(action)
        joints.append(info["joints"])
        if term or trunc:
            break
    out["env"] = np.stack(joints)

    venv = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=3, vectorization_mode="vector_entry_point", generator=gen,
        action_mode="absolute", frames_per_step=1,
    )  # fmt: skip
    obs, info = venv.reset(seed=1)
    vj = []
    for _ in range(40):
        obs, _, _, _, info = venv.step(np.asarray(obs["target"], np.float32))
        vj.append(np.asarray(obs["pose"]))
    out["vector_env"] = np.stack(vj)

    # A learner: a new normalised target for every character at every step (the route re-planned
    # each token), with same-step autoresets.
    venv = gym.make_vec(
        "motion_env/Waypoints-v0", num_envs=4, vectorization_mode="vector_entry_point", generator=gen,
        follow_action=False, max_episode_steps=12, autoreset_mode="same_step",
    )  # fmt: skip
    obs, info = venv.reset(seed=2)
    rng = np.random.default_rng(0)
    vj = []
    for _ in range(40):
        obs, _, _, _, info = venv.step(rng.uniform(-1, 1, (4, 2)).astype(np.float32))
        vj.append(info["step_joints"])
    out["learner_env"] = np.stack(vj)
    return out


def outputs() -> dict[str, np.ndarray]:
    """Every recorded output of the shipped model, by name."""
    gen = motion_env.MotionGenerator.from_pretrained()
    return {**_clips(gen), **_controlled(gen), "stream": _stream(gen), **_envs(gen)}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--record", help="write the outputs to this .npz")
    g.add_argument("--compare", help="compare the outputs with this .npz")
    p.add_argument("--tol", type=float, default=1e-5, help="largest allowed difference (m)")
    args = p.parse_args()
    torch.set_num_threads(1)
    out = outputs()
    if args.record:
        np.savez(args.record, **out)
        print(f"wrote {len(out)} outputs to {args.record}")
        return 0
    ref = np.load(args.compare)
    worst = 0.0
    for key in sorted(set(ref.files) | set(out)):
        if key not in ref.files or key not in out or ref[key].shape != out[key].shape:
            print(f"{key:12s} MISMATCH: missing or different shape")
            worst = np.inf
            continue
        diff = float(np.abs(ref[key].astype(np.float64) - out[key]).max())
        worst = max(worst, diff)
        print(f"{key:12s} {str(out[key].shape):16s} max |difference| {diff:.3g} m")
    ok = worst <= args.tol
    print(f"{'SAME' if ok else 'DIFFERENT'}: largest difference {worst:.3g} m (tolerance {args.tol:g})")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
