"""The body put on its path, compiled (numba): what :func:`local_pose_from_features`,
:func:`align_heading_to_travel`, :func:`recompose` and :func:`on_bone_lengths`
(:mod:`motion_env.generation.recompose`) do with numpy's and scipy's operations, frame by frame.

A stream's token composes four new frames from a window of about forty: on numpy that is some
four hundred operations on arrays of a few hundred numbers (the features' root integrated twice,
the heading unwrapped and smoothed, the path's direction of travel, six rounds of the bones'
lengths, the arms re-solved), 1.2 ms of the token as a quiet-machine equivalent, nearly all of it
dispatch. Compiled, a frame is its arithmetic. The operations are numpy's (and
``scipy.ndimage.gaussian_filter1d``'s, whose symmetric loop sums the two sides of each tap
first), in their order, on float64, rounded to float32 where numpy rounds: the same numbers to the
bit (``tests/generation/test_recompose.py``, ``tests/generation/test_feet.py``). The one matrix
product, of a bone-lengths round, stays numpy's, whose sums are the BLAS's.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from motion_env.generation.ik_jit import norm, solve
from motion_env.models.jit_math import clip, unwrap, wrap

__all__ = [
    "arms_on_lengths",
    "bone_excess",
    "gaussian_weights",
    "local_pose",
    "place_on_path",
    "smooth_paths",
    "travel_heading",
]


@lru_cache(maxsize=8)
def gaussian_weights(sigma: float) -> np.ndarray:
    """The taps ``scipy.ndimage.gaussian_filter1d(..., sigma)`` correlates with (truncated at 4
    sigma), computed as it computes them. One array per sigma, shared: not to be written to (numba
    would compile a second version for a read-only array)."""
    radius = int(4.0 * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1)
    phi = np.exp(-0.5 / (sigma * sigma) * x**2)
    return np.ascontiguousarray((phi / phi.sum())[::-1])


@njit(cache=True, nogil=True, error_model="numpy")
def _smooth(values, weights, out):
    """``gaussian_filter1d(values, mode="nearest")`` of a (T,) float64 line into `out`: scipy's
    symmetric correlation (the centre tap, then the two sides of each tap from the outermost in)."""
    half = weights.shape[0] // 2
    last = values.shape[0] - 1
    for i in range(values.shape[0]):
        total = values[i] * weights[half]
        for k in range(half, 0, -1):
            total += (values[max(i - k, 0)] + values[min(i + k, last)]) * weights[half - k]
        out[i] = total


@njit(cache=True, nogil=True, error_model="numpy")
def _joint(ric, t, j, root_x, root_z, c, s):
    """features_to_joints' joint j >= 1 at frame t: its float32 (x, y, z)."""
    x, y, z = np.float64(ric[t, 3 * j - 3]), np.float64(ric[t, 3 * j - 2]), np.float64(ric[t, 3 * j - 1])
    return np.float32(x * c + z * s + root_x), np.float32(y), np.float32(-x * s + z * c + root_z)


