"""Train Ray RLlib PPO on motion_env/Waypoints-v0: several env runners, each a native vector env.

RLlib (new API stack) starts --num-env-runners sampling processes. Each builds its own
`WaypointsVectorEnv` of --num-envs-per-env-runner characters through Gymnasium's vector entry point
(`gym_env_vectorize_mode="vector_entry_point"`), so its characters still cost one batched generator
call per frame, and loads its own generator (`model_path` travels in `env_config`, not the model).
The env id is given as "motion_env:motion_env/Waypoints-v0": Gymnasium imports `motion_env`, which
registers the ids, inside every env runner. RLlib's `FlattenObservations` connector turns the Dict
observation into the vector its default network reads. One learner updates the policy from all
runners; every iteration prints the mean episode return and success rate. The example then saves an
RLlib checkpoint, walks one fixed route with the trained policy (deterministic) and writes that
rollout as a video, a top-down plot and a .npz, next to a random agent's return.

Past one machine (recipe: docs/scaling.md): Ray 2.60 joins nodes with token authentication. On
the head, `export RAY_AUTH_MODE=token; ray get-auth-token --generate; ray start --head`; on each
other machine (this package installed), `export RAY_AUTH_MODE=token RAY_AUTH_TOKEN=<head's token>;
ray start --address=HEAD:6379`; then run this with RAY_AUTH_MODE=token and `--ray-address auto`;
env runners are then placed across the machines.

Needs the optional extra (a separate venv is best: Ray pins its own gymnasium, 1.2.2 for Ray 2.60),
from the repository root, as docs/scaling.md: pip install -c constraints.txt -e ".[ray]" pytest

    python examples/rllib_ppo.py --out runs/rllib_ppo
    python examples/rllib_ppo.py --random-model --iterations 1 --num-envs-per-env-runner 2 \\
        --train-batch-size 64 --minibatch-size 32 --num-epochs 1 --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

import motion_env
from motion_env.args import ExampleArgs, parse_dataclass, parse_waypoints, require
from motion_env.evaluation.episode import run_episode

ENV_ID = "motion_env:motion_env/Waypoints-v0"  # "module:id": Gymnasium imports motion_env first


@dataclass
class Args(ExampleArgs):
    out: str = "runs/rllib_ppo"  # output folder
    iterations: int = 5  # PPO training iterations (each: one train batch, then the updates)
    num_env_runners: int = 2  # sampling processes (Ray actors), each with its own vector env
    num_envs_per_env_runner: int = 8  # characters per env runner (one batched generator call per frame)
    train_batch_size: int = 2000  # env steps per iteration, summed over the runners
    minibatch_size: int = 256  # PPO minibatch
    num_epochs: int = 10  # passes over each train batch
    learning_rate: float = 3e-4  # Adam step size
    frames_per_step: int = 4  # frames per decision (0.2 s at 20 fps), the env's default
    episode_steps: int = 150  # decisions per training episode (30 s), the registration's default
    eval_steps: int = 150  # decisions in the evaluation rollout
    eval_route: str = "0,3;3,5;5,2"  # the evaluation route "x,z;..." (world metres)
    text: str = "a person walks forward"  # caption of the evaluation rollout
    sample_timeout_s: float = 600.0  # how long to wait for a runner's share of a batch (RLlib's default: 60)
    ray_address: str = ""  # "": Ray here; "auto": join the cluster (RAY_AUTH_MODE=token, docs/scaling.md)


def log_success(episode: Any, metrics_logger: Any, **kwargs: Any) -> None:
    """RLlib episode-end callback: whether the character reached its route's last waypoint."""
    success = float(episode.get_infos(-1)["is_success"])
    metrics_logger.log_value("success_rate", success, reduce="mean", window=100)


