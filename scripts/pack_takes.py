"""A built dataset's takes packed small enough to travel to a machine that has no copy of the
motion capture (a lent GPU machine takes a working tree of 64 MiB), and unpacked there into the
same HumanML3D-layout dataset.

A built dataset stores 263 features a frame for every take and its mirror (about 800 MB); a take
is its 22 joints' positions as imported from its BVH file, from which the build computes
everything else. The pack holds those positions (re-imported from the files `index.csv` names),
rounded to 0.01 mm and stored as frame-to-frame changes under lzma, with the captions of every
clip and the dataset's Mean/Std; unpacking computes each take's features and its mirror's as
`motion-env data build` does. The train and val splits of the shared data pack into about 25 MB;
the features unpacked match the built ones to about 1e-4 of a standard deviation.

    python scripts/pack_takes.py pack --data data/mocap --splits train,val --out gpu/takes.npz
    python scripts/pack_takes.py unpack gpu/takes.npz --out /tmp/mocap --workers 16
    python scripts/pack_takes.py check gpu/takes.npz --data data/mocap   # unpacked against built

The motion capture's licences travel with it: a pack is not for publishing (Bandai Namco's
takes are CC BY-NC 4.0).
"""

from __future__ import annotations

import argparse
import json
import lzma
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from tqdm import tqdm

from motion_env.data.dataset import load_stats, read_index
from motion_env.data.jobs import clip_arrays
from motion_env.io.bvh import load_bvh

QUANTUM_M = 1e-5  # positions are stored to this (0.01 mm): far below the capture's own precision
FORMAT = 1


def _import(path: str) -> np.ndarray:
    return load_bvh(path).joints.astype(np.float32)


def pack(data: Path, splits: list[str], out: Path, workers: int) -> None:
    """Write the takes of `splits` of the built dataset `data` into the pack `out`."""
    index = read_index(data)
    if not index:
        raise SystemExit(
            f"{data}: no index.csv (only datasets made by `motion-env data build` can be packed)"
        )
    split_names = {s: (data / f"{s}.txt").read_text(encoding="utf-8").split() for s in splits}
    clips = [n for names in split_names.values() for n in names]
    takes = [n for n in clips if index[n]["mirrored"] == "0"]
    missing = [n for n in takes if not Path(index[n]["file"]).is_file()]
    if missing:
        raise SystemExit(
            f"{len(missing)} motion file(s) named by {data / 'index.csv'} are missing, "
            f"e.g. {index[missing[0]]['file']}"
        )
    with ProcessPoolExecutor(workers) as pool:
        joints = list(
            tqdm(
                pool.map(_import, [index[n]["file"] for n in takes], chunksize=8),
                total=len(takes),
                desc="importing",
            )
        )
    steps = [
        np.diff(np.round(j / QUANTUM_M).astype(np.int64), axis=0, prepend=0).reshape(len(j), -1)
        for j in joints
    ]
    blob = np.concatenate(steps)
    if np.abs(blob).max() >= 2**31:
        raise SystemExit("a position is too far from the origin for the pack's 32-bit steps")
    texts = {n: (data / "texts" / f"{n}.txt").read_text(encoding="utf-8") for n in clips}
    mean, std = load_stats(data)
    out.parent.mkdir(parents=True, exist_ok=True)
    np.savez(
        out, format=FORMAT, quantum=QUANTUM_M, takes=np.array(takes),
        lengths=np.array([len(j) for j in joints]),
        positions=np.frombuffer(lzma.compress(blob.astype(np.int32).tobytes()), np.uint8),
        splits=np.frombuffer(lzma.compress(json.dumps(split_names).encode()), np.uint8),
        texts=np.frombuffer(lzma.compress(json.dumps(texts).encode()), np.uint8), mean=mean, std=std,
    )  # fmt: skip
    print(
        f"{out}: {len(takes)} takes ({sum(map(len, joints))} frames), {len(clips)} clips, "
        f"{out.stat().st_size / 1e6:.1f} MB"
    )