@njit(cache=True, nogil=True, error_model="numpy")
def local_pose(features, first, weights, face):
    """:func:`~motion_env.generation.recompose.local_pose_from_features` of (B, T, 263) float32
    `features`, frames first..: (B, T - first, 22, 3) float32, and whether every joint and path
    point the numpy path checks came out finite. `weights`: the heading's Gaussian taps
    (:func:`gaussian_weights` of HEADING_SMOOTH_SIGMA); `face`: FACE_JOINTS (right hip, left hip,
    right and left shoulder)."""
    batch, frames, joints = features.shape[0], features.shape[1], 22
    out = np.empty((batch, frames - first, joints, 3), np.float32)
    root_x, root_z, cos_h, sin_h = np.empty(frames), np.empty(frames), np.empty(frames), np.empty(frames)
    facing, unwrapped, smoothed = np.empty(frames), np.empty(frames), np.empty(frames)
    finite = True
    for b in range(batch):
        channels, ric = features[b, :, :4], features[b, :, 4:]
        half = 0.0
        for t in range(frames):
            # features_to_joints' root: the heading's half-angles summed, the steps turned and summed
            if t == 1:
                half = np.float64(channels[0, 0])
            elif t > 1:
                half += np.float64(channels[t - 1, 0])
            heading = -2.0 * half
            c, s = math.cos(heading), math.sin(heading)
            cos_h[t], sin_h[t] = c, s
            sx = np.float64(channels[t - 1, 1]) if t else 0.0
            sz = np.float64(channels[t - 1, 2]) if t else 0.0
            step_x, step_z = sx * c + sz * s, -sx * s + sz * c
            root_x[t] = root_x[t - 1] + step_x if t else step_x
            root_z[t] = root_z[t - 1] + step_z if t else step_z
            # root_path_from_joints' facing: the float32 hips' and shoulders' right-minus-left
            rh = _joint(ric, t, face[0], root_x[t], root_z[t], c, s)
            lh = _joint(ric, t, face[1], root_x[t], root_z[t], c, s)
            rs = _joint(ric, t, face[2], root_x[t], root_z[t], c, s)
            ls = _joint(ric, t, face[3], root_x[t], root_z[t], c, s)
            across_x = (np.float64(rh[0]) - np.float64(lh[0])) + (np.float64(rs[0]) - np.float64(ls[0]))
            across_z = (np.float64(rh[2]) - np.float64(lh[2])) + (np.float64(rs[2]) - np.float64(ls[2]))
            facing[t] = math.atan2(across_z, -across_x)
        unwrap(facing, unwrapped)
        _smooth(unwrapped, weights, smoothed)
        for t in range(first, frames):
            # local_pose_from_joints: the float32 path's pelvis taken off, its heading turned back
            path_x, path_z = np.float64(np.float32(root_x[t])), np.float64(np.float32(root_z[t]))
            turn = -np.float64(np.float32(smoothed[t]))
            finite = finite and math.isfinite(path_x) and math.isfinite(path_z) and math.isfinite(turn)
            c, s = math.cos(turn), math.sin(turn)
            for j in range(joints):
                if j == 0:
                    jx, jy, jz = np.float32(root_x[t]), np.float32(channels[t, 3]), np.float32(root_z[t])
                else:
                    jx, jy, jz = _joint(ric, t, j, root_x[t], root_z[t], cos_h[t], sin_h[t])
                finite = finite and math.isfinite(jx) and math.isfinite(jy) and math.isfinite(jz)
                lx, lz = np.float64(jx) - path_x, np.float64(jz) - path_z
                out[b, t - first, j, 0] = np.float32(lx * c + lz * s)
                out[b, t - first, j, 1] = jy
                out[b, t - first, j, 2] = np.float32(-lx * s + lz * c)
    return out, finite


