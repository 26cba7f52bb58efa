"""Change the caption and the path while the character walks (motion_env/Waypoints-v0).

The character starts walking a straight route north. At --text-step the caption changes
(env.unwrapped.set_text); at --path-step the agent changes its mind and steers through a new list of
points, issued as actions (each one a detour target that replaces the current one); at --text2-step
the caption changes again. The generator blends every edit into the ongoing motion, so poses stay
continuous: the example prints the largest joint move between consecutive frames around each edit
and overall. Writes a video (edit frames highlighted), a top-down plot and the motion into --out.

    python examples/edit_path_midrollout.py --out runs/edit
    python examples/edit_path_midrollout.py --random-model --max-steps 30 --text-step 5 \\
        --path-step 10 --text2-step 20 --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass
from policies import WaypointPolicy


@dataclass
class Args(ExampleArgs):
    out: str = "runs/edit_path_midrollout"  # output folder
    text: str = "a person walks forward"  # the first caption
    text2: str = "a person jogs forward"  # caption from --text-step on
    text3: str = "a person walks slowly"  # caption from --text2-step on
    text_step: int = 60  # steps (frames) before the first caption change
    path_step: int = 80  # the agent switches to the new points here (while still walking)
    text2_step: int = 150
    max_steps: int = 500


ROUTE = np.array([[0.0, 4.0], [0.0, 9.0]], np.float32)  # the route given at reset: straight north
NEW_POINTS = np.array([[-2.5, 6.0], [-4.0, 3.0], [-2.0, 0.5]], np.float32)  # the edited path


def max_step_near(joints: np.ndarray, frame: int, window: int = 10) -> float:
    """Largest joint move (m) between consecutive frames within `window` frames of `frame`."""
    lo, hi = max(frame - window, 0), min(frame + window, len(joints) - 1)
    if hi <= lo:
        return 0.0
    return float(np.linalg.norm(np.diff(joints[lo : hi + 1], axis=0), axis=-1).max())


def main(args: Args) -> dict:
    _, generator = args.setup()  # the outputs go to args.out (write_outputs)

    env = gym.make("motion_env/Waypoints-v0", generator=generator, terminate_on_arrival=False,
                   max_episode_steps=args.max_steps, action_mode="absolute", frames_per_step=1)  # fmt: skip
    obs, info = env.reset(seed=args.seed, options={"text": args.text, "waypoints": ROUTE})
    route_agent, new_agent = WaypointPolicy(ROUTE), WaypointPolicy(NEW_POINTS)
    radius = env.unwrapped.config.arrive_radius

    frames, edits, captions = [info["joints"]], {}, [args.text]
    truncated = False
    step = 0
    while not truncated:
        if step == args.text_step:
            env.unwrapped.set_text(args.text2)
            edits[f"caption -> {args.text2!r}"] = len(frames) - 1
        if step == args.text2_step:
            env.unwrapped.set_text(args.text3)
            edits[f"caption -> {args.text3!r}"] = len(frames) - 1
        if step == args.path_step:
            edits["path -> new points"] = len(frames) - 1
        agent = new_agent if step >= args.path_step else route_agent
        obs, reward, terminated, truncated, info = env.step(agent.act(obs))
        frames.append(info["joints"])
        captions.append(info["text"])
        step += 1
        # Done when the last of the new points is reached (the original route no longer matters).
        if step > args.path_step and np.linalg.norm(obs["root"][:2] - NEW_POINTS[-1]) < radius:
            break
    env.close()

    joints = np.stack(frames)
    joint_steps = np.linalg.norm(np.diff(joints, axis=0), axis=-1)  # (T-1, 22) metres per frame
    result = {
        "frames": int(len(joints)),
        "edits_at_frame": edits,
        "max_joint_step_near_edit_m": {name: round(max_step_near(joints, f), 4) for name, f in edits.items()},
        "max_joint_step_m": float(joint_steps.max()) if joint_steps.size else 0.0,
        "final_distance_to_last_point_m": float(np.linalg.norm(joints[-1, 0, [0, 2]] - NEW_POINTS[-1])),
    }

    title = f"{args.text} -> {args.text2} -> {args.text3}"
    points = np.concatenate([ROUTE, NEW_POINTS])
    motion = motion_env.Motion(joints, text=title, waypoints=points, meta={"example": "edit_path_midrollout"})
    args.write_outputs(motion, "edit_path_midrollout", result, "route 1-2, then edited path 3-5",
                       highlight_frames=sorted(edits.values()), highlight_label="edit")  # fmt: skip
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
