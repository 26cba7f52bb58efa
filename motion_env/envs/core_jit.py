"""The environments' per-frame bookkeeping compiled (numba): what :class:`CharacterBatch
<motion_env.envs.core.CharacterBatch>` does after each emitted frame (positions, velocities,
progress, route advance), with each action (the command's route test) and for each observation.

On numpy each is some thirty to sixty operations on arrays of a few numbers, whose dispatch (one
to five microseconds each) is nearly all of their time: about 0.2-0.3 ms a frame and as much an
observation, a tenth of one environment's step at one frame a step. Here each is one loop over
the characters. The same float64 operations in the same order, rounded to float32 where numpy
rounds: the same numbers to the bit (``tests/envs/test_core_jit.py``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from motion_env.models.jit_math import clip, wrap

__all__ = ["observe", "route_commands", "track_frame"]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _norm(x, z):
    """``np.linalg.norm`` of one (x, z) vector: the root of the sum of the squares in order."""
    return math.sqrt(x * x + z * z)


@njit(cache=True, nogil=True, error_model="numpy")
def track_frame(  # noqa: PLR0913 (one compiled loop: the parameters are the batch's arrays)
    rows, joints, root, frame, fresh, pos, theta, prev_pos, prev_theta, vel,
    route_arr, route_count, k, following, reached, command_xz, progress, arrivals, frames,
    arrive_radius, fps,
):  # fmt: skip
    """One emitted frame of characters `rows` (their (R, 22, 3) `joints`, (R, 3) `root` state
    and (R,) `frame` index): positions, velocities, route progress and route advance
    (``CharacterBatch.emit_frame`` and ``_advance_routes``), the batch's arrays in place."""
    last_slot = route_arr.shape[1]
    for i in range(rows.shape[0]):
        b = rows[i]
        x, z, heading = np.float64(joints[i, 0, 0]), np.float64(joints[i, 0, 2]), np.float64(root[i, 2])
        if fresh[b]:
            px, pz, ptheta = x, z, heading
        else:
            px, pz, ptheta = pos[b, 0], pos[b, 1], theta[b]
        prev_pos[b, 0], prev_pos[b, 1], prev_theta[b] = px, pz, ptheta
        pos[b, 0], pos[b, 1], theta[b] = x, z, heading
        fresh[b] = False
        dx, dz = x - px, z - pz
        c, s = math.cos(heading), math.sin(heading)
        vel[b, 0] = (dx * c - dz * s) * fps
        vel[b, 1] = (dx * s + dz * c) * fps
        vel[b, 2] = wrap(heading - ptheta) * fps
        tx, tz = route_arr[b, k[b], 0], route_arr[b, k[b], 1]
        progress[b] += _norm(px - tx, pz - tz) - _norm(x - tx, z - tz)
        frames[b] += 1.0
        # The route target is passed when reached, or when its time comes while following.
        slot, count, passed = k[b], route_count[b], 0.0
        for _ in range(last_slot):
            if slot >= count - 1:
                break
            wx, wz, wt = route_arr[b, slot, 0], route_arr[b, slot, 1], route_arr[b, slot, 2]
            hit = _norm(x - wx, z - wz) < arrive_radius
            late = not hit and following[b] and not math.isnan(wt) and frame[i] >= wt
            if not (hit or late):
                break
            passed += 1.0 if hit else 0.0
            slot += 1
        final = (
            slot == count - 1
            and not reached[b]
            and _norm(x - route_arr[b, count - 1, 0], z - route_arr[b, count - 1, 1]) < arrive_radius
        )
        k[b] = slot
        arrivals[b] += passed + (1.0 if final else 0.0)
        reached[b] = reached[b] or final
        if following[b]:
            command_xz[b, 0], command_xz[b, 1] = route_arr[b, slot, 0], route_arr[b, slot, 1]