@njit(cache=True, nogil=True, error_model="numpy")
def travel_heading(paths, speed_weights, angle_weights, ramp, max_offset, fps):  # noqa: PLR0913
    """:func:`~motion_env.generation.recompose.align_heading_to_travel` of (B, T, 3) float64
    `paths`: (B, T, 3) float32. `speed_weights` / `angle_weights`: the Gaussian taps of the travel's
    velocity (sigma 2) and of the correction (sigma 1); `ramp` (min_speed, full_speed - min_speed
    floored at 1e-6); `max_offset` in radians."""
    batch, frames = paths.shape[0], paths.shape[1]
    out = np.empty((batch, frames, 3), np.float32)
    vel_x, vel_z = np.empty(frames), np.empty(frames)
    smooth_x, smooth_z = np.empty(frames), np.empty(frames)
    weighted, correction = np.empty(frames), np.empty(frames)
    for b in range(batch):
        heading = paths[b, :, 2]
        if frames >= 2:
            for axis, vel in ((0, vel_x), (1, vel_z)):
                vel[0] = (paths[b, 1, axis] - paths[b, 0, axis]) / 1.0 * fps
                for t in range(1, frames - 1):
                    vel[t] = (paths[b, t + 1, axis] - paths[b, t - 1, axis]) / 2.0 * fps
                vel[frames - 1] = (paths[b, frames - 1, axis] - paths[b, frames - 2, axis]) / 1.0 * fps
            _smooth(vel_x, speed_weights, smooth_x)
            _smooth(vel_z, speed_weights, smooth_z)
        for t in range(frames):
            if frames >= 2:
                speed = math.sqrt(smooth_x[t] * smooth_x[t] + smooth_z[t] * smooth_z[t])
                travel = math.atan2(smooth_x[t], smooth_z[t])
            else:
                speed, travel = 0.0, heading[t]
            offset = wrap(travel - heading[t])
            w_speed = clip((speed - ramp[0]) / ramp[1], 0.0, 1.0)
            w_angle = clip((1.5 * max_offset - abs(offset)) / max_offset, 0.0, 1.0)
            weighted[t] = w_speed * w_angle * offset
        _smooth(weighted[:frames], angle_weights, correction)
        for t in range(frames):
            out[b, t, 0], out[b, t, 1] = np.float32(paths[b, t, 0]), np.float32(paths[b, t, 1])
            out[b, t, 2] = np.float32(heading[t] + correction[t])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def place_on_path(local, paths):
    """:func:`~motion_env.generation.recompose.recompose` (without facing the travel) of (B, T, 22,
    3) float64 `local` poses on (B, T, 3) float64 `paths`: (B, T, 22, 3) float32."""
    batch, frames, joints = local.shape[0], local.shape[1], local.shape[2]
    out = np.empty((batch, frames, joints, 3), np.float32)
    for b in range(batch):
        for t in range(frames):
            c, s = math.cos(paths[b, t, 2]), math.sin(paths[b, t, 2])
            px, pz = local[b, t, 0, 0], local[b, t, 0, 2]
            for j in range(joints):
                lx, lz = local[b, t, j, 0] - px, local[b, t, j, 2] - pz
                out[b, t, j, 0] = np.float32(lx * c + lz * s + paths[b, t, 0])
                out[b, t, j, 1] = np.float32(local[b, t, j, 1])
                out[b, t, j, 2] = np.float32(-lx * s + lz * c + paths[b, t, 1])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def bone_excess(x, target, children, parents):
    """One round of :func:`~motion_env.motion.kinematics.fit_bone_lengths` up to its matrix product:
    how much each bone of the joint-major float32 `x` (22, frames * 3) is too long by, (21, frames
    * 3) float32 (the bones `children` - `parents`, their lengths `target`)."""
    cols = x.shape[1]
    out = np.empty((children.shape[0], cols), np.float32)
    floor, one = np.float32(1e-9), np.float32(1.0)
    for i in range(children.shape[0]):
        c, p = children[i], parents[i]
        for k in range(0, cols, 3):
            b0, b1, b2 = x[c, k] - x[p, k], x[c, k + 1] - x[p, k + 1], x[c, k + 2] - x[p, k + 2]
            norm = np.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
            keep = one - target[i] / (norm if norm > floor else floor)
            out[i, k], out[i, k + 1], out[i, k + 2] = b0 * keep, b1 * keep, b2 * keep
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _rebuild(x, pelvis, lengths, rest, parents, out):
    """fit_bone_lengths' exact rebuild of frame f's joint-major float32 `x` (22, frames * 3) from
    `pelvis` (frames, 3) float64 outward, into `out` (frames, 22, 3) float64, rounded through float32
    as fit_bone_lengths returns it."""
    for f in range(out.shape[0]):
        k = 3 * f
        build = np.empty((22, 3))
        build[0, 0], build[0, 1], build[0, 2] = pelvis[f, 0], pelvis[f, 1], pelvis[f, 2]
        for j in range(1, 22):
            p = parents[j]
            v0 = np.float64(x[j, k]) - np.float64(x[p, k])
            v1 = np.float64(x[j, k + 1]) - np.float64(x[p, k + 1])
            v2 = np.float64(x[j, k + 2]) - np.float64(x[p, k + 2])
            size = norm(v0, v1, v2)
            if size > 1e-9:
                d0, d1, d2 = v0 / max(size, 1e-9), v1 / max(size, 1e-9), v2 / max(size, 1e-9)
            else:
                d0, d1, d2 = rest[j, 0], rest[j, 1], rest[j, 2]
            for a, d in ((0, d0), (1, d1), (2, d2)):
                build[j, a] = build[p, a] + d * lengths[j]
        for j in range(22):
            for a in range(3):
                out[f, j, a] = np.float64(np.float32(build[j, a]))


@njit(cache=True, nogil=True, error_model="numpy")
def _arm_length(joints, f, shoulder, elbow, wrist):
    """An arm's length in frame f: its upper arm's and its forearm's, as numpy sums them."""
    upper = norm(
        joints[f, elbow, 0] - joints[f, shoulder, 0], joints[f, elbow, 1] - joints[f, shoulder, 1],
        joints[f, elbow, 2] - joints[f, shoulder, 2],
    )  # fmt: skip
    fore = norm(
        joints[f, wrist, 0] - joints[f, elbow, 0], joints[f, wrist, 1] - joints[f, elbow, 1],
        joints[f, wrist, 2] - joints[f, elbow, 2],
    )  # fmt: skip
    return upper + fore


