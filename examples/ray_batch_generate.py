"""Generate many clips with Ray Data: a table of (caption, route, seed) rows in, one .npz per clip out.

The table is a CSV with the columns `caption`, `route` ("x,z;x,z;..." in world metres, as the
command line's --waypoints; "x,z,t" for a timed waypoint) and `seed` (--table FILE), or one of
--num-clips rows drawn here: captions from a short list, random walks of 2 to 4 waypoints. Ray Data
cuts it into batches of --batch-size rows and sends them to --num-actors actors; each actor loads the
generator once and turns a batch into clips with one `MotionGenerator.generate_batch` call per seed
(character b of a call draws from (seed, b); the seed and b are kept in each clip's meta and in the
summary). Every clip is written as `clips/clip_NNNNN.npz` (`Motion.save`), and `summary.json`
lists them with the run's timing.

Past one machine (recipe: docs/scaling.md): Ray 2.60 joins nodes with token authentication. On
the head, `export RAY_AUTH_MODE=token; ray get-auth-token --generate; ray start --head`; on each
other machine (this package installed), `export RAY_AUTH_MODE=token RAY_AUTH_TOKEN=<head's token>;
ray start --address=HEAD:6379`; put --out on storage that every machine sees and run this with
RAY_AUTH_MODE=token and `--ray-address auto`; the actors are then spread over the machines.

Needs the optional extra, in a venv of its own, from the repository root, as docs/scaling.md:
pip install -c constraints.txt -e ".[ray]" pytest

    python examples/ray_batch_generate.py --out runs/ray_batch --num-clips 64
    python examples/ray_batch_generate.py --random-model --num-clips 6 --batch-size 2 \\
        --num-frames 20 --out /tmp/smoke   # smoke test
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.args import ExampleArgs, parse_dataclass, parse_waypoints, require, write_json

CAPTIONS = (
    "a person walks forward",
    "a person jogs",
    "a person walks slowly",
    "a person runs",
    "a person walks and waves with the right hand",
    "a person walks happily",
)


@dataclass
class Args(ExampleArgs):
    out: str = "runs/ray_batch"  # output folder (clips/ and summary.json)
    table: str = ""  # CSV with columns caption, route, seed; empty = draw --num-clips rows here
    num_clips: int = 32  # rows drawn when there is no --table
    num_frames: int = 200  # frames per clip (20 fps)
    batch_size: int = 8  # rows per generate_batch call
    num_actors: int = 2  # generator actors (each loads the model once)
    ray_address: str = ""  # "": Ray here; "auto": join the cluster (RAY_AUTH_MODE=token, docs/scaling.md)


def random_table(args: Args) -> list[dict[str, Any]]:
    """--num-clips rows: a caption from CAPTIONS, a walk of 2-4 untimed waypoints from the origin
    (legs of 1.5-3.5 m, turns up to 90 degrees), and one seed per --batch-size rows."""
    rng = np.random.default_rng(args.seed)
    rows = []
    for i in range(args.num_clips):
        heading, point, route = 0.0, np.zeros(2), []
        for _ in range(int(rng.integers(2, 5))):
            heading += rng.uniform(-np.pi / 2, np.pi / 2)
            point = point + rng.uniform(1.5, 3.5) * np.array([np.sin(heading), np.cos(heading)])
            route.append(f"{point[0]:.2f},{point[1]:.2f}")
        caption = CAPTIONS[int(rng.integers(len(CAPTIONS)))]
        rows.append({"caption": caption, "route": ";".join(route), "seed": args.seed + i // args.batch_size})
    return rows


def read_table(path: str) -> list[dict[str, Any]]:
    """The rows of a CSV with the columns caption, route and seed (checked here, before Ray starts)."""
    import csv

    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    missing = {"caption", "route", "seed"} - set(rows[0] if rows else {})
    if missing:
        raise SystemExit(f"{path}: no rows, or no column {sorted(missing)} (need caption, route, seed)")
    for k, row in enumerate(rows):
        parse_waypoints(row["route"], f"{path} row {k} route")  # a bad route fails here, not in an actor
    return [{"caption": r["caption"], "route": r["route"], "seed": int(r["seed"])} for r in rows]


class GenerateClips:
    """Ray Data's callable-class UDF: the generator is loaded once per actor, in ``__init__``."""

    def __init__(self, model: str, out: str, num_frames: int, threads: int) -> None:
        import torch

        from motion_env.generation.generator import MotionGenerator

        torch.set_num_threads(threads)
        self.generator = MotionGenerator.from_pretrained(model or None)
        self.out = Path(out)
        self.num_frames = num_frames

    def __call__(self, batch: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """A batch of rows (columns ``id``, ``caption``, ``route``, ``seed``) -> the clips' records."""
        routes = [np.array(parse_waypoints(str(r), "route"), np.float32) for r in batch["route"]]
        files, rows, seconds = [""] * len(routes), np.zeros(len(routes), np.int64), np.zeros(len(routes))
        for seed in dict.fromkeys(int(s) for s in batch["seed"]):  # the batch's seeds, in order
            index = np.nonzero(batch["seed"] == seed)[0]
            start = time.perf_counter()
            motions = self.generator.generate_batch(
                [str(batch["caption"][i]) for i in index], [routes[i] for i in index], self.num_frames, seed
            )
            seconds[index] = (time.perf_counter() - start) / len(index)
            for b, (i, motion) in enumerate(zip(index, motions)):
                motion.meta["clip_id"] = str(batch["id"][i])
                files[i] = str(motion.save(self.out / "clips" / f"clip_{int(batch['id'][i]):05d}.npz"))
                rows[i] = b
        return {**batch, "file": np.array(files), "row": rows, "seconds": seconds}


def main(args: Args) -> dict:
    ray = require("ray", "ray")  # the optional extra
    require("ray.data", "ray")
    for name in ("num_clips", "num_frames", "batch_size", "num_actors", "threads"):
        if getattr(args, name) < 1:
            raise SystemExit(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    rows = read_table(args.table) if args.table else random_table(args)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    env_vars = {"OMP_NUM_THREADS": str(args.threads), "HF_HUB_OFFLINE": os.environ.get("HF_HUB_OFFLINE", "1")}
    if args.ray_address:
        ray.init(address=args.ray_address, runtime_env={"env_vars": env_vars})
    else:  # every actor asks for one CPU: give Ray enough to start them all here
        cpus = max(os.cpu_count() or 1, args.num_actors)
        ray.init(num_cpus=cpus, include_dashboard=False, runtime_env={"env_vars": env_vars})

    start = time.perf_counter()
    records = (
        ray.data.from_items([{"id": i, **row} for i, row in enumerate(rows)])  # id: the row in the table
        .map_batches(
            GenerateClips,
            fn_constructor_kwargs=dict(
                model="random" if args.random_model else args.model,
                out=str(out.resolve()),
                num_frames=args.num_frames,
                threads=args.threads,
            ),
            batch_size=args.batch_size,
            batch_format="numpy",
            compute=ray.data.ActorPoolStrategy(size=args.num_actors),
            num_cpus=1,
        )
        .take_all()
    )
    wall = time.perf_counter() - start
    ray.shutdown()

    clips = sorted(
        (
            {
                "id": int(r["id"]),
                "caption": str(r["caption"]),
                "route": str(r["route"]),
                "seed": int(r["seed"]),
                "row": int(r["row"]),
                "file": str(Path(r["file"]).relative_to(out.resolve())),
            }
            for r in records
        ),
        key=lambda c: c["id"],
    )
    result = dict(
        num_clips=len(clips),
        num_frames=args.num_frames,
        wall_seconds=round(wall, 2),
        clips_per_second=round(len(clips) / wall, 3),
        generate_seconds_per_clip=float(np.mean([r["seconds"] for r in records])) if records else 0.0,
        versions={"ray": ray.__version__},
    )
    print(f"{len(clips)} clips of {args.num_frames} frames in {wall:.1f} s ({args.num_actors} actors)")
    write_json(out / "summary.json", {"args": asdict(args), **result, "clips": clips})
    return result


if __name__ == "__main__":
    main(parse_dataclass(Args, description=__doc__))