@njit(cache=True, nogil=True, error_model="numpy")
def route_commands(points, apply, route_arr, route_count, k, following, command_xz, snap_radius, tolerance):
    """What each character's command point (`points` (B, 2) world x, z, where `apply` (B,))
    asks (``CharacterBatch.command``): -1 nothing new, j >= 0 follow the route from waypoint j
    (k, following and the command updated here), -2 a detour to the point (the same); (B,) int64."""
    out = np.full(points.shape[0], -1, np.int64)
    for b in range(points.shape[0]):
        if not apply[b]:
            continue
        x, z = points[b, 0], points[b, 1]
        for j in range(k[b], route_count[b]):
            if _norm(route_arr[b, j, 0] - x, route_arr[b, j, 1] - z) <= snap_radius:
                if not (following[b] and j == k[b]):  # not "keep following the route"
                    k[b], following[b] = j, True
                    command_xz[b, 0], command_xz[b, 1] = route_arr[b, j, 0], route_arr[b, j, 1]
                    out[b] = j
                break
        else:
            if following[b] or _norm(x - command_xz[b, 0], z - command_xz[b, 1]) > tolerance:
                following[b] = False
                command_xz[b, 0], command_xz[b, 1] = x, z
                out[b] = -2
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _local(dx, dz, c, s):
    """``to_heading_frame`` of one (dx, dz) vector, given the heading's cosine and sine."""
    return dx * c - dz * s, dx * s + dz * c


@njit(cache=True, nogil=True, error_model="numpy")
def observe(  # noqa: PLR0913 (one compiled loop: the parameters are the batch's arrays)
    joints, pos, theta, vel, route_arr, route_count, k, following, ahead_count,
    max_coordinate, target_bound, ahead_bound, velocity_bound, pose_bound,
    root_out, target_out, ahead_out, state_out, velocity_out, pose_out,
):  # fmt: skip
    """``CharacterBatch.observations`` without the caption, into the float32 outputs (B, ...)."""
    for b in range(pos.shape[0]):
        x, z, heading = pos[b, 0], pos[b, 1], theta[b]
        c, s = math.cos(heading), math.sin(heading)
        root_out[b, 0] = np.float32(clip(x, -max_coordinate, max_coordinate))
        root_out[b, 1] = np.float32(clip(z, -max_coordinate, max_coordinate))
        root_out[b, 2], root_out[b, 3] = np.float32(c), np.float32(s)
        last = route_count[b] - 1
        lx, lz = _local(route_arr[b, k[b], 0] - x, route_arr[b, k[b], 1] - z, c, s)
        target_out[b, 0] = np.float32(clip(lx, -target_bound, target_bound))
        target_out[b, 1] = np.float32(clip(lz, -target_bound, target_bound))
        for a in range(ahead_count):
            j = min(k[b] + 1 + a, last)
            lx, lz = _local(route_arr[b, j, 0] - x, route_arr[b, j, 1] - z, c, s)
            ahead_out[b, 2 * a] = np.float32(clip(lx, -ahead_bound, ahead_bound))
            ahead_out[b, 2 * a + 1] = np.float32(clip(lz, -ahead_bound, ahead_bound))
        state_out[b, 0] = 1.0 if following[b] else 0.0
        state_out[b, 1] = 1.0 if k[b] == last else 0.0
        state_out[b, 2] = np.float32(min(last - k[b], ahead_count) / ahead_count)
        for d in range(3):
            velocity_out[b, d] = np.float32(clip(vel[b, d], -velocity_bound, velocity_bound))
        for j in range(joints.shape[1]):
            lx, lz = _local(np.float64(joints[b, j, 0]) - x, np.float64(joints[b, j, 2]) - z, c, s)
            pose_out[b, 3 * j] = np.float32(clip(lx, -pose_bound, pose_bound))
            pose_out[b, 3 * j + 1] = np.float32(clip(np.float64(joints[b, j, 1]), -pose_bound, pose_bound))
            pose_out[b, 3 * j + 2] = np.float32(clip(lz, -pose_bound, pose_bound))