@njit(cache=True, nogil=True, error_model="numpy")
def _arm_goal(flat, dec, f, shoulder, elbow, wrist, other, side, scale_range):
    """on_bone_lengths' goal for one arm of frame f (the decoded wrist relative to the shoulder,
    scaled to the arm's length) and its bend hint (back and out): six numbers."""
    length = _arm_length(flat, f, shoulder, elbow, wrist)
    decoded = _arm_length(dec, f, shoulder, elbow, wrist)
    scale = clip(length / max(decoded, 1e-9), scale_range[0], scale_range[1])
    g0 = flat[f, shoulder, 0] + (dec[f, wrist, 0] - dec[f, shoulder, 0]) * scale
    g1 = flat[f, shoulder, 1] + (dec[f, wrist, 1] - dec[f, shoulder, 1]) * scale
    g2 = flat[f, shoulder, 2] + (dec[f, wrist, 2] - dec[f, shoulder, 2]) * scale
    o0, o1, o2 = flat[f, shoulder, 0] - flat[f, other, 0], 0.0, flat[f, shoulder, 2] - flat[f, other, 2]
    # np.cross(outward, (0, 1, 0)) times the side's sign, term by term as numpy takes them
    c0 = (o1 * 0.0 - o2 * 1.0) * side
    c1 = (o2 * 0.0 - o0 * 0.0) * side
    c2 = (o0 * 1.0 - o1 * 0.0) * side
    back, out = max(norm(c0, c1, c2), 1e-9), max(norm(o0, o1, o2), 1e-9)
    h0, h1, h2 = c0 / back + 0.5 * o0 / out, c1 / back + 0.5 * o1 / out, c2 / back + 0.5 * o2 / out
    return g0, g1, g2, h0, h1, h2


@njit(cache=True, nogil=True, error_model="numpy")
def arms_on_lengths(x, pelvis, dec, lengths, rest, parents, arms, sides, constants):
    """:func:`~motion_env.generation.recompose.on_bone_lengths` after fit_bone_lengths' rounds: the
    rounds' joint-major float32 `x` (22, N * 3) rebuilt on `lengths` from `pelvis` (N, 3), each arm
    re-solved for its decoded wrist (`dec`, (N, 22, 3) float64, the joints as they came), the
    elbows bent one way: (N, 22, 3) float32. `arms`: ARMS (2, 3); `sides`: the sign of each arm's
    back; `constants`: 1 / ARM_SCALE, ARM_SCALE, ARM_BEND_HINT, ARM_BEND_FILL, ELBOW_SAGITTAL,
    ELBOW_DOWN."""
    n = dec.shape[0]
    flat = np.empty((n, 22, 3))
    _rebuild(x, pelvis, lengths, rest, parents, flat)
    goals = np.empty((2, n, 6))
    for a in range(2):  # every goal first: the arms' IK reads the joints as rebuilt
        for f in range(n):
            goals[a, f] = _arm_goal(
                flat, dec, f, arms[a, 0], arms[a, 1], arms[a, 2], arms[1 - a, 0], sides[a], constants[:2]
            )
    for a in range(2):
        s, e, w = arms[a, 0], arms[a, 1], arms[a, 2]
        for f in range(n):
            g = goals[a, f]
            k = solve(
                flat[f, s, 0], flat[f, s, 1], flat[f, s, 2], flat[f, e, 0], flat[f, e, 1], flat[f, e, 2],
                flat[f, w, 0], flat[f, w, 1], flat[f, w, 2], g[0], g[1], g[2], g[3], g[4], g[5],
                True, constants[2], 0.0, constants[3],
            )  # fmt: skip
            flat[f, e, 0], flat[f, e, 1], flat[f, e, 2] = k[0], k[1], k[2]
            flat[f, w, 0], flat[f, w, 1], flat[f, w, 2] = k[3], k[4], k[5]
    _bend_elbows(flat, arms, constants[4], constants[5])
    out = np.empty((n, 22, 3), np.float32)
    for f in range(n):
        for j in range(22):
            for c in range(3):
                out[f, j, c] = np.float32(flat[f, j, c])
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _elbow_terms(flat, f, s, e, w, left):
    """bend_elbows_one_way's terms for one arm of frame f: the shoulder-wrist line's point
    nearest the elbow (3), the elbow's offset from it (3), the posterior (3), weight and wrong."""
    b0, b1, b2 = flat[f, s, 0], flat[f, s, 1], flat[f, s, 2]
    a0, a1, a2 = flat[f, w, 0] - b0, flat[f, w, 1] - b1, flat[f, w, 2] - b2
    size = max(norm(a0, a1, a2), 1e-9)
    a0, a1, a2 = a0 / size, a1 / size, a2 / size
    r0, r1, r2 = flat[f, e, 0] - b0, flat[f, e, 1] - b1, flat[f, e, 2] - b2
    dot = r0 * a0 + r1 * a1 + r2 * a2
    p0, p1, p2 = dot * a0, dot * a1, dot * a2
    o0, o1, o2 = r0 - p0, r1 - p1, r2 - p2
    l0, l1, l2 = left
    k0, k1, k2 = l1 * a2 - l2 * a1, l2 * a0 - l0 * a2, l0 * a1 - l1 * a0
    sagittal = norm(k0, k1, k2)
    floor = max(sagittal, 1e-9)
    k0, k1, k2 = k0 / floor, k1 / floor, k2 / floor
    return (b0 + p0, b1 + p1, b2 + p2, o0, o1, o2, k0, k1, k2, sagittal, -a1)


