"""Train a stable-baselines3 PPO agent on motion_env/Waypoints-v0 through the native vector env.

`motion_env.make_sb3_env` gives SB3 a VecEnv of --num-envs characters that share one batched
generator stream. The env's learning defaults do the rest: normalised actions (a point up to
`reach` metres around the character, in its own frame, plus a "follow the route" switch), four
frames (0.2 s) per decision, and a reward of progress, arrival bonuses and a time cost. PPO runs with
SB3's default hyperparameters unless told otherwise. After training the agent walks one fixed route
deterministically; the example writes that rollout as a video, a top-down plot and a .npz, the
model as a .zip, and prints the evaluation return next to a random agent's.

Needs the optional extra: pip install -c constraints.txt -e ".[rl]"  (stable-baselines3)

    python examples/sb3_ppo.py --out runs/ppo --total-timesteps 60000
    python examples/sb3_ppo.py --random-model --total-timesteps 32 --n-steps 16 --eval-steps 10 \\
        --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass, parse_waypoints, require
from motion_env.evaluation.episode import run_episode


@dataclass
class Args(ExampleArgs):
    out: str = "runs/sb3_ppo"  # output folder
    total_timesteps: int = 60_000  # env steps of training, summed over the envs
    num_envs: int = 16  # characters trained together (one batched generator call per frame)
    n_steps: int = 2048  # rollout length per env and PPO update (SB3's default)
    batch_size: int = 64  # SB3's default
    learning_rate: float = 3e-4  # SB3's default
    frames_per_step: int = 4  # frames per decision (0.2 s at 20 fps), the env's default
    episode_steps: int = 150  # decisions per training episode (30 s), the registration's default
    eval_steps: int = 150  # decisions in the evaluation rollout
    eval_route: str = "0,3;3,5;5,2"  # the evaluation route "x,z;..." (world metres)
    text: str = "a person walks forward"  # caption of the evaluation rollout


def make_env(generator: object, args: Args, max_steps: int) -> gym.Env:
    """One Waypoints-v0 with the learning defaults, for the evaluation rollout."""
    return gym.make("motion_env/Waypoints-v0", generator=generator, max_episode_steps=max_steps,
                    frames_per_step=args.frames_per_step)  # fmt: skip


def main(args: Args) -> dict:
    sb3 = require("stable_baselines3", "rl")  # the optional extra
    out, generator = args.setup()

    # Train: random captions and routes every episode (drawn by the env from its seed).
    env = motion_env.make_sb3_env(
        "motion_env/Waypoints-v0",
        args.num_envs,
        generator=generator,
        frames_per_step=args.frames_per_step,
        max_episode_steps=args.episode_steps,
    )
    env.seed(args.seed)
    model = sb3.PPO(
        "MultiInputPolicy",
        env,
        n_steps=args.n_steps,
        batch_size=args.batch_size,
        learning_rate=args.learning_rate,
        seed=args.seed,
        device="cpu",
        verbose=0,
    )
    model.learn(total_timesteps=args.total_timesteps, progress_bar=True)  # minutes of training: show them
    model.save(out / "ppo_waypoints.zip")
    env.close()  # fmt: skip

    # Evaluate on a fixed route: the trained agent, then a random one for comparison.
    route = np.array(parse_waypoints(args.eval_route, "--eval-route"), np.float32)[:, :2]
    episode = {"text": args.text, "waypoints": route}
    eval_env = make_env(generator, args, args.eval_steps)
    ppo = run_episode(eval_env, lambda o: model.predict(o, deterministic=True)[0], args.seed, episode)
    random_agent = run_episode(eval_env, None, args.seed, episode)
    eval_env.close()

    result = dict(
        total_timesteps=args.total_timesteps,
        eval_return=ppo.total_return,
        random_agent_return=random_agent.total_return,
        eval_reached_last_waypoint=ppo.terminated,
        eval_frames=int(len(ppo.joints)),
    )
    motion = motion_env.Motion(ppo.joints, text=args.text, waypoints=route, meta={"example": "sb3_ppo"})
    args.write_outputs(motion, "sb3_ppo_eval", result, f"PPO after {args.total_timesteps} steps: {args.text}")
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
