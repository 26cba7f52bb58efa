"""Keep what was made in the studio: a clip as the bytes of an .npz, a BVH or a robot CSV.

The page sends these bytes to the browser as a download; nothing is written on the server's disk
but temporary files.
"""

from __future__ import annotations

import importlib.util
import tempfile
from pathlib import Path

from motion_env.motion.types import Motion

__all__ = ["CLIP_KINDS", "clip_file"]

CLIP_KINDS = ("npz", "bvh", "csv")
ROBOT = "unitree_g1"
ROBOT_FPS = 50.0


def clip_file(motion: Motion, kind: str, name: str) -> tuple[str, bytes]:
    """`motion` as a file: returns (file name, content).

    Args:
        kind: "npz" (:meth:`Motion.save`), "bvh" (:func:`motion_env.io.bvh_write.save_bvh`) or
            "csv" (retargeted onto the Unitree G1 at 50 fps, :func:`motion_env.retarget.retarget`;
            needs the ``robots`` extra).
        name: the file name without its suffix.

    Raises:
        ValueError: an unknown kind, or "csv" without the mink package (the message says how to
            install it).
    """
    if kind not in CLIP_KINDS:
        raise ValueError(f"a clip is kept as one of {CLIP_KINDS}, not {kind!r}")
    if kind == "bvh":
        from motion_env.io.bvh_write import bvh_text

        return f"{name}.bvh", bvh_text(motion).encode("ascii")
    if kind == "csv" and importlib.util.find_spec("mink") is None:
        raise ValueError(
            'a robot CSV needs the mink package: pip install -c constraints.txt "motion-env[robots]"'
        )
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{name}.{kind}"
        if kind == "npz":
            motion.save(path)
        else:
            from motion_env.retarget import retarget

            retarget(motion, ROBOT, fps=ROBOT_FPS).save(path)
        return path.name, path.read_bytes()
