"""The studio's floor geometry: where a click lands on the floor, the figure as coloured bone
segments, dense paths resampled into waypoints. Pure numpy, so it is tested without a browser.

World conventions as everywhere (docs/conventions.md): metres, Y up, floor at y = 0; floor
points are (x, z).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from motion_env.motion.skeleton import JOINT_NAMES, NUM_JOINTS, PARENTS
from motion_env.render.drawing import LEFT_COLOR, RIGHT_COLOR, SPINE_COLOR, hex_rgb

__all__ = [
    "ARENA_HALF_SIZE",
    "BONES",
    "bone_colors",
    "bone_segments",
    "floor_point",
    "followed_camera",
    "joint_colors",
    "resample_path",
]

ARENA_HALF_SIZE = 25.0  # metres: the floor the studio draws and accepts clicks on, centred on 0

# Bone b joins joint BONES[b, 0] (the parent) to BONES[b, 1].
BONES = np.array([(p, j) for j, p in enumerate(PARENTS) if p >= 0], np.int64)  # (21, 2)


def _side(joint: int) -> str:
    name = JOINT_NAMES[joint]
    return "left" if name.startswith("left") else "right" if name.startswith("right") else "centre"


_SIDE_COLOR = {"left": LEFT_COLOR, "right": RIGHT_COLOR, "centre": SPINE_COLOR}


def joint_colors() -> np.ndarray:
    """(22, 3) uint8: left joints blue, right orange, the spine dark grey (as the videos draw them)."""
    return np.array([hex_rgb(_SIDE_COLOR[_side(j)]) * 255 for j in range(NUM_JOINTS)]).astype(np.uint8)


def bone_colors() -> np.ndarray:
    """(21, 2, 3) uint8: each bone in the colour of the joint it ends at (the hips and the collars
    take the side of their limb)."""
    per_joint = joint_colors()
    return np.repeat(per_joint[BONES[:, 1]][:, None], 2, axis=1)


def bone_segments(joints: np.ndarray) -> np.ndarray:
    """Joints (..., 22, 3) -> bone segments (..., 21, 2, 3), the layout of viser's line segments."""
    return np.asarray(joints, np.float32)[..., BONES, :]


def floor_point(
    ray_origin: Sequence[float], ray_direction: Sequence[float], half_size: float = ARENA_HALF_SIZE
) -> np.ndarray | None:
    """Where a ray from the camera meets the floor, as (x, z); None when it does not within the arena.

    A click on the sky (a ray that points up or along the floor), behind the camera, or further than
    `half_size` metres from the origin in x or z has no floor point: the caller says so instead of
    placing a waypoint at infinity.
    """
    origin = np.asarray(ray_origin, np.float64)
    direction = np.asarray(ray_direction, np.float64)
    if origin.shape != (3,) or direction.shape != (3,) or not np.isfinite([*origin, *direction]).all():
        return None
    if direction[1] > -1e-6:  # upwards or parallel to the floor: it never comes down to y = 0
        return None
    t = -origin[1] / direction[1]
    if t <= 0:  # the camera is below the floor
        return None
    point = (origin + t * direction)[[0, 2]]
    if np.abs(point).max() > half_size:
        return None
    return point


def resample_path(points: np.ndarray | Sequence, spacing: float = 0.5) -> np.ndarray:
    """A drawn polyline (N, 2) -> points every `spacing` metres along it (M, 2), ends kept.

    A pointer drag arrives as points about 20 times a second, bunched where the hand slowed down;
    the route is made even so that the path controller reads a steady pace. A path shorter than
    `spacing` gives its last point alone.
    """
    pts = np.asarray(points, np.float64).reshape(-1, 2)
    if len(pts) == 0:
        raise ValueError("a drawn path needs at least one point")
    if not spacing > 0:
        raise ValueError(f"spacing must be > 0 metres, got {spacing}")
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    along = np.concatenate([[0.0], np.cumsum(seg)])
    total = along[-1]
    if total < spacing:
        return pts[-1:].copy()
    count = int(np.ceil(total / spacing))
    at = np.linspace(0.0, total, count + 1)[1:]  # the start is where the character already is
    return np.stack([np.interp(at, along, pts[:, 0]), np.interp(at, along, pts[:, 1])], axis=1)


def followed_camera(
    position: np.ndarray, look_at: np.ndarray, target: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A camera that follows a character: the look-at point moved over `target` (3,) on the floor
    (its height kept), the eye moved by as much, so that the angle and distance the user chose by
    orbiting and zooming are kept.

    It is a translation, so a camera a tab reports late (from before the last move) still carries
    the user's angle and distance: the view never falls behind the character.

    Returns:
        (position, look_at), each (3,) float64.
    """
    position, look_at = np.asarray(position, np.float64), np.asarray(look_at, np.float64)
    new_look_at = np.array([target[0], look_at[1], target[2]], np.float64)
    return position + (new_look_at - look_at), new_look_at
