"""Goal reaching with hindsight relabelling: stable-baselines3 SAC + HerReplayBuffer on GoalReach-v0.

motion_env/GoalReach-v0 is the GoalEnv form of the waypoint env: the observation is a Dict with
``observation``, ``achieved_goal`` (the pelvis x, z) and ``desired_goal``, and its
``compute_reward`` works on batches of goals, so SB3's HerReplayBuffer can pretend, after the fact,
that wherever the character ended up was the goal ("future" strategy). The sparse reward is -1 per
decision until the pelvis is within arrive_radius of the goal. After training the agent walks to a
fixed goal; the example writes that rollout as a video, a top-down plot and a .npz, and prints the
evaluation success next to a random agent's.

Needs the optional extra: pip install -c constraints.txt -e ".[rl]"  (stable-baselines3)

    python examples/goal_reach_her.py --out runs/her --total-timesteps 3000
    python examples/goal_reach_her.py --random-model --total-timesteps 60 --learning-starts 20 \\
        --eval-steps 10 --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass, require
from motion_env.evaluation.episode import run_episode


@dataclass
class Args(ExampleArgs):
    out: str = "runs/goal_reach_her"  # output folder
    total_timesteps: int = 3000  # env steps of training
    learning_starts: int = 200  # random steps before the first update
    batch_size: int = 128
    n_sampled_goal: int = 4  # relabelled goals per real one
    frames_per_step: int = 4  # frames per decision (0.2 s at 20 fps)
    reach: float = 2.0  # metres: the action [-1, 1]^2 maps to a point this far in the character's frame
    episode_steps: int = 50  # decisions per training episode (10 s)
    eval_steps: int = 75
    goal_x: float = 2.0  # the evaluation goal, world metres
    goal_z: float = 3.0
    text: str = "a person walks forward"  # caption of the evaluation rollout


def make_env(generator: object, args: Args, max_steps: int) -> gym.Env:
    """GoalReach-v0 with normalised actions: [-1, 1]^2 is a point up to `reach` metres around the
    character, in its own frame. No "follow" switch: the agent must learn to steer to the goal."""
    return gym.make(
        "motion_env/GoalReach-v0",
        generator=generator,
        action_mode="normalized",
        reach=args.reach,
        follow_action=False,
        frames_per_step=args.frames_per_step,
        max_episode_steps=max_steps,
    )


def main(args: Args) -> dict:
    sb3 = require("stable_baselines3", "rl")  # the optional extra
    out, generator = args.setup()

    # Train: a random goal 1.5-4 m away every episode; HER relabels with goals reached later on.
    env = make_env(generator, args, args.episode_steps)
    env.reset(seed=args.seed)
    model = sb3.SAC(
        "MultiInputPolicy",
        env,
        replay_buffer_class=sb3.HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": args.n_sampled_goal, "goal_selection_strategy": "future"},
        learning_starts=args.learning_starts,
        batch_size=args.batch_size,
        seed=args.seed,
        device="cpu",
        verbose=0,
    )
    model.learn(total_timesteps=args.total_timesteps, progress_bar=True)  # minutes of training: show them
    model.save(out / "sac_her_goal_reach.zip")
    env.close()

    goal = np.array([args.goal_x, args.goal_z], np.float32)
    episode = {"text": args.text, "goal": goal}
    eval_env = make_env(generator, args, args.eval_steps)
    sac = run_episode(eval_env, lambda o: model.predict(o, deterministic=True)[0], args.seed, episode)
    random_agent = run_episode(eval_env, None, args.seed, episode)
    eval_env.close()

    final = float(np.linalg.norm(sac.joints[-1, 0, [0, 2]] - goal))
    result = {
        "total_timesteps": args.total_timesteps,
        "eval_success": bool(sac.info["is_success"]),
        "eval_final_distance_m": final,
        "random_agent_success": bool(random_agent.info["is_success"]),
        "eval_frames": int(len(sac.joints)),
    }
    motion = motion_env.Motion(
        sac.joints, text=args.text, waypoints=goal[None], meta={"example": "goal_reach_her"}
    )
    args.write_outputs(motion, "goal_reach_her_eval", result, f"SAC + HER after {args.total_timesteps} steps")
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
