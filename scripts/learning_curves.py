"""Learning curves of stable-baselines3 agents on the motion_env environments (success vs steps).

Trains with SB3's default hyperparameters unless told otherwise, on the native vector env
(:func:`motion_env.make_sb3_env`), and records every training episode's outcome (``is_success``
of its last step) against the env steps taken so far; at the end the trained policy runs
``--eval-episodes`` fresh episodes deterministically. Writes ``<out>/<name>.json``; ``--plot``
draws every JSON in ``<out>`` into ``<out>/learning_curves.png``.

    python scripts/learning_curves.py --name ppo_default --timesteps 60000 --num-envs 16
    python scripts/learning_curves.py --name ppo_steer --timesteps 60000 --env-kwargs follow_action=False
    python scripts/learning_curves.py --algo sac_her --env-id motion_env/GoalReach-v0 --num-envs 1 \\
        --timesteps 15000 --name sac_her
    python scripts/learning_curves.py --plot --out runs/curves
"""

from __future__ import annotations

import ast
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from motion_env.args import parse_dataclass, require, write_json

ALGOS = ("ppo", "sac_her")


@dataclass
class Args:
    name: str = "ppo_default"  # the run's name (its JSON file and its label on the plot)
    algo: str = "ppo"  # "ppo" (on the vector env) or "sac_her" (GoalReach, SB3's HerReplayBuffer)
    env_id: str = "motion_env/Waypoints-v0"
    num_envs: int = 16
    timesteps: int = 60_000  # env steps in all (summed over the envs)
    env_kwargs: str = ""  # extra env arguments "name=value,name=value" (Python literals)
    algo_kwargs: str = ""  # hyperparameters that differ from SB3's defaults, "n_steps=128,..."
    eval_episodes: int = 100  # deterministic episodes of the trained policy
    seed: int = 0
    model: str = ""  # model folder ("" = the shipped model)
    random_model: bool = False  # the untrained test model (smoke tests)
    out: str = "runs/curves"
    plot: bool = False  # only draw the curves of <out>/*.json


def parse_env_kwargs(text: str) -> dict[str, Any]:  # also reads --algo-kwargs
    """ "a=1,b=False" -> {"a": 1, "b": False} (values are Python literals)."""
    out: dict[str, Any] = {}
    for part in filter(None, (p.strip() for p in text.split(","))):
        name, sep, value = part.partition("=")
        if not sep or not name.strip():
            raise ValueError(f"--env-kwargs entries must be name=value, got {part!r}")
        try:
            out[name.strip()] = ast.literal_eval(value.strip())
        except (ValueError, SyntaxError):
            out[name.strip()] = value.strip()
    return out


def _callback(sb3: Any, log: list[tuple[int, bool]]) -> Any:
    """An SB3 callback that appends (steps so far, success) at the end of every training episode."""

    class EpisodeLog(sb3.common.callbacks.BaseCallback):
        def _on_step(self) -> bool:
            for done, info in zip(self.locals["dones"], self.locals["infos"]):
                if done:
                    log.append((int(self.num_timesteps), bool(info.get("is_success", False))))
            return True

    return EpisodeLog()


def evaluate(model: Any, env: Any, episodes: int) -> float:
    """Share of `episodes` fresh episodes the deterministic policy finishes (vector env, SB3 API)."""
    done_count, successes = 0, 0
    obs = env.reset()
    while done_count < episodes:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, dones, infos = env.step(action)
        for done, info in zip(dones, infos):
            if done and done_count < episodes:
                done_count += 1
                successes += bool(info.get("is_success", False))
    return successes / episodes


def train(args: Args) -> dict[str, Any]:
    sb3 = require("stable_baselines3", "rl")
    import stable_baselines3.common.callbacks  # noqa: F401  (sb3.common.callbacks below)

    import motion_env
    from motion_env.generation.generator import RANDOM_MODEL, MotionGenerator

    if args.algo not in ALGOS:
        raise ValueError(f"--algo must be one of {ALGOS}, got {args.algo!r}")
    torch.set_num_threads(1)
    generator = MotionGenerator.from_pretrained(RANDOM_MODEL if args.random_model else (args.model or None))
    kwargs = {"generator": generator, **parse_env_kwargs(args.env_kwargs)}
    hyper = parse_env_kwargs(args.algo_kwargs)
    log: list[tuple[int, bool]] = []
    start = time.perf_counter()
    env = motion_env.make_sb3_env(args.env_id, args.num_envs, **kwargs)
    env.seed(args.seed)
    if args.algo == "ppo":
        model = sb3.PPO("MultiInputPolicy", env, seed=args.seed, device="cpu", **hyper)
    else:
        model = sb3.SAC(
            "MultiInputPolicy",
            env,
            replay_buffer_class=sb3.HerReplayBuffer,
            replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
            seed=args.seed,
            device="cpu",
            **{"learning_starts": 500, **hyper},
        )
    model.learn(total_timesteps=args.timesteps, callback=_callback(sb3, log), progress_bar=True)
    train_s = time.perf_counter() - start
    eval_env = motion_env.make_sb3_env(args.env_id, args.num_envs, **kwargs)
    eval_env.seed(args.seed + 10_000)  # routes and captions the training never drew with this seed
    success = evaluate(model, eval_env, args.eval_episodes)
    settings = {k: v for k, v in kwargs.items() if k != "generator"}
    return {
        "name": args.name,
        "algo": args.algo,
        "env_id": args.env_id,
        "num_envs": args.num_envs,
        "env_kwargs": {k: repr(v) for k, v in settings.items()},
        "algo_kwargs": {k: repr(v) for k, v in hyper.items()},
        "timesteps": args.timesteps,
        "train_seconds": round(train_s, 1),
        "episodes": [[steps, int(ok)] for steps, ok in log],
        "eval_success": success,
        "eval_episodes": args.eval_episodes,
        "model": generator.name,
        "args": asdict(args),
    }


def success_curve(episodes: np.ndarray, window: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """(steps, success rate over the last `window` episodes) at each episode's end."""
    steps, ok = episodes[:, 0], episodes[:, 1].astype(np.float64)
    csum = np.concatenate([[0.0], np.cumsum(ok)])
    idx = np.arange(1, len(ok) + 1)
    lo = np.maximum(idx - window, 0)
    return steps, (csum[idx] - csum[lo]) / (idx - lo)


def plot(out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [json.loads(p.read_text()) for p in sorted(out.glob("*.json"))]
    runs = [r for r in runs if r.get("episodes")]
    if not runs:
        raise FileNotFoundError(f"no learning-curve JSON files in {out}")
    fig, ax = plt.subplots(figsize=(7, 4), dpi=100)
    for run in runs:
        steps, rate = success_curve(np.asarray(run["episodes"]))
        label = f"{run['name']} (eval {run['eval_success']:.0%})"
        ax.plot(steps, rate, label=label)
    ax.axhline(0.9, color="gray", lw=0.8, ls="--")
    ax.set_xlabel("env steps")
    ax.set_ylabel("success (last 100 training episodes)")
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    path = out / "learning_curves.png"
    fig.savefig(path)
    plt.close(fig)
    return path


def main(args: Args) -> dict[str, Any] | Path:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.plot:
        path = plot(out)
        print(f"wrote {path}")
        return path
    result = train(args)
    write_json(out / f"{args.name}.json", result)
    print(f"{args.name}: eval success {result['eval_success']:.2f} after {args.timesteps} steps "
          f"({result['train_seconds']:.0f} s)")  # fmt: skip
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
