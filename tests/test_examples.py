"""Smoke tests of examples/: each runs top to bottom with the random model and tiny settings.

They check that every example writes its video, top-down plot, motion and result; the walking
quality of the examples is a property of the shipped model (see test_envs.py's slow tests).
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

import motion_env
from motion_env.args import parse_dataclass

os.environ.setdefault("HF_HUB_OFFLINE", "1")
torch.set_num_threads(1)
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
COMMON = ["--random-model", "--video", "gif", "--width", "96", "--height", "64"]


def _load(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module


def _run(name: str, out: Path, *flags: str) -> dict:
    module = _load(name)
    result = module.main(parse_dataclass(module.Args, [*COMMON, "--out", str(out), *flags]))
    assert (out / "result.json").is_file()
    assert json.loads((out / "result.json").read_text())["args"]["random_model"] is True
    return result


def _check_outputs(out: Path, stem: str) -> motion_env.Motion:
    assert (out / f"{stem}.gif").stat().st_size > 0
    assert (out / f"{stem}.png").stat().st_size > 0
    return motion_env.Motion.load(out / f"{stem}.npz")


def test_astar_obstacles(tmp_path):
    result = _run("astar_obstacles", tmp_path, "--max-steps", "12")
    motion = _check_outputs(tmp_path, "astar_obstacles")
    assert motion.num_frames == result["frames"] == 13
    assert "min_obstacle_clearance_m" in result


def test_waypoints_demo(tmp_path):
    result = _run("waypoints_demo", tmp_path, "--max-steps", "12", "--route", "0,2;1,3,40")
    motion = _check_outputs(tmp_path, "waypoints_demo")
    assert motion.num_frames == 13 and motion.waypoints.shape == (2, 3)
    assert len(result["waypoint_errors_m"]) == 2


def test_edit_path_midrollout(tmp_path):
    result = _run(
        "edit_path_midrollout", tmp_path,
        "--max-steps", "16", "--text-step", "3", "--path-step", "6", "--text2-step", "10",
    )  # fmt: skip
    _check_outputs(tmp_path, "edit_path_midrollout")
    assert sorted(result["edits_at_frame"].values()) == [3, 6, 10]


# The two RL examples (the optional "rl" extra): a few steps of training, then the evaluation rollout.
RL_EXAMPLES = {
    "sb3_ppo": (["--total-timesteps", "32", "--n-steps", "8", "--num-envs", "2", "--episode-steps", "10"],
                "ppo_waypoints.zip"),
    "goal_reach_her": (["--total-timesteps", "24", "--learning-starts", "12", "--episode-steps", "6"],
                       "sac_her_goal_reach.zip"),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(RL_EXAMPLES))
def test_rl_examples(tmp_path, name):
    pytest.importorskip("stable_baselines3", reason="the optional 'rl' extra is not installed")
    flags, model_file = RL_EXAMPLES[name]
    result = _run(name, tmp_path, *flags, "--batch-size", "8", "--frames-per-step", "2", "--eval-steps", "5")
    motion = _check_outputs(tmp_path, f"{name}_eval")
    assert motion.num_frames == 1 + 5 * 2 and result["eval_frames"] == motion.num_frames
    assert (tmp_path / model_file).is_file()
    assert (
        np.isfinite(result["eval_return"]) if name == "sb3_ppo" else isinstance(result["eval_success"], bool)
    )


# The two Ray examples (the optional "ray" extra, best in its own venv: Ray pins gymnasium). They run
# as scripts, as documented: Ray pickles the examples' callbacks and classes by value only from
# __main__, and each run starts and stops its own local Ray instance.
NO_RAY = "the optional 'ray' extra is not installed (pip install -c constraints.txt -e \".[ray]\")"


def _run_script(name: str, out: Path, *flags: str) -> None:
    command = [sys.executable, str(EXAMPLES / f"{name}.py"), "--random-model", "--out", str(out), *flags]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{name} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"


def test_rllib_ppo_example(tmp_path):
    pytest.importorskip("ray.rllib", reason=NO_RAY)
    _run_script(
        "rllib_ppo", tmp_path, "--video", "gif", "--width", "96", "--height", "64",
        "--iterations", "2", "--num-env-runners", "2", "--num-envs-per-env-runner", "2",
        "--train-batch-size", "48", "--minibatch-size", "24", "--num-epochs", "1",
        "--episode-steps", "8", "--frames-per-step", "2", "--eval-steps", "5",
    )  # fmt: skip
    result = json.loads((tmp_path / "result.json").read_text())
    assert result["args"]["random_model"] is True
    history = result["history"]
    assert [row["iteration"] for row in history] == [1, 2]
    assert history[-1]["env_steps"] >= 2 * 48  # both iterations sampled a full train batch
    assert np.isfinite(history[-1]["episode_return_mean"])  # 8-step episodes ended in every batch
    assert 0.0 <= history[-1]["success_rate"] <= 1.0
    assert (tmp_path / "checkpoint" / "learner_group").is_dir()
    motion = _check_outputs(tmp_path, "rllib_ppo_eval")
    assert motion.num_frames == 1 + 5 * 2 == result["eval_frames"]
    assert np.isfinite(result["eval_return"])


def test_ray_batch_generate_example(tmp_path):
    pytest.importorskip("ray.data", reason=NO_RAY)
    _run_script(
        "ray_batch_generate", tmp_path,
        "--num-clips", "5", "--batch-size", "2", "--num-actors", "2", "--num-frames", "12",
    )  # fmt: skip
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["num_clips"] == 5 and [c["id"] for c in summary["clips"]] == list(range(5))
    for clip in summary["clips"]:
        motion = motion_env.Motion.load(tmp_path / clip["file"])
        assert motion.joints.shape == (12, 22, 3) and motion.text == clip["caption"]
        assert motion.meta["seed"] == str(clip["seed"]) and motion.meta["row"] == str(clip["row"])
        route = np.array(motion_env.args.parse_waypoints(clip["route"]))[:, :2]
        assert np.allclose(motion.waypoints[:, :2], route)


def test_ray_batch_generate_checks_its_table_before_starting_ray(tmp_path):
    pytest.importorskip("ray.data", reason=NO_RAY)
    table = tmp_path / "jobs.csv"
    table.write_text('caption,route,seed\na person walks,"0,2;1,x",0\n')
    module = _load("ray_batch_generate")
    with pytest.raises(ValueError, match="row 0 route item 1"):
        module.main(parse_dataclass(module.Args, ["--table", str(table), "--out", str(tmp_path / "out")]))


@pytest.mark.parametrize("name", ["rllib_ppo", "ray_batch_generate"])
def test_ray_examples_say_how_to_install_ray_when_it_is_missing(tmp_path, name):
    if importlib.util.find_spec("ray") is not None:
        pytest.skip("ray is installed: nothing is missing")
    module = _load(name)
    with pytest.raises(SystemExit, match=r'-e "\.\[ray\]"'):
        module.main(parse_dataclass(module.Args, ["--random-model", "--out", str(tmp_path)]))


@pytest.mark.slow
def test_astar_example_reaches_its_goal_around_the_obstacles_with_the_shipped_model(
    tmp_path, pretrained_generator
):
    module = _load("astar_obstacles")
    flags = ["--video", "gif", "--width", "96", "--height", "64", "--out", str(tmp_path)]
    result = module.main(parse_dataclass(module.Args, flags))
    assert result["reached_goal"] and result["final_distance_m"] < 0.75
    assert result["pelvis_inside_obstacle_frames"] == 0 and result["min_obstacle_clearance_m"] > 0.0
