"""Follow a route of waypoints in motion_env/Waypoints-v0, one frame per step.

The route is given at reset; a policies.WaypointPolicy issues each waypoint in turn as the action,
which tells the env to keep following the route (an action at a route waypoint means "follow the
route from there"). Writes a video, a top-down plot and the motion (.npz) into --out and prints the
distance to each waypoint at its closest approach and the largest joint move between frames.

    python examples/waypoints_demo.py --out runs/waypoints
    python examples/waypoints_demo.py --text "a person jogs" --route "0,3;3,6;6,4"
    python examples/waypoints_demo.py --random-model --max-steps 20 --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass, parse_waypoints
from motion_env.motion.trajectory import waypoint_errors
from policies import WaypointPolicy


@dataclass
class Args(ExampleArgs):
    out: str = "runs/waypoints_demo"  # output folder
    text: str = "a person walks forward"  # caption
    route: str = "0,3;2.5,5.5;5,5;6,2"  # waypoints "x,z[,frame];..." in world metres
    max_steps: int = 800


def main(args: Args) -> dict:
    _, generator = args.setup()  # the outputs go to args.out (write_outputs)
    route = np.array(parse_waypoints(args.route, "--route"), np.float32)

    env = gym.make(
        "motion_env/Waypoints-v0", generator=generator, max_episode_steps=args.max_steps,
        action_mode="absolute", frames_per_step=1,  # the policy issues world points, every frame
    )  # fmt: skip
    obs, info = env.reset(seed=args.seed, options={"text": args.text, "waypoints": route})
    policy = WaypointPolicy(route, radius=env.unwrapped.config.arrive_radius)

    frames = [info["joints"]]
    total_reward, terminated, truncated = 0.0, False, False
    while not (terminated or truncated):
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
        frames.append(info["joints"])
        total_reward += reward
    env.close()

    joints = np.stack(frames)
    joint_steps = np.linalg.norm(np.diff(joints, axis=0), axis=-1)  # (T-1, 22) metres per frame
    errors = waypoint_errors(joints[:, 0, [0, 2]], route)
    result = {
        "reached_last_waypoint": bool(terminated),
        "frames": int(len(joints)),
        "final_distance_m": float(np.linalg.norm(joints[-1, 0, [0, 2]] - route[-1, :2])),
        "waypoint_errors_m": [round(float(e), 3) for e in errors],
        "max_joint_step_m": float(joint_steps.max()) if joint_steps.size else 0.0,
        "return": float(total_reward),
    }

    motion = motion_env.Motion(joints, text=args.text, waypoints=route, meta={"example": "waypoints_demo"})
    args.write_outputs(motion, "waypoints_demo", result)
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
