#!/usr/bin/env python
"""How smooth are VQ-VAE reconstructions of held-out takes, next to the takes themselves?

Encodes and decodes every clip of a split with each given VQ-VAE checkpoint, recovers world joints
from the features (:func:`motion_env.motion.features.features_to_joints`, for the real takes and
the reconstructions alike) and, per action (the Bandai label of the dataset's ``index.csv``;
labels with fewer than ``--min-clips`` clips are pooled as "other"), measures:

- ``acc_p99`` / ``jerk_p99``: the 99th percentile over joints and frames of |second / third
  finite difference| x fps^2 / fps^3 (m/s^2, m/s^3);
- ``hf_share``: the share of the acceleration energy (Hann-windowed spectrum of each joint axis,
  summed over the clips) at 5 Hz and above, 5 Hz being the token rate (4 frames per token at
  20 fps), so a decoder that ripples once per token shows up here; ``token_band`` is the energy in
  4.5-5.5 Hz per second of motion;
- ``wrist_flips``: sign changes per second of the wrists' vertical velocity (jitter);
- ``mpjpe_cm``: mean per-joint error of the reconstruction with the pelvis aligned per frame
  (``mpjpe_global_cm``: without, so the drift of the integrated root path counts);
- ``plausible``: for the actions of ``--replay``, the share of clips (of those long enough to
  judge) that the MuJoCo replay (:func:`motion_env.replay.evaluate`) finds plausible, and the
  checks that failed.

Reconstruction numbers are also given as ratios to the real takes'. With two or more checkpoints
it also checks that every clip gets the same tokens from each (it must when only the decoder was
fine-tuned). Prints a table per checkpoint and writes everything to ``--json``.

    python scripts/analyze_smoothness.py --checkpoints motion_env/weights/vqvae.pt,runs/vq_smooth.pt

With ``--stages ACTIONS`` it finds instead where the pops of generated clips come from: the
naturalness takes of those actions (:mod:`motion_env.evaluation.naturalness`, same choice, same
protocol) are made again by the shipped generator, and each clip is measured after every stage of
its placement: ``decoded`` (the decoded body relative to its root), ``pelvis_out`` and ``fitted``
(that body put on the skeleton's bone lengths by a rebuild from the pelvis outward along the
decoded bones, :func:`~motion_env.motion.kinematics.with_bone_lengths`, as the generator did
before, or by :func:`~motion_env.motion.kinematics.fit_bone_lengths`, as it does now),
``composed`` (on the path, on the bones, arms re-solved), ``feet`` (the foot pinning) and
``physics``. Per clip and stage: the largest joint acceleration, its joint and frame, and whether
it pops (over 1.5 x the real takes' p99.9, as ``eval natural``); the foot skating; per action,
each stage's acceleration p99 over the real takes' (the final one also without each clip's first
``--skip-frames`` frames, where clips start), and how far planted feet slide (cm per frame,
frames where the decoder marks both contacts of a foot).

    python scripts/analyze_smoothness.py --stages walk,walk-left,walk-right --split test
"""

from __future__ import annotations

import csv
import json
import time
from collections import defaultdict
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from motion_env.args import parse_dataclass, write_json
from motion_env.data.dataset import read_split
from motion_env.models.checkpoint import load_checkpoint
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE, VQVAEConfig
from motion_env.motion.features import features_to_joints
from motion_env.motion.skeleton import FPS, JOINT_INDEX

