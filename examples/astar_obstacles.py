"""Walk around obstacles to a goal: an A* planner drives motion_env/Waypoints-v0.

The planner (policies.AStarPolicy) plans on an occupancy grid whose obstacles are inflated by a
clearance, smooths the plan, and every step issues a "carrot" point one lookahead ahead on it as the
env's action. The route given at reset is just the goal, so the episode ends when the pelvis is
within arrive_radius of it. Writes a video, a top-down plot and the motion (.npz) into --out, and
prints whether the goal was reached and how close the pelvis came to an obstacle.

    python examples/astar_obstacles.py --out runs/astar
    python examples/astar_obstacles.py --random-model --max-steps 20 --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass
from motion_env.envs.arena import obstacle_distance
from policies import AStarPolicy


@dataclass
class Args(ExampleArgs):
    out: str = "runs/astar_obstacles"  # output folder
    text: str = "a person walks forward"  # caption
    goal_x: float = 1.0  # goal, world metres
    goal_z: float = 8.0
    max_steps: int = 600  # 30 s at 20 fps
    clearance: float = 0.6  # how far the planned pelvis path keeps from obstacles (m)
    lookahead: float = 1.0  # carrot distance along the plan (m)


# Circles (x, z, radius) between the start (origin, facing +Z) and the goal.
OBSTACLES = np.array([[0.0, 3.0, 1.0], [2.2, 5.6, 0.8], [-0.2, 6.6, 0.6]])


def main(args: Args) -> dict:
    _, generator = args.setup()  # the outputs go to args.out (write_outputs)

    goal = np.array([args.goal_x, args.goal_z])
    env = gym.make(
        "motion_env/Waypoints-v0", generator=generator, obstacles=OBSTACLES, max_episode_steps=args.max_steps,
        action_mode="absolute", frames_per_step=1,  # world points, one frame per planning step
    )  # fmt: skip
    policy = AStarPolicy(goal=goal, obstacles=[tuple(o) for o in OBSTACLES],
                         clearance=args.clearance, lookahead=args.lookahead)  # fmt: skip
    obs, info = env.reset(seed=args.seed, options={"text": args.text, "waypoints": [goal]})
    policy.reset()

    # Roll out: the planner reads the pelvis position from the observation and returns a carrot.
    frames, carrots = [info["joints"]], []
    terminated = truncated = False
    while not (terminated or truncated):
        action = policy.act(obs)
        carrots.append(action)
        obs, reward, terminated, truncated, info = env.step(action)
        frames.append(info["joints"])
    env.close()

    joints = np.stack(frames)
    joint_steps = np.linalg.norm(np.diff(joints, axis=0), axis=-1)  # (T-1, 22) metres per frame
    pelvis = joints[:, 0, [0, 2]]
    clearance = obstacle_distance(pelvis, [tuple(o) for o in OBSTACLES])
    result = {
        "reached_goal": bool(terminated),
        "final_distance_m": float(np.linalg.norm(pelvis[-1] - goal)),
        "min_obstacle_clearance_m": float(clearance.min()),
        "pelvis_inside_obstacle_frames": int((clearance < 0).sum()),
        "frames": int(len(joints)),
        "max_joint_step_m": float(joint_steps.max()) if joint_steps.size else 0.0,
    }

    motion = motion_env.Motion(
        joints, text=args.text, waypoints=goal[None], meta={"example": "astar_obstacles"}
    )
    args.write_outputs(
        motion, "astar_obstacles", result, f"A* around obstacles: {args.text}", obstacles=OBSTACLES
    )
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