def ppo_config(args: Args) -> Any:
    """The RLlib PPO configuration: env runners that each step one native vector env."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.connectors.env_to_module import FlattenObservations

    env_config = dict(
        model_path="random" if args.random_model else args.model or None,  # loaded in every runner
        frames_per_step=args.frames_per_step,
        max_episode_steps=args.episode_steps,
        # RLlib's env runner resets an ended episode on the next step (Gymnasium's default mode).
        autoreset_mode="next_step",
    )
    return (
        PPOConfig()
        .api_stack(enable_rl_module_and_learner=True, enable_env_runner_and_connector_v2=True)
        .environment(ENV_ID, env_config=env_config)
        .env_runners(
            num_env_runners=args.num_env_runners,
            num_envs_per_env_runner=args.num_envs_per_env_runner,
            gym_env_vectorize_mode="vector_entry_point",  # the env's own batched VectorEnv
            env_to_module_connector=lambda env, spaces, device: FlattenObservations(),
            # RLlib drops the samples of a runner slower than this: on a busy CPU with the shipped
            # model a runner's share of the batch can take minutes.
            sample_timeout_s=args.sample_timeout_s,
        )
        .training(
            train_batch_size_per_learner=args.train_batch_size,
            minibatch_size=args.minibatch_size,
            num_epochs=args.num_epochs,
            lr=args.learning_rate,
        )
        .callbacks(on_episode_end=log_success)
        .debugging(seed=args.seed)
    )


def load_module(checkpoint: str) -> Any:
    """The trained policy network (an RLModule) from an RLlib checkpoint folder."""
    from pathlib import Path

    from ray.rllib import core
    from ray.rllib.core.rl_module import RLModule

    # An algorithm checkpoint holds the learner's copy of every module under this path.
    parts = (core.COMPONENT_LEARNER_GROUP, core.COMPONENT_LEARNER, core.COMPONENT_RL_MODULE)
    return RLModule.from_checkpoint(Path(checkpoint).joinpath(*parts, core.DEFAULT_MODULE_ID))


def policy(module: Any, observation_space: gym.Space, action_space: gym.Space):
    """The trained module as a deterministic act(obs) for one env, with the pieces RLlib's
    connectors use (the same flattening of the Dict observation, the same action unsquashing)."""
    import torch
    from ray.rllib.utils.numpy import flatten_inputs_to_1d_tensor
    from ray.rllib.utils.spaces.space_utils import get_base_struct_from_space, unsquash_action

    obs_struct = get_base_struct_from_space(observation_space)
    dist_cls = module.get_inference_action_dist_cls()

    def act(obs: dict[str, np.ndarray]) -> np.ndarray:
        flat = flatten_inputs_to_1d_tensor(obs, spaces_struct=obs_struct, batch_axis=False)
        with torch.no_grad():
            out = module.forward_inference({"obs": torch.as_tensor(flat[None], dtype=torch.float32)})
        action = dist_cls.from_logits(out["action_dist_inputs"]).to_deterministic().sample()[0]
        return unsquash_action(action.numpy(), action_space).astype(np.float32)

    return act


def main(args: Args) -> dict:
    ray = require("ray", "ray")  # the optional extra
    require("ray.rllib", "ray")
    out, generator = args.setup()
    # Env runners inherit these: torch on --threads threads, no Hugging Face downloads.
    env_vars = {"OMP_NUM_THREADS": str(args.threads), "HF_HUB_OFFLINE": os.environ.get("HF_HUB_OFFLINE", "1")}
    if args.ray_address:
        ray.init(address=args.ray_address, runtime_env={"env_vars": env_vars})
    else:  # every env runner asks for one CPU: give Ray enough to start them all here
        cpus = max(os.cpu_count() or 1, args.num_env_runners)
        ray.init(num_cpus=cpus, include_dashboard=False, runtime_env={"env_vars": env_vars})

    start = time.perf_counter()
    algo = ppo_config(args).build_algo()
    print(f"RLlib PPO: {args.num_env_runners} env runners x {args.num_envs_per_env_runner} characters")
    history = []
    for i in range(args.iterations):
        runners = algo.train()["env_runners"]
        row = dict(
            iteration=i + 1,
            env_steps=int(runners.get("num_env_steps_sampled_lifetime", 0)),
            episode_return_mean=float(runners.get("episode_return_mean", np.nan)),
            success_rate=float(runners.get("success_rate", np.nan)),
            seconds=round(time.perf_counter() - start, 1),
        )
        history.append(row)
        print(
            f"iteration {row['iteration']}: {row['env_steps']} env steps, "
            f"return {row['episode_return_mean']:.2f}, success {row['success_rate']:.2f}, {row['seconds']} s"
        )
    checkpoint = algo.save_to_path(str((out / "checkpoint").resolve()))
    algo.stop()
    ray.shutdown()

    # Evaluate on a fixed route in this process: the trained policy, then a random agent.
    route = np.array(parse_waypoints(args.eval_route, "--eval-route"), np.float32)[:, :2]
    env = gym.make("motion_env/Waypoints-v0", generator=generator, max_episode_steps=args.eval_steps,
                   frames_per_step=args.frames_per_step)  # fmt: skip
    act = policy(load_module(checkpoint), env.observation_space, env.action_space)
    episode = {"text": args.text, "waypoints": route}
    ppo = run_episode(env, act, args.seed, episode)
    random_agent = run_episode(env, None, args.seed, episode)
    env.close()

    result = dict(
        history=history,
        train_seconds=history[-1]["seconds"] if history else 0.0,
        checkpoint=str(checkpoint),
        eval_return=ppo.total_return,
        random_agent_return=random_agent.total_return,
        eval_reached_last_waypoint=ppo.terminated,
        eval_frames=int(len(ppo.joints)),
        versions={"ray": ray.__version__, "gymnasium": gym.__version__},
    )
    motion = motion_env.Motion(ppo.joints, text=args.text, waypoints=route, meta={"example": "rllib_ppo"})
    title = f"RLlib PPO, {args.iterations} iterations: {args.text}"
    args.write_outputs(motion, "rllib_ppo_eval", result, title)
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