WRISTS = (JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"])
HF_CUTOFF_HZ = 5.0
TOKEN_BAND_HZ = (4.5, 5.5)


@dataclass
class Args:
    data: str = "data/mocap"  # HumanML3D-layout dataset with index.csv
    checkpoints: str = "motion_env/weights/vqvae.pt"  # comma-separated VQ-VAE checkpoints
    split: str = "val"  # the split whose clips are measured
    min_clips: int = 10  # labels with fewer clips are pooled as "other"
    replay: str = "run,walk"  # comma-separated actions whose clips are replayed in MuJoCo ("": none)
    threads: int = 1  # torch CPU threads
    json: str = "runs/smoothness.json"  # where the numbers go
    stages: str = ""  # comma-separated actions: attribute generated clips' pops to stages instead
    per_action: int = 7  # --stages: clips per action (the naturalness evaluation's choice)
    skip_frames: int = 8  # --stages: the final acceleration ratio also without each clip's first frames


# --- measures on one clip's world joints (T, 22, 3) ----------------------------------------


def _diff_norms(joints: np.ndarray, order: int) -> np.ndarray:
    """|order-th finite difference| x fps^order per joint and frame (flattened)."""
    d = np.diff(joints.astype(np.float64), n=order, axis=0) * FPS**order
    return np.linalg.norm(d, axis=-1).ravel()


def _acc_spectrum(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies, power per frequency summed over joint axes) of the acceleration."""
    acc = np.diff(joints.astype(np.float64), n=2, axis=0).reshape(len(joints) - 2, -1) * FPS**2
    window = np.hanning(len(acc))[:, None]
    power = np.abs(np.fft.rfft(acc * window, axis=0)) ** 2
    return np.fft.rfftfreq(len(acc), 1.0 / FPS), power.sum(axis=1)


def _wrist_flips(joints: np.ndarray) -> int:
    vy = np.diff(joints[:, WRISTS, 1], axis=0)
    return int((np.sign(vy[1:]) * np.sign(vy[:-1]) < 0).sum())


class Stats:
    """Measures pooled over the clips of one group (one action, real or reconstructed)."""

    def __init__(self) -> None:
        self.acc: list[np.ndarray] = []
        self.jerk: list[np.ndarray] = []
        self.energy = self.hf = self.band = 0.0
        self.flips, self.seconds, self.clips = 0, 0.0, 0
        self.err: list[float] = []
        self.global_err: list[float] = []

    def add(self, joints: np.ndarray, truth: np.ndarray | None = None) -> None:
        self.clips += 1
        self.acc.append(_diff_norms(joints, 2))
        self.jerk.append(_diff_norms(joints, 3))
        freq, power = _acc_spectrum(joints)
        half_bin = 0.5 * (freq[1] - freq[0])
        self.energy += float(power.sum())
        self.hf += float(power[freq >= HF_CUTOFF_HZ - half_bin].sum())
        self.band += float(power[(freq >= TOKEN_BAND_HZ[0]) & (freq <= TOKEN_BAND_HZ[1])].sum())
        self.flips += _wrist_flips(joints)
        self.seconds += len(joints) / FPS
        if truth is not None:
            local = (joints - joints[:, :1]) - (truth - truth[:, :1])
            self.err.append(float(np.linalg.norm(local, axis=-1)[:, 1:].mean()))
            self.global_err.append(float(np.linalg.norm(joints - truth, axis=-1).mean()))

    def summary(self) -> dict[str, float]:
        out = {
            "clips": float(self.clips),
            "acc_p99": float(np.percentile(np.concatenate(self.acc), 99)),
            "jerk_p99": float(np.percentile(np.concatenate(self.jerk), 99)),
            "hf_share": self.hf / max(self.energy, 1e-12),
            "token_band": self.band / max(self.seconds, 1e-12),
            "wrist_flips": self.flips / max(self.seconds, 1e-12),
        }
        if self.err:
            out["mpjpe_cm"] = float(np.mean(self.err) * 100)
            out["mpjpe_global_cm"] = float(np.mean(self.global_err) * 100)
        return out


# --- the split, the checkpoints ------------------------------------------------------------


def clip_groups(data: Path, split: str, min_clips: int) -> tuple[list[Any], list[str]]:
    """The whole clips of `split` (at least 4 frames) and each one's group: its label or "other"."""
    with (data / "index.csv").open(newline="", encoding="utf-8") as f:
        labels = {row["name"]: row["label"] or "other" for row in csv.DictReader(f)}
    clips = [c for c in read_split(data, split) if ":" not in c.name and c.num_frames >= 8]
    names = [labels.get(c.name, "other") for c in clips]
    counts = defaultdict(int)
    for name in names:
        counts[name] += 1
    return clips, [n if counts[n] >= min_clips else "other" for n in names]


@torch.no_grad()
def reconstruct(path: str, clips: list[Any]) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each clip's codes and reconstructed world joints, through the VQ-VAE at `path`."""
    model, ckpt = load_checkpoint(path, "vqvae", VQVAEConfig, VQVAE)
    normalizer = Normalizer.from_checkpoint(ckpt, path)
    codes, joints = [], []
    for clip in clips:
        n = clip.num_frames // model.rate * model.rate
        x = torch.from_numpy(normalizer.normalize(clip.features[:n]))[None]  # (1, n, 263)
        c = model.encode(x)
        codes.append(c[0].numpy())
        joints.append(features_to_joints(normalizer.denormalize(model.decode(c)[0])))
    return codes, joints


def measure(
    clips: list[Any], groups: list[str], recon: list[np.ndarray] | None
) -> dict[str, dict[str, float]]:
    """group -> summary of the real takes (recon None) or of the reconstructions, plus "all"."""
    stats: dict[str, Stats] = defaultdict(Stats)
    for i, (clip, group) in enumerate(zip(clips, groups, strict=True)):
        truth = features_to_joints(clip.features)
        joints = truth if recon is None else recon[i]  # a reconstruction stops at a whole token
        for key in (group, "all"):
            stats[key].add(joints, None if recon is None else truth[: len(joints)])
    return {k: s.summary() for k, s in sorted(stats.items())}


def replay(joints: list[np.ndarray], groups: list[str], actions: set[str]) -> dict[str, dict[str, Any]]:
    """action -> {"judged", "plausible" (share), "failed" (check -> clips), "mean_values" (check ->
    mean measured value)} of the MuJoCo replay."""
    from motion_env.motion.types import Motion
    from motion_env.replay import evaluate

    out: dict[str, dict[str, Any]] = {}
    for j, group in zip(joints, groups, strict=True):
        if group not in actions:
            continue
        verdict = evaluate(Motion(joints=j, fps=FPS))
        entry = out.setdefault(group, {"judged": 0, "passed": 0, "failed": defaultdict(int)})
        entry.setdefault("values", defaultdict(list))
        if verdict["judged"]:
            entry["judged"] += 1
            entry["passed"] += int(bool(verdict["plausible"]))
            for check in verdict["failed"]:
                entry["failed"][check] += 1
            for check, result in verdict["checks"].items():
                entry["values"][check].append(result["value"])
    for entry in out.values():
        entry["plausible"] = entry.pop("passed") / max(entry["judged"], 1)
        entry["failed"] = dict(entry["failed"])
        # A pass rate moves by whole clips; the mean measured values show smaller changes.
        entry["mean_values"] = {k: float(np.mean(v)) for k, v in entry.pop("values").items()}
    return out


def print_replay(name: str, verdicts: dict[str, dict[str, Any]]) -> None:
    for group, v in sorted(verdicts.items()):
        print(f"  {name} {group}: plausible {v['plausible']:.2f} of {v['judged']}, failed {v['failed']}")
        print("    mean values: " + ", ".join(f"{k} {x:.4g}" for k, x in v["mean_values"].items()))


def ratios(recon: dict[str, dict[str, float]], real: dict[str, dict[str, float]]) -> dict[str, dict]:
    keys = ("acc_p99", "jerk_p99", "hf_share", "token_band", "wrist_flips")
    return {g: {k: recon[g][k] / max(real[g][k], 1e-12) for k in keys} for g in recon}


def print_table(name: str, real: dict, recon: dict, ratio: dict) -> None:
    print(f"\n{name}: reconstruction / real takes (real values in brackets)")
    head = f"{'action':<22}{'clips':>6}{'MPJPE cm':>9}{'global':>7}{'acc p99':>16}{'jerk p99':>18}"
    print(head + f"{'HF>=5Hz share':>20}{'5Hz band':>10}{'wrist flips/s':>20}")
    for g in recon:
        r, q, t = recon[g], ratio[g], real[g]
        print(
            f"{g:<22}{int(r['clips']):>6}{r['mpjpe_cm']:>9.2f}{r['mpjpe_global_cm']:>7.1f}"
            f"{q['acc_p99']:>7.2f}x ({t['acc_p99']:>5.1f}){q['jerk_p99']:>8.2f}x ({t['jerk_p99']:>6.0f})"
            f"{r['hf_share']:>9.3f} ({t['hf_share']:.3f}){q['token_band']:>9.2f}x"
            f"{r['wrist_flips']:>10.2f} ({t['wrist_flips']:>5.2f})"
        )


# --- where the pops of generated clips come from (--stages) --------------------------------

STAGE_NAMES = ("decoded", "pelvis_out", "fitted", "composed", "feet", "physics")


def placed_stages(pipe: Any, features: np.ndarray, path: np.ndarray) -> dict[str, np.ndarray]:
    """The joints after each stage of :meth:`Pipeline.place_clip` for decoded `features` (n, 263)
    on a root `path` (>= n, 3): decoded (root-relative), that body on the bone lengths by either
    rebuild (pelvis_out, fitted; on a still path), composed, feet, physics."""
    from motion_env.generation.feet import FootPinner
    from motion_env.generation.physics import apply_physics
    from motion_env.generation.recompose import local_pose_from_features, recompose
    from motion_env.motion.kinematics import fit_bone_lengths, with_bone_lengths
    from motion_env.motion.skeleton import FOOT_CONTACT

    n = len(features)
    decoded = local_pose_from_features(features)
    still = recompose(decoded, np.zeros((n, 3), np.float32), face_travel=False)
    composed, _ = pipe.compose(features, path, n)
    feet = FootPinner(1).apply(0, composed, features[:, FOOT_CONTACT])
    physics = apply_physics(feet, features[:, FOOT_CONTACT])
    return {
        "decoded": decoded,
        "pelvis_out": with_bone_lengths(still),
        "fitted": fit_bone_lengths(still),
        "composed": composed,
        "feet": feet,
        "physics": physics,
    }


def planted_slide(joints: np.ndarray, contacts: np.ndarray) -> list[float]:
    """Horizontal steps (m) of each ankle between frames where both its contacts are on."""
    from motion_env.motion.skeleton import LEGS

    out: list[float] = []
    for leg, (_, _, ankle, _) in enumerate(LEGS):
        flat = contacts[:, 2 * leg] & contacts[:, 2 * leg + 1]
        both = flat[1:] & flat[:-1]
        out += list(np.linalg.norm(np.diff(joints[:, ankle, [0, 2]], axis=0), axis=-1)[both])
    return out


def _stage_cell(m: dict[str, Any]) -> str:
    """One stage of one clip: largest acceleration, joint, frame, POP, skating."""
    skating = "" if m["skating"] is None else f"{m['skating']:.2f}"
    pop = "POP" if m["pops"] else ""
    return f"{m['max_accel']:>9.1f} j{m['joint']:<2d} f{m['frame']:<4d}{pop:>4}{skating:>5}"


@torch.no_grad()
def stage_pops(args: Args) -> dict[str, Any]:
    """Per action and clip, the stages' largest accelerations, pops and skating (module docstring)."""
    import warnings

    from motion_env.evaluation.metrics import foot_skating_ratio, joint_acceleration
    from motion_env.evaluation.naturalness import (
        POP_FACTOR,
        extended_path,
        naturalness_takes,
        travel_waypoints,
    )
    from motion_env.generation.generator import MotionGenerator
    from motion_env.generation.request import check_request
    from motion_env.motion.skeleton import FOOT_CONTACT
    from motion_env.motion.trajectory import root_path_from_joints

    actions = [a.strip() for a in args.stages.split(",") if a.strip()]
    takes = naturalness_takes(args.data, args.split, 3)
    rng = np.random.default_rng(0)  # NaturalnessSettings' seed: the same takes as eval natural
    chosen = {
        a: [ts[i] for i in sorted(rng.choice(len(ts), min(args.per_action, len(ts)), replace=False))]
        for a, ts in takes.items()
    }
    pipe = MotionGenerator.from_pretrained().pipeline
    out: dict[str, Any] = {}
    pooled: dict[str, list[np.ndarray]] = {name: [] for name in (*STAGE_NAMES, "real")}
    for action in actions:
        if action not in takes:
            raise SystemExit(f"no action {action!r} with 3 takes in split {args.split!r}: {sorted(takes)}")
        real_accel = np.concatenate([joint_acceleration(t.joints).ravel() for t in takes[action]])
        pop = POP_FACTOR * float(np.percentile(real_accel, 99.9))
        clips, slide = [], {name: [] for name in STAGE_NAMES[3:]}
        accels: dict[str, list[np.ndarray]] = {name: [] for name in STAGE_NAMES}
        late: list[np.ndarray] = []  # the final stage without the clips' first frames
        for take in chosen[action]:
            t_len = len(take.joints)
            path = extended_path(root_path_from_joints(take.joints))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                req = check_request(
                    take.text, travel_waypoints(path), len(path), 0, path[0], "warn", None, None
                )
                emb = pipe.encode_text(req.texts)
                _, paths = pipe.plan_paths(emb, req)
            n_tok = -(-req.num_frames // pipe.rate)
            body = pipe.decode(pipe.sample_tokens(emb, paths, n_tok, req.seed))[0]
            stages = placed_stages(pipe, body, paths[0])
            contacts = body[:t_len, FOOT_CONTACT] > 0.5
            row: dict[str, Any] = {"take": take.name}
            for name, joints in stages.items():
                acc = joint_acceleration(joints[:t_len])
                accels[name].append(acc.ravel())
                frame, joint = np.unravel_index(int(acc.argmax()), acc.shape)
                row[name] = {
                    "max_accel": float(acc.max()),
                    "joint": int(joint),
                    "frame": int(frame) + 1,
                    "pops": bool(acc.max() > pop),
                    "skating": foot_skating_ratio(joints[:t_len]) if name in STAGE_NAMES[3:] else None,
                }
                if name in slide:
                    slide[name] += planted_slide(joints[:t_len], contacts)
            late.append(joint_acceleration(stages["physics"][:t_len])[args.skip_frames :].ravel())
            clips.append(row)
        real = [joint_acceleration(t.joints).ravel() for t in chosen[action]]
        real_p99 = float(np.percentile(np.concatenate(real), 99))
        for name in STAGE_NAMES:
            pooled[name] += accels[name]
        pooled["real"] += real
        real_late = np.concatenate(
            [joint_acceleration(t.joints)[args.skip_frames :].ravel() for t in chosen[action]]
        )
        accel_ratio = {n: float(np.percentile(np.concatenate(v), 99)) / real_p99 for n, v in accels.items()}
        accel_ratio[f"physics_after_{args.skip_frames}"] = float(
            np.percentile(np.concatenate(late), 99) / np.percentile(real_late, 99)
        )
        real_skating = float(np.mean([foot_skating_ratio(t.joints) for t in chosen[action]]))
        out[action] = {
            "pop_threshold": pop,
            "clips": clips,
            "real_skating": real_skating,
            "planted_slide_cm": {k: 100 * float(np.mean(v)) if v else None for k, v in slide.items()},
            "accel_p99_ratio": accel_ratio,
        }
        print(f"\n{action} (pop over {pop:.1f} m/s^2; real skating {real_skating:.3f})")
        print(f"{'take':<40}" + "".join(f"{n:>26}" for n in STAGE_NAMES))
        for row in clips:
            print(f"{row['take'][:39]:<40}" + "".join(_stage_cell(row[n]) for n in STAGE_NAMES))
        print("acceleration p99 / real " + ", ".join(f"{n} {v:.2f}" for n, v in accel_ratio.items()))
        pops = {n: sum(r[n]["pops"] for r in clips) for n in STAGE_NAMES}
        print("pops " + ", ".join(f"{n} {v}/{len(clips)}" for n, v in pops.items()))
        if real_skating > 0:  # takes in place (raised hands, waves) have no skating to compare
            skate = {n: np.mean([r[n]["skating"] for r in clips]) / real_skating for n in STAGE_NAMES[3:]}
            print("skating / real " + ", ".join(f"{n} {v:.2f}" for n, v in skate.items()))
        slides = out[action]["planted_slide_cm"].items()
        print("planted feet slide (cm/frame) " + ", ".join(f"{n} {v:.2f}" for n, v in slides))
    if len(actions) > 1:
        real_p99 = float(np.percentile(np.concatenate(pooled["real"]), 99))
        ratio = {n: float(np.percentile(np.concatenate(pooled[n]), 99)) / real_p99 for n in STAGE_NAMES}
        out["all"] = {"accel_p99_ratio": ratio}
        print(
            "\nall these actions: acceleration p99 / real "
            + ", ".join(f"{n} {v:.2f}" for n, v in ratio.items())
        )
    return out


def main() -> None:
    args = parse_dataclass(Args, description=__doc__)
    torch.set_num_threads(args.threads)
    t0 = time.perf_counter()
    if args.stages:
        out = {"args": asdict(args), "stages": stage_pops(args), "seconds": time.perf_counter() - t0}
        write_json(args.json, json.loads(json.dumps(out)))
        return
    clips, groups = clip_groups(Path(args.data), args.split, args.min_clips)
    real = measure(clips, groups, None)
    actions = set(filter(None, (a.strip() for a in args.replay.split(","))))
    real_joints = [features_to_joints(c.features) for c in clips]
    out: dict[str, Any] = {"args": asdict(args), "real": real, "checkpoints": {}}
    out["real_replay"] = replay(real_joints, groups, actions)
    print_replay("real takes", out["real_replay"])
    first_codes = None
    for path in filter(None, (p.strip() for p in args.checkpoints.split(","))):
        codes, joints = reconstruct(path, clips)
        recon = measure(clips, groups, joints)
        ratio = ratios(recon, real)
        entry: dict[str, Any] = {"recon": recon, "ratio": ratio, "replay": replay(joints, groups, actions)}
        if first_codes is None:
            first_codes = codes
        else:
            same = sum(np.array_equal(a, b) for a, b in zip(first_codes, codes, strict=True))
            entry["clips_with_same_tokens"] = f"{same}/{len(codes)}"
            print(f"\n{path}: {same}/{len(codes)} clips get the same tokens as the first checkpoint")
        out["checkpoints"][path] = entry
        print_table(path, real, recon, ratio)
        print_replay("reconstructions", entry["replay"])
    out["seconds"] = time.perf_counter() - t0
    write_json(args.json, json.loads(json.dumps(out)))


if __name__ == "__main__":
    main()
