"""From a caption and a route to robot-ready reference motion: generate a clip with the shipped
model, retarget it onto the Unitree G1 and the Booster T1, and write each robot's qpos (.csv, one
row per frame) and a MuJoCo video of it.

Each robot gets the clip scaled to its size, its feet on the floor and every joint inside its
range (motion_env.retarget). The printed result says, per robot, how far the hands and feet ended
from their targets and the checks of scripts/evaluate_retarget.py (joint ranges, floor, jumps).
Needs the optional mink package: pip install -c constraints.txt -e ".[robots]".

    python examples/retarget_to_robot.py --out runs/retarget
    python examples/retarget_to_robot.py --text "a person jogs and waves" --route "0,3;2,6"
    python examples/retarget_to_robot.py --random-model --frames 12 --video gif --out /tmp/smoke  # smoke test
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass, parse_waypoints, require, write_json


@dataclass
class Args(ExampleArgs):
    out: str = "runs/retarget_to_robot"  # output folder
    text: str = "a person walks forward and waves with the right hand"  # caption
    route: str = "0,2;1.5,4"  # waypoints "x,z[,frame];..." in world metres
    frames: int = 160  # frames to generate (20 fps)
    robots: str = "unitree_g1,booster_t1"  # robot names or MJCF paths, comma-separated
    fps: float = 50.0  # frame rate of the robot motion


def main(args: Args) -> dict:
    require("mink", "robots")
    from motion_env.retarget.quality import measure
    from motion_env.retarget.video import render_robot_video

    out, generator = args.setup()
    route = np.array(parse_waypoints(args.route, "--route"), np.float32)
    motion = generator.generate(args.text, route, num_frames=args.frames, seed=args.seed)
    written = [motion.save(out / "human.npz")]

    result: dict = {"text": args.text, "human_frames": motion.num_frames, "robots": {}}
    for robot in (name.strip() for name in args.robots.split(",") if name.strip()):
        robot_motion = motion_env.retarget(motion, robot=robot, fps=args.fps)
        stem = Path(robot).stem  # a name, or the MJCF's file name
        written.append(robot_motion.save(out / f"{stem}.csv"))
        written.append(
            render_robot_video(
                robot_motion, out / f"{stem}.{args.video}", width=args.width, height=args.height
            )
        )
        numbers = measure(robot_motion, motion)  # ranges, floor, jumps, correlations, residuals
        result["robots"][stem] = {k: round(v, 3) if isinstance(v, float) else v for k, v in numbers.items()}

    print(json.dumps(result, indent=2))
    for path in written:
        print(f"wrote {path}")
    write_json(out / "result.json", {"args": asdict(args), **result})
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