@njit(cache=True, nogil=True, error_model="numpy")
def _bend_elbows(flat, arms, sagittal_full, down_full):
    """:func:`~motion_env.generation.recompose.bend_elbows_one_way` of (N, 22, 3) float64, in place.
    As numpy's, every elbow is rewritten when any elbow of any frame moves (a moved elbow's
    arithmetic rounds the others' by the last bit)."""
    n = flat.shape[0]
    terms = np.empty((n, 2, 11))
    moves = False
    for f in range(n):
        right, left_shoulder = arms[0, 0], arms[1, 0]
        l0 = flat[f, right, 0] - flat[f, left_shoulder, 0]
        l2 = flat[f, right, 2] - flat[f, left_shoulder, 2]
        size = max(norm(l0, 0.0, l2), 1e-9)
        left = (l0 / size, 0.0 / size, l2 / size)
        for a in range(2):
            t = _elbow_terms(flat, f, arms[a, 0], arms[a, 1], arms[a, 2], left)
            for c in range(11):
                terms[f, a, c] = t[c]
            weight = clip((t[9] - 0.3) / (sagittal_full - 0.3), 0.0, 1.0)
            weight *= clip((t[10] - 0.2) / (down_full - 0.2), 0.0, 1.0)
            wrong = max(0.0, -(t[3] * t[6] + t[4] * t[7] + t[5] * t[8]))
            terms[f, a, 9], terms[f, a, 10] = weight, wrong
            moves = moves or weight * wrong != 0.0
    if not moves:
        return
    for f in range(n):
        for a in range(2):
            t = terms[f, a]
            push = 2.0 * t[9] * t[10]
            m0, m1, m2 = t[3] + push * t[6], t[4] + push * t[7], t[5] + push * t[8]
            size, radius = norm(m0, m1, m2), norm(t[3], t[4], t[5])
            if size > 1e-9:
                floor = max(size, 1e-9)
                m0, m1, m2 = m0 * radius / floor, m1 * radius / floor, m2 * radius / floor
            else:
                m0, m1, m2 = t[3], t[4], t[5]
            e = arms[a, 1]
            flat[f, e, 0], flat[f, e, 1], flat[f, e, 2] = t[0] + m0, t[1] + m1, t[2] + m2


@njit(cache=True, nogil=True, error_model="numpy")
def smooth_paths(paths, pad, weights):
    """:func:`~motion_env.generation.recompose.smooth_path` of (B, T, 3) float64 `paths`: each
    column extended by `pad` frames of odd reflection (``2 p[0] - p[k]``, as ``np.pad`` makes
    them), smoothed by the Gaussian `weights`, cut back to (B, T, 3) float64."""
    batch, frames = paths.shape[0], paths.shape[1]
    out = np.empty_like(paths)
    line, smoothed = np.empty(frames + 2 * pad), np.empty(frames + 2 * pad)
    for b in range(batch):
        for c in range(3):
            first, last = paths[b, 0, c], paths[b, frames - 1, c]
            for k in range(pad):
                line[k] = 2.0 * first - paths[b, pad - k, c]
                line[pad + frames + k] = 2.0 * last - paths[b, frames - 2 - k, c]
            for t in range(frames):
                line[pad + t] = paths[b, t, c]
            _smooth(line, weights, smoothed)
            for t in range(frames):
                out[b, t, c] = smoothed[pad + t]
    return out
