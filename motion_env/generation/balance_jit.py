"""The floor's push compiled (numba): what :func:`~motion_env.generation.balance._wanted_push`
does with numpy's operations, frame by frame.

On numpy a stream token's push is some fifty operations on the support polygon of its frames
(every segment between the four sole points, every triangle of them): 0.3 ms of a stream's token
as a quiet-machine equivalent, nearly all dispatch. Compiled, a frame is its arithmetic. The
operations are numpy's, in its order, on float64 (NaN where numpy's would give NaN: a stream's
first token reads frames not emitted yet, whose equations the balance then drops): the same
numbers to the bit (``tests/generation/test_balance.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.models.jit_math import clip

__all__ = ["wanted_push"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _side(p0x, p0y, p1x, p1y, rx, ry):
    """balance._in_triangle's side of r against the line p0 -> p1."""
    return (p1x - p0x) * (ry - p0y) - (p1y - p0y) * (rx - p0x)


@njit(cache=True, nogil=True, error_model="numpy")
def _pressure_point(wx, wy, points, bearing, pairs, triangles):
    """balance._pressure_point of one frame: the point of the support polygon nearest to (wx, wy)."""
    any_bearing = False
    for s in range(points.shape[0]):
        any_bearing = any_bearing or bearing[s]
    if not any_bearing:
        return wx, wy
    for n in range(triangles.shape[0]):
        a, b, c = triangles[n, 0], triangles[n, 1], triangles[n, 2]
        if not (bearing[a] and bearing[b] and bearing[c]):
            continue
        ax, ay, bx, by = points[a, 0], points[a, 1], points[b, 0], points[b, 1]
        cx, cy = points[c, 0], points[c, 1]
        area = _side(ax, ay, bx, by, cx, cy)
        s1 = _side(ax, ay, bx, by, wx, wy) * area
        s2 = _side(bx, by, cx, cy, wx, wy) * area
        s3 = _side(cx, cy, ax, ay, wx, wy) * area
        if abs(area) > 1e-8 and s1 >= 0 and s2 >= 0 and s3 >= 0:
            return wx, wy
    best, best_x, best_y = np.inf, 0.0, 0.0
    found = False
    for n in range(pairs.shape[0]):
        a, b = pairs[n, 0], pairs[n, 1]
        abx, aby = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1]
        along = ((wx - points[a, 0]) * abx + (wy - points[a, 1]) * aby) / max(abx * abx + aby * aby, 1e-12)
        t = clip(along, 0.0, 1.0)
        nx, ny = points[a, 0] + t * abx, points[a, 1] + t * aby
        d = (nx - wx) ** 2 + (ny - wy) ** 2 if bearing[a] and bearing[b] else np.inf
        # np.argmin: the first NaN, else the first smallest (segment 0 where every one is inf)
        if not found and (math.isnan(d) or d < best or n == 0):
            best, best_x, best_y = d, nx, ny
            found = math.isnan(d)
    return best_x, best_y


@njit(cache=True, nogil=True, error_model="numpy")
def wanted_push(c, accel, k, points, bearing, pairs, triangles):
    """balance._wanted_push of M frames: centre of mass `c` (M, 3), acceleration `accel` (M, 3),
    stiffness `k` (M,), sole points (M, 4, 2) and which bear weight (M, 4) -> (M, 2)."""
    out = np.empty((c.shape[0], 2))
    for m in range(c.shape[0]):
        safe = k[m] if k[m] > 0.0 else 1.0
        cx, cz = c[m, 0], c[m, 2]
        px, pz = _pressure_point(
            cx - accel[m, 0] / safe, cz - accel[m, 2] / safe, points[m], bearing[m], pairs, triangles
        )
        if k[m] > 0.0:
            out[m, 0], out[m, 1] = k[m] * (cx - px), k[m] * (cz - pz)
        else:
            out[m, 0], out[m, 1] = 0.0, 0.0
    return out
