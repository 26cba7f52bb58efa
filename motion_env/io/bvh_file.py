"""BVH files in: the parser and forward kinematics on the file's own skeleton.

:func:`read_bvh` parses the hierarchy (any Euler order per joint, 3- or 6-channel joints, End
Sites, several roots) and the MOTION block (one numpy conversion for all values);
:func:`bvh_world_positions` runs forward kinematics on the source skeleton, vectorised over
frames, in the file's units. :mod:`motion_env.io.bvh` turns the result into a canonical
:class:`~motion_env.motion.types.Motion`.
"""

from __future__ import annotations

import gzip
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["AXES", "BvhFile", "bvh_world_positions", "read_bvh"]

AXES = {"x": 0, "y": 1, "z": 2}
"""Index of each axis letter of a BVH channel name."""
_CHANNEL = re.compile(r"^([XYZxyz])(position|rotation)$", re.IGNORECASE)


@dataclass
class BvhFile:
    """A parsed BVH file: the source skeleton and its per-frame channel values.

    Attributes:
        path: the file it was read from.
        names: (J,) joint names in file order (parents come before their children).
        parents: (J,) parent index of each joint, -1 for a root.
        offsets: (J, 3) rest offset of each joint from its parent, file units.
        channels: per joint, the channel names in file order (e.g. ``("Zrotation", "Xrotation",
            "Yrotation")``); empty for a joint without channels.
        channel_start: (J,) column of each joint's first channel in ``values``.
        end_sites: joint index -> (3,) offset of its End Site, file units.
        frame_time: seconds per frame.
        values: (T, C) float64 channel values (positions in file units, rotations in degrees).
    """

    path: Path
    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[str, ...]]
    channel_start: np.ndarray
    end_sites: dict[int, np.ndarray]
    frame_time: float
    values: np.ndarray

    @property
    def num_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def fps(self) -> float:
        """Frames per second; snapped to the nearest integer when within 0.01 % of it, since
        Frame Time is written with few digits (0.0333333 s is 30 fps, not 30.00003)."""
        fps = 1.0 / self.frame_time
        return float(round(fps)) if abs(fps - round(fps)) < 1e-4 * fps else fps


def _read_text(path: Path) -> str:
    """The file's text; gzip is recognised by its magic bytes as well as by the suffix."""
    if not path.is_file():
        raise FileNotFoundError(f"no BVH file at {path}")
    with path.open("rb") as fh:
        gzipped = fh.read(2) == b"\x1f\x8b"
    try:
        if gzipped or path.suffix.lower() == ".gz":
            # latin-1 maps every byte, so binary junk reaches the HIERARCHY check below instead of
            # failing with a decode error that does not say what is wrong.
            with gzip.open(path, "rt", encoding="latin-1") as fh:
                return fh.read()
        return path.read_text(encoding="latin-1")
    except (OSError, EOFError) as exc:  # gzip.BadGzipFile is an OSError
        raise ValueError(f"{path}: cannot read the file as gzip-compressed text ({exc})") from exc


def _parse_hierarchy(path: Path, tokens: list[str]) -> tuple:
    """Parse the HIERARCHY tokens into names, parents, offsets, channels and end sites."""
    names: list[str] = []
    parents: list[int] = []
    offsets: list[np.ndarray] = []
    channels: list[tuple[str, ...]] = []
    end_sites: dict[int, np.ndarray] = {}
    stack: list[tuple[str, int]] = []  # ("joint", index) or ("end", owner index)
    pending: tuple[str, int] | None = None
    i, n = 1, len(tokens)

    def fail(msg: str) -> ValueError:
        return ValueError(f"{path}: malformed BVH hierarchy: {msg}")

    while i < n:
        tok = tokens[i]
        key = tok.upper()
        if key in ("ROOT", "JOINT"):
            if key == "JOINT" and not (stack and stack[-1][0] == "joint"):
                raise fail(f"JOINT outside a joint block (token {i})")
            j = i + 1
            while j < n and tokens[j] != "{":  # names may contain spaces ("Bip01 L Thigh")
                j += 1
            if j == i + 1 or j == n:
                raise fail(f"{tok} without a name and a '{{'")
            names.append(" ".join(tokens[i + 1 : j]))
            parents.append(stack[-1][1] if stack else -1)
            offsets.append(np.zeros(3))
            channels.append(())
            pending = ("joint", len(names) - 1)
            i = j
        elif key == "END":
            if i + 1 >= n or tokens[i + 1].upper() != "SITE" or not stack or stack[-1][0] != "joint":
                raise fail(f"misplaced End Site (token {i})")
            pending = ("end", stack[-1][1])
            i += 2
        elif tok == "{":
            if pending is None:
                raise fail(f"'{{' without a ROOT, JOINT or End Site (token {i})")
            stack.append(pending)
            pending = None
            i += 1
        elif tok == "}":
            if not stack:
                raise fail(f"unbalanced '}}' (token {i})")
            stack.pop()
            i += 1
        elif key == "OFFSET":
            if not stack:
                raise fail("OFFSET outside a block")
            off = _offset(tokens[i + 1 : i + 4], fail)
            kind, idx = stack[-1]
            if kind == "joint":
                offsets[idx] = off
            else:
                end_sites.setdefault(idx, off)
            i += 4
        elif key == "CHANNELS":
            if not stack or stack[-1][0] != "joint":
                raise fail("CHANNELS outside a joint block")
            chans = _channels(tokens, i + 1, names[stack[-1][1]], fail)
            channels[stack[-1][1]] = chans
            i += 2 + len(chans)
        else:
            raise fail(f"unexpected token {tok!r} (token {i})")
    if stack:
        raise fail("missing '}' at the end of the hierarchy")
    if not names:
        raise fail("no joints")
    return names, parents, offsets, channels, end_sites


