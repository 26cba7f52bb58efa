"""Where a robot meets the floor: which geoms count, and the lowest point of each, frame by frame.

The lowest point itself is the replay's (:class:`motion_env.replay.robot_kinematic.GeomPoints`:
a mesh's convex-hull vertices, as MuJoCo collides it; box corners; cylinder rims; sphere and
capsule centres with their radius), so the retargeter keeps the robot above the floor exactly as
``evaluate_robot`` measures it. The retargeter sets the root height of every frame from the lowest
point of the foot geoms, and the quality numbers measure floor penetration with the lowest point
of all collision geoms.
"""

from __future__ import annotations

import mujoco
import numpy as np

from motion_env.replay.robot_kinematic import GeomPoints

__all__ = ["GeomPoints", "collision_geoms"]


def collision_geoms(model: mujoco.MjModel, bodies: list[int] | None = None) -> np.ndarray:
    """Geom ids of the collision geoms (contype or conaffinity set) on `bodies` (default: every
    body but the world); all their geoms when none collides."""
    on = np.isin(model.geom_bodyid, bodies) if bodies is not None else model.geom_bodyid > 0
    colliding = on & ((model.geom_contype != 0) | (model.geom_conaffinity != 0))
    return np.flatnonzero(colliding if colliding.any() else on)
