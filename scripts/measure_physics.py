"""Does the physics stage make generated motion physically plausible? Before/after, clip by clip.

Generates runs, jogs and walks with the shipped model, keeps each clip's decoded foot contacts,
and applies :func:`motion_env.generation.physics.apply_physics` (whole clips) and
:class:`~motion_env.generation.physics.PhysicsFilter` (the stream's causal version, fed one token
at a time) to the feet stage's output. For each version it prints the share of clips the MuJoCo
replay judges plausible (and the checks that fail), the foot skating ratio, the p99 joint
acceleration and the root error at the timed waypoints. With --real it also runs the stage on
real Bandai Namco runs and walks (contacts from their joints, as the training features have them),
which should stay plausible.

    python scripts/measure_physics.py --seeds 10 --cache /tmp/physics_clips
    python scripts/measure_physics.py --seeds 10 --cache /tmp/physics_clips --untimed
    python scripts/measure_physics.py --seeds 0 --real ../shared/data

Generated clips are cached in --cache (one .npz per clip), so a second run only measures.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from motion_env.evaluation.metrics import foot_skating_ratio, joint_acceleration
from motion_env.generation.physics import PhysicsFilter, apply_physics
from motion_env.motion.skeleton import FOOT_CONTACT, FPS
from motion_env.motion.trajectory import waypoint_errors
from motion_env.motion.types import Motion

# Timed routes whose last waypoint lies past the clip's end (the path controller stops at a
# route's end); --untimed drops the times (the controller paces itself).
CASES: tuple[tuple[str, list[list[float]]], ...] = (
    ("a person runs", [[0, 6, 40], [0, 12, 80], [0, 18, 120], [0, 24, 160], [0, 36, 240]]),
    ("a person jogs", [[0, 5, 40], [0, 10, 80], [0, 15, 120], [0, 20, 160], [0, 30, 240]]),
    ("a person walks", [[0, 3, 60], [0, 6, 120], [0, 9, 180], [0, 12, 240]]),
    ("an elderly person walks slowly", [[0, 2, 60], [1, 4, 140], [2.25, 6.5, 240]]),
)
VERSIONS = ("before", "whole", "stream")
REAL_TAKES = ("run", "walk")  # Bandai Namco dataset-2 contents
REAL_STRIDE = 20  # every n-th take of each content


@dataclass
class Args:
    seeds: int
    untimed: bool
    frames: int
    cache: Path
    rate: int
    real: Path | None
    json: Path | None


def parse_args() -> Args:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seeds", type=int, default=10, help="clips per caption")
    parser.add_argument("--untimed", action="store_true", help="routes without times")
    parser.add_argument("--frames", type=int, default=200, help="frames per clip (20 fps)")
    parser.add_argument("--cache", type=Path, default=Path("physics_clips"), help="folder of generated clips")
    parser.add_argument("--rate", type=int, default=4, help="frames per token of the causal version")
    parser.add_argument("--real", type=Path, default=None, help="data folder with bandai/: real takes too")
    parser.add_argument("--json", type=Path, default=None, help="also write the per-clip numbers here")
    ns = parser.parse_args()
    return Args(ns.seeds, ns.untimed, ns.frames, ns.cache, ns.rate, ns.real, ns.json)


def cases(untimed: bool) -> list[tuple[str, list[list[float]]]]:
    """The captions and their routes (without times when `untimed`)."""
    return [(text, [w[:2] for w in route] if untimed else route) for text, route in CASES]


def generate(args: Args) -> list[Path]:
    """Generate (or find in the cache) every clip: joints after the feet stage and contacts."""
    kind = "untimed" if args.untimed else "timed"
    jobs = [(text, wps, seed) for text, wps in cases(args.untimed) for seed in range(args.seeds)]
    files = [args.cache / f"{text.replace(' ', '_')}_{kind}_{seed}.npz" for text, _, seed in jobs]
    if all(f.is_file() for f in files):
        return files
    import torch

    from motion_env.generation.generator import MotionGenerator
    from motion_env.generation.request import check_request

    torch.set_num_threads(1)
    torch.set_grad_enabled(False)
    pipe = MotionGenerator.from_pretrained().pipeline
    args.cache.mkdir(parents=True, exist_ok=True)
    for (text, wps, seed), path in tqdm(list(zip(jobs, files)), desc="generate", unit="clip"):
        if path.is_file():
            continue
        # The stages of Pipeline.clips for one clip without joint targets, keeping the contacts.
        req = check_request(text, wps, args.frames, seed, None)
        emb = pipe.encode_text(req.texts)
        _, paths = pipe.plan_paths(emb, req)
        n_tok = math.ceil(req.num_frames / pipe.rate)
        body = pipe.decode(pipe.sample_tokens(emb, paths, n_tok, req.seed))
        _, joints = pipe.place_clip(body[0], paths[0], n_tok * pipe.rate)
        np.savez(
            path,
            joints=joints[: args.frames],
            contacts=body[0, : args.frames, FOOT_CONTACT],
            waypoints=np.asarray(wps, np.float32),
            text=text,
            seed=seed,
        )
    return files


def real_takes(data: Path) -> list[dict]:
    """Real runs and walks: joints and the contacts the training features give them."""
    from motion_env.io.bvh import load_bvh
    from motion_env.motion.features import joints_to_features

    clips = []
    for content in REAL_TAKES:
        for path in sorted((data / "bandai" / "dataset-2" / "bvh").glob(f"*_{content}_*"))[::REAL_STRIDE]:
            joints = load_bvh(path).joints
            contacts = joints_to_features(joints)[:, FOOT_CONTACT]
            text = f"real {content} (Bandai Namco)"
            clips.append({"text": text, "joints": joints[: len(contacts)], "contacts": contacts})
    return clips


def streamed(joints: np.ndarray, contacts: np.ndarray, rate: int) -> np.ndarray:
    """The causal version, fed one token (`rate` frames) at a time, as the stream does."""
    stage = PhysicsFilter(1)
    parts = [
        stage.apply(0, joints[f : f + rate], contacts[f : f + rate]) for f in range(0, len(joints), rate)
    ]
    return np.concatenate(parts)


def measure(joints: np.ndarray, waypoints: np.ndarray) -> dict:
    """Replay verdict, skating, acceleration and root error of one clip."""
    from motion_env.replay import evaluate

    report = evaluate(Motion(joints=joints, fps=FPS))
    timed = waypoints[waypoints[:, 2] < len(joints)] if waypoints.shape[1] == 3 else waypoints[:0]
    errors = waypoint_errors(joints[:, 0, [0, 2]], timed) if len(timed) else np.zeros(1)
    return {
        "plausible": bool(report["plausible"]),
        "failed": report["failed"],
        "values": {name: c["value"] for name, c in report["checks"].items()},
        "skating": foot_skating_ratio(joints),
        "accel_p99": float(np.percentile(joint_acceleration(joints), 99)),
        "root_error_cm": float(100 * errors.max()),
    }


def summary(rows: list[dict], version: str, text: str | None = None) -> str:
    """One line per version and caption: plausible share, failed checks, the other metrics."""
    sel = [r[version] for r in rows if text is None or r["text"] == text]
    fails = Counter(name for r in sel for name in r["failed"])
    worst = {k: max(r["values"][k] for r in sel) for k in ("root_force", "root_torque", "penetration")}
    return (
        f"{version:6s} plausible {sum(r['plausible'] for r in sel):2d}/{len(sel)}  "
        f"skating {np.mean([r['skating'] for r in sel]):.3f}  "
        f"accel p99 {np.mean([r['accel_p99'] for r in sel]):5.1f} m/s^2  "
        f"root err max {max(r['root_error_cm'] for r in sel):.2f} cm  "
        f"worst force {worst['root_force']:.1f} N/kg torque {worst['root_torque']:.1f} N m/kg "
        f"penetration {100 * worst['penetration']:.1f} cm  failed {dict(fails)}"
    )


def main() -> None:
    args = parse_args()
    clips = []
    for path in generate(args):
        clip = np.load(path)
        clips.append({k: clip[k] for k in ("joints", "contacts", "waypoints")} | {"text": str(clip["text"])})
    if args.real is not None:
        clips += real_takes(args.real)
    rows = []
    for clip in tqdm(clips, desc="measure", unit="clip"):
        joints, contacts = clip["joints"], clip["contacts"]
        wps = clip.get("waypoints", np.zeros((0, 3), np.float32))
        outputs = {
            "before": joints,
            "whole": apply_physics(joints, contacts),
            "stream": streamed(joints, contacts, args.rate),
        }
        rows.append({"text": clip["text"]} | {v: measure(outputs[v], wps) for v in VERSIONS})
    for text in dict.fromkeys(r["text"] for r in rows):
        print(text)
        for version in VERSIONS:
            print("  " + summary(rows, version, text))
    print("all")
    for version in VERSIONS:
        print("  " + summary(rows, version))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