def _offset(values: list[str], fail: Callable[[str], ValueError]) -> np.ndarray:
    """(3,) the `values` of an OFFSET line as numbers."""
    try:
        off = np.array([float(t) for t in values])
    except ValueError as exc:
        raise fail(f"bad OFFSET values {values}") from exc
    if off.shape != (3,) or not np.isfinite(off).all():
        raise fail(f"bad OFFSET values {values}")
    return off


def _channels(tokens: list[str], i: int, joint: str, fail: Callable[[str], ValueError]) -> tuple[str, ...]:
    """The channel names of a CHANNELS line whose count is token `i`."""
    try:
        count = int(tokens[i])
    except (ValueError, IndexError) as exc:
        raise fail(f"bad channel count {tokens[i : i + 1]}") from exc
    chans = tuple(tokens[i + 1 : i + 1 + count])
    bad = [c for c in chans if not _CHANNEL.match(c)]
    if len(chans) != count or bad:
        raise fail(f"joint {joint!r} has bad channels {list(chans)}")
    return chans


def read_bvh(path: str | Path) -> BvhFile:
    """Parse a ``.bvh`` or ``.bvh.gz`` file (no kinematics, no mapping).

    Raises:
        FileNotFoundError: the file does not exist.
        ValueError: not a BVH file, a malformed hierarchy, a truncated or over-long MOTION block,
            a non-numeric or NaN / infinite channel value; the message names the file.
    """
    path = Path(path)
    text = _read_text(path).removeprefix("\xef\xbb\xbf")  # a UTF-8 byte-order mark, read as latin-1
    head = text.lstrip()[:9]
    if head.upper() != "HIERARCHY":
        raise ValueError(f"{path}: not a BVH file (it should start with HIERARCHY, starts with {head!r})")
    motion = re.search(r"^[ \t]*MOTION\b", text, re.MULTILINE)
    if motion is None:
        raise ValueError(f"{path}: no MOTION section (the file is truncated or not a BVH file)")
    names, parents, offsets, channels, end_sites = _parse_hierarchy(path, text[: motion.start()].split())

    header = re.match(r"\s*Frames:\s*(\S+)\s+Frame\s+Time:\s*(\S+)", text[motion.end() :], re.IGNORECASE)
    if header is None:
        raise ValueError(f"{path}: MOTION section lacks 'Frames:' and 'Frame Time:' lines")
    try:
        num_frames = int(header.group(1))
        frame_time = float(header.group(2))
    except ValueError as exc:
        raise ValueError(f"{path}: bad Frames / Frame Time values {header.groups()}") from exc
    if num_frames < 1:
        raise ValueError(f"{path}: the file has no frames (Frames: {num_frames})")
    if not (np.isfinite(frame_time) and frame_time > 0):
        raise ValueError(f"{path}: Frame Time must be a positive number, got {frame_time}")

    counts = np.array([len(c) for c in channels])
    num_channels = int(counts.sum())
    if num_channels == 0:
        raise ValueError(f"{path}: the hierarchy declares no channels")
    tokens = text[motion.end() + header.end() :].split()
    try:
        values = np.array(tokens, dtype=np.float64)
    except ValueError:
        bad = next(k for k, t in enumerate(tokens) if not _is_float(t))
        raise ValueError(
            f"{path}: non-numeric value {tokens[bad]!r} in frame {bad // num_channels} of the MOTION block"
        ) from None
    expected = num_frames * num_channels
    if values.size != expected:
        kind = "truncated" if values.size < expected else "longer than its header says"
        raise ValueError(
            f"{path}: MOTION block is {kind}: Frames: {num_frames} x {num_channels} channels = "
            f"{expected} values, found {values.size} ({values.size // num_channels} whole frames)"
        )
    values = values.reshape(num_frames, num_channels)
    channel_start = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    if not np.isfinite(values).all():
        frame, col = np.argwhere(~np.isfinite(values))[0]
        joint = int(np.searchsorted(channel_start, col, side="right") - 1)
        raise ValueError(
            f"{path}: NaN or infinite channel value at frame {frame}, joint {names[joint]!r} "
            f"channel {channels[joint][col - channel_start[joint]]!r}"
        )
    return BvhFile(
        path=path,
        names=names,
        parents=np.array(parents, dtype=np.int64),
        offsets=np.stack(offsets),
        channels=channels,
        channel_start=channel_start,
        end_sites=end_sites,
        frame_time=frame_time,
        values=values,
    )


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def bvh_world_positions(
    bvh: BvhFile, joints: list[int] | None = None
) -> tuple[np.ndarray, dict[int, np.ndarray]]:
    """World forward kinematics of the source skeleton, vectorised over frames.

    A joint's local rotation is the product of its rotation channels in file order (``Zrotation
    Xrotation Yrotation`` gives R = Rz @ Rx @ Ry, intrinsic); its translation from the parent is
    its position channels where it has them (they replace the OFFSET, as BVH exporters write
    them) and its OFFSET otherwise.

    Args:
        bvh: a parsed file.
        joints: compute only these joints (and their ancestors); None = all.

    Returns:
        positions: (T, J, 3) world positions in file units (NaN for joints not computed).
        end_sites: joint index -> (T, 3) world position of its End Site (computed joints only).
    """
    num_frames, num_joints = bvh.num_frames, len(bvh.names)
    needed = np.zeros(num_joints, dtype=bool)
    for j in range(num_joints) if joints is None else joints:
        while j >= 0 and not needed[j]:
            needed[j] = True
            j = int(bvh.parents[j])
    # Local rotations, one scipy call per distinct channel order (upper case = intrinsic: "ZXY"
    # is Rz @ Rx @ Ry).
    local: dict[int, np.ndarray] = {}
    by_order: dict[str, list[int]] = {}
    for j in np.flatnonzero(needed):
        order = "".join(c[0].upper() for c in bvh.channels[j] if c[1:].lower() == "rotation")
        if order:
            by_order.setdefault(order, []).append(int(j))
    for order, group in by_order.items():
        cols = [
            int(bvh.channel_start[j]) + k
            for j in group
            for k, c in enumerate(bvh.channels[j])
            if c[1:].lower() == "rotation"
        ]
        angles = bvh.values[:, cols].reshape(num_frames, len(group), len(order))
        mats = Rotation.from_euler(order, angles.reshape(-1, len(order)), degrees=True).as_matrix()
        mats = mats.reshape(num_frames, len(group), 3, 3)
        for g, j in enumerate(group):
            local[j] = mats[:, g]

    pos = np.full((num_frames, num_joints, 3), np.nan)
    rot = np.empty((num_frames, num_joints, 3, 3))
    for j in np.flatnonzero(needed):
        start = int(bvh.channel_start[j])
        trans = np.broadcast_to(bvh.offsets[j], (num_frames, 3)).copy()
        for k, name in enumerate(bvh.channels[j]):
            if name[1:].lower() == "position":
                trans[:, AXES[name[0].lower()]] = bvh.values[:, start + k]
        p = int(bvh.parents[j])
        if p < 0:
            pos[:, j] = trans
            rot[:, j] = local[j] if j in local else np.eye(3)
        else:
            pos[:, j] = pos[:, p] + np.einsum("tij,tj->ti", rot[:, p], trans)
            rot[:, j] = rot[:, p] @ local[j] if j in local else rot[:, p]
    ends = {
        j: pos[:, j] + np.einsum("tij,j->ti", rot[:, j], off) for j, off in bvh.end_sites.items() if needed[j]
    }
    return pos, ends
