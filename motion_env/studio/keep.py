"""Keep what was made in the studio: a clip as the bytes of an .npz, a BVH or a robot file (the
project's CSV, or a tracker's format: LAFAN-style CSV, mjlab's .npz, GMR's .pkl).

The page sends these bytes to the browser as a download; nothing is written on the server's disk
but temporary files.
"""

from __future__ import annotations

import importlib.util
import tempfile
from pathlib import Path

from motion_env.args import install_line
from motion_env.motion.types import Motion

__all__ = ["CLIP_KINDS", "ROBOT_KINDS", "clip_file"]

ROBOT_KINDS = ("csv", "lafan_csv", "mjlab", "gmr")  # formats of RobotMotion.save
CLIP_KINDS = ("npz", "bvh", *ROBOT_KINDS)
ROBOT = "unitree_g1"
ROBOT_FPS = 50.0


def clip_file(motion: Motion, kind: str, name: str, robot: str = ROBOT) -> tuple[str, bytes]:
    """`motion` as a file: returns (file name, content).

    Args:
        kind: "npz" (:meth:`Motion.save`), "bvh" (:func:`motion_env.io.bvh_write.save_bvh`) or a
            robot format of :data:`ROBOT_KINDS` (retargeted onto `robot` at 50 fps by
            :func:`motion_env.retarget.retarget`, written by ``RobotMotion.save(path, format=kind)``;
            needs the ``robots`` extra).
        name: the file name without its suffix (a robot format other than "csv" adds its name).
        robot: the robot of the robot formats.

    Raises:
        ValueError: an unknown kind, or a robot format without the mink package (the message says
            how to install it).
    """
    if kind not in CLIP_KINDS:
        raise ValueError(f"a clip is kept as one of {CLIP_KINDS}, not {kind!r}")
    if kind == "bvh":
        from motion_env.io.bvh_write import bvh_text

        return f"{name}.bvh", bvh_text(motion).encode("ascii")
    if kind == "npz":
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / f"{name}.npz"
            motion.save(path)
            return path.name, path.read_bytes()
    if importlib.util.find_spec("mink") is None:
        raise ValueError(f"a robot file needs the mink package: {install_line('robots')}")
    from motion_env.retarget import retarget
    from motion_env.retarget.files import FORMATS

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"{name if kind == 'csv' else f'{name}_{kind}'}{FORMATS[kind]}"
        retarget(motion, robot, fps=ROBOT_FPS).save(path, format=kind)
        return path.name, path.read_bytes()
