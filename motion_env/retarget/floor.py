"""Where a robot meets the floor: the lowest point of its geoms, frame by frame.

:class:`GeomSet` holds the shape of a set of geoms once (primitive sizes; for a mesh, the
vertices of its convex hull, which MuJoCo computed for collisions, or all of them) and turns the
geoms' world poses of a clip into the height of each geom's lowest point. The retargeter sets the
root height of every frame from the lowest point of the foot geoms, and the quality numbers
measure floor penetration with the lowest point of all collision geoms.
"""

from __future__ import annotations

import mujoco
import numpy as np

__all__ = ["GeomSet", "collision_geoms"]

_T = mujoco.mjtGeom


def collision_geoms(model: mujoco.MjModel, bodies: list[int] | None = None) -> np.ndarray:
    """Geom ids of the collision geoms (contype or conaffinity set) on `bodies` (default: every
    body but the world); all their geoms when none collides."""
    on = np.isin(model.geom_bodyid, bodies) if bodies is not None else model.geom_bodyid > 0
    colliding = on & ((model.geom_contype != 0) | (model.geom_conaffinity != 0))
    return np.flatnonzero(colliding if colliding.any() else on)


def _mesh_points(model: mujoco.MjModel, mesh: int) -> np.ndarray:
    """(V, 3) vertices of a mesh in its geom's frame: the convex hull's when MuJoCo has one."""
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    verts = model.mesh_vert[start : start + count]
    graph = model.mesh_graphadr[mesh]
    if graph >= 0:
        # mesh_graph: numvert, numface, vert_edgeadr[numvert], vert_globalid[numvert], ...
        num = model.mesh_graph[graph]
        ids = model.mesh_graph[graph + 2 + num : graph + 2 + 2 * num]
        verts = verts[ids]
    return np.asarray(verts, dtype=np.float64)


class GeomSet:
    """The lowest point of each of a set of geoms, for many frames at once."""

    def __init__(self, model: mujoco.MjModel, geoms: np.ndarray) -> None:
        self.ids = np.asarray(geoms, dtype=int)
        self.types = model.geom_type[self.ids].copy()
        self.sizes = model.geom_size[self.ids].copy()
        self.points = {
            k: _mesh_points(model, model.geom_dataid[g])
            for k, g in enumerate(self.ids)
            if self.types[k] in (_T.mjGEOM_MESH, _T.mjGEOM_SDF) and model.geom_dataid[g] >= 0
        }

    def lowest(self, xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
        """Height of each geom's lowest point, (T, G).

        xpos: (T, G, 3) geom positions; xmat: (T, G, 9) geom orientations (MuJoCo's row-major
        ``geom_xmat`` of these geoms).
        """
        z = xpos[..., 2].copy()
        down = xmat[..., 6:9]  # (T, G, 3): the third row, how each local axis projects on world z
        for k, kind in enumerate(self.types):
            s, d = self.sizes[k], np.abs(down[:, k])
            if kind == _T.mjGEOM_SPHERE:
                z[:, k] -= s[0]
            elif kind == _T.mjGEOM_CAPSULE:
                z[:, k] -= d[:, 2] * s[1] + s[0]
            elif kind == _T.mjGEOM_CYLINDER:
                z[:, k] -= d[:, 2] * s[1] + s[0] * np.sqrt(np.clip(1.0 - d[:, 2] ** 2, 0.0, 1.0))
            elif kind == _T.mjGEOM_BOX:
                z[:, k] -= d @ s
            elif kind == _T.mjGEOM_ELLIPSOID:
                z[:, k] -= np.sqrt(((d * s) ** 2).sum(-1))
            elif k in self.points:
                z[:, k] += (down[:, k] @ self.points[k].T).min(axis=1)
            # planes, heightfields and SDFs without vertices are left at their origin
        return z