def read_pack(
    path: Path,
) -> tuple[dict[str, np.ndarray], dict[str, list[str]], dict[str, str], np.ndarray, np.ndarray]:
    """(take -> joints, split -> clip names, clip -> caption file text, mean, std) of a pack."""
    with np.load(path) as z:
        if int(z["format"]) != FORMAT:
            raise SystemExit(f"{path}: pack format {int(z['format'])}, this script reads {FORMAT}")
        steps = np.frombuffer(lzma.decompress(z["positions"].tobytes()), np.int32).reshape(-1, 66)
        ends = np.cumsum(z["lengths"])
        joints = {
            str(name): (np.cumsum(s.astype(np.int64), axis=0) * float(z["quantum"]))
            .astype(np.float32)
            .reshape(-1, 22, 3)
            for name, s in zip(z["takes"], np.split(steps, ends[:-1]), strict=True)
        }  # fmt: skip
        splits = json.loads(lzma.decompress(z["splits"].tobytes()))
        texts = json.loads(lzma.decompress(z["texts"].tobytes()))
        return joints, splits, texts, z["mean"], z["std"]


def _features(item: tuple[str, np.ndarray]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """A take's clip and its mirror's, as a build writes them."""
    return [(clip, f.astype(np.float32), j.astype(np.float32)) for clip, f, j in clip_arrays(*item)]


def unpack(path: Path, out: Path, workers: int) -> None:
    """Write the pack's clips as a HumanML3D-layout dataset at `out` (a new or empty folder)."""
    if out.exists() and any(out.iterdir()):
        raise SystemExit(f"{out} exists and is not empty; nothing was written")
    joints, splits, texts, mean, std = read_pack(path)
    for sub in ("new_joint_vecs", "new_joints", "texts"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    with ProcessPoolExecutor(workers) as pool:
        for rows in tqdm(
            pool.map(_features, joints.items(), chunksize=8), total=len(joints), desc="features"
        ):
            for clip, features, new_joints in rows:
                np.save(out / "new_joint_vecs" / f"{clip}.npy", features)
                np.save(out / "new_joints" / f"{clip}.npy", new_joints)
    for clip, text in texts.items():
        (out / "texts" / f"{clip}.txt").write_text(text, encoding="utf-8")
    for split, names in splits.items():
        (out / f"{split}.txt").write_text("\n".join(names) + "\n", encoding="utf-8")
    np.save(out / "Mean.npy", mean)
    np.save(out / "Std.npy", std)
    print(f"{out}: {sum(len(n) for n in splits.values())} clips unpacked")


def check(path: Path, data: Path, takes: int) -> None:
    """Features unpacked from the pack against the built dataset's, in standard deviations."""
    joints, _, _, _, std = read_pack(path)
    worst = 0.0
    for name in list(joints)[:: max(1, len(joints) // takes)]:
        for clip, features, _ in _features((name, joints[name])):
            built = np.load(data / "new_joint_vecs" / f"{clip}.npy")
            if built.shape != features.shape:
                raise SystemExit(f"{clip}: {features.shape} frames unpacked, {built.shape} built")
            worst = max(worst, float(np.abs((features - built) / std).max()))
    print(f"largest difference, unpacked vs built: {worst:.2e} standard deviations")
    if worst > 1e-2:
        raise SystemExit("the pack does not reproduce the built features")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("pack", help="pack a built dataset's takes")
    p.add_argument("--data", type=Path, required=True, help="a dataset made by `motion-env data build`")
    p.add_argument("--splits", default="train,val", help="comma-separated splits to pack")
    p.add_argument("--out", type=Path, required=True, help="the pack (.npz) to write")
    p.add_argument("--workers", type=int, default=2, help="processes importing BVH files")
    u = sub.add_parser("unpack", help="write a pack as a dataset")
    u.add_argument("pack", type=Path)
    u.add_argument("--out", type=Path, required=True, help="a new or empty folder")
    u.add_argument("--workers", type=int, default=2, help="processes computing features")
    c = sub.add_parser("check", help="compare a pack's features with the built dataset's")
    c.add_argument("pack", type=Path)
    c.add_argument("--data", type=Path, required=True)
    c.add_argument("--takes", type=int, default=40, help="takes compared (evenly spaced)")
    args = parser.parse_args(argv)
    if args.command == "pack":
        if args.out.exists():
            raise SystemExit(f"{args.out} exists; nothing was written")
        pack(args.data, [s for s in args.splits.split(",") if s], args.out, args.workers)
    elif args.command == "unpack":
        unpack(args.pack, args.out, args.workers)
    else:
        check(args.pack, args.data, args.takes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
