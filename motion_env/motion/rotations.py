"""Rotations: quaternions ``(..., 4)`` as ``(w, x, y, z)``, matrices, axis-angle and 6-D (numpy).

- rotation matrices ``(..., 3, 3)`` act on column vectors;
- the 6-D representation is HumanML3D's ``cont6d``: the first two *columns* of the matrix,
  concatenated, ``(..., 6)``.
"""

from __future__ import annotations

import numpy as np

from motion_env.motion.validation import EPS, check_last

__all__ = [
    "cross",
    "matrix_to_rot6d",
    "qbetween",
    "qfix",
    "qinv",
    "qmul",
    "qnormalize",
    "qrot",
    "quat_from_axis_angle",
    "quat_from_matrix",
    "quat_from_yaw",
    "quat_to_axis_angle",
    "quat_to_matrix",
    "quat_to_rot6d",
    "rot6d_to_matrix",
    "rot6d_to_quat",
    "vector_norm",
]


# np.linalg.norm and np.cross cost 5-20 microseconds a call in checks and dispatch, more than the
# arithmetic on the few vectors of a stream's token (the legs' re-solve calls them thousands of
# times a second); these two do the same operations in the same order, so the numbers are the same.
def vector_norm(v: np.ndarray, keepdims: bool = False) -> np.ndarray:
    """Euclidean length over the last axis: ``np.linalg.norm(v, axis=-1)``, the same numbers."""
    return np.sqrt((v * v).sum(-1, keepdims=keepdims))


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of (..., 3) vectors, shapes broadcast: ``np.cross(a, b)``, the same numbers."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def qnormalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4)."""
    q = check_last(q, 4, "q")
    return q / np.maximum(vector_norm(q, keepdims=True), EPS)


def qinv(q: np.ndarray) -> np.ndarray:
    """Inverse (conjugate) of unit quaternions (..., 4)."""
    q = check_last(q, 4, "q")
    return q * np.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype if q.dtype.kind == "f" else np.float64)


def qmul(q: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Hamilton product ``q * r`` (apply r, then q); shapes broadcast, (..., 4)."""
    q = check_last(q, 4, "q")
    r = check_last(r, 4, "r")
    w1, x1, y1, z1 = np.moveaxis(q, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(r, -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def qrot(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by unit quaternions q (..., 4); shapes broadcast."""
    q = check_last(q, 4, "q")
    v = check_last(v, 3, "v")
    qvec = q[..., 1:]
    uv = cross(qvec, v)
    uuv = cross(qvec, uv)
    return v + 2.0 * (q[..., :1] * uv + uuv)


def qbetween(v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """The shortest-arc unit quaternion rotating direction v0 onto v1, (..., 3) -> (..., 4).

    Same formula as HumanML3D's ``qbetween``; for opposite directions (where that formula is
    0/0) it returns a half turn about an axis perpendicular to v0.
    """
    v0 = check_last(v0, 3, "v0").astype(np.float64)
    v1 = check_last(v1, 3, "v1").astype(np.float64)
    v0, v1 = np.broadcast_arrays(v0, v1)
    w = np.sqrt((v0**2).sum(-1, keepdims=True) * (v1**2).sum(-1, keepdims=True)) + (v0 * v1).sum(
        -1, keepdims=True
    )
    q = np.concatenate([w, cross(v0, v1)], axis=-1)
    norm = vector_norm(q, keepdims=True)
    scale = np.sqrt((v0**2).sum(-1, keepdims=True) * (v1**2).sum(-1, keepdims=True))
    opposite = (norm < 1e-6 * np.maximum(scale, EPS))[..., 0]
    if opposite.any():
        # Any axis perpendicular to v0 works; cross with the coordinate axis least aligned to it.
        a = v0[opposite]
        helper = np.eye(3)[np.argmin(np.abs(a), axis=-1)]
        axis = cross(a, helper)
        axis /= np.maximum(vector_norm(axis, keepdims=True), EPS)
        q = q.copy()
        q[opposite] = np.concatenate([np.zeros(axis.shape[:-1] + (1,)), axis], axis=-1)
        norm = vector_norm(q, keepdims=True)
    return q / np.maximum(norm, EPS)


def qfix(q: np.ndarray) -> np.ndarray:
    """Flip signs along axis 0 (time) so consecutive quaternions have a non-negative dot product.

    q: (T, ..., 4). Returns the same rotations, continuous in time (as HumanML3D's ``qfix``).
    """
    q = check_last(q, 4, "q")
    if q.ndim < 2:
        raise ValueError(f"qfix needs a time axis: q must have shape (T, ..., 4), got {q.shape}")
    dots = (q[1:] * q[:-1]).sum(-1)
    flip = np.cumsum(dots < 0, axis=0) % 2 == 1
    out = q.copy()
    out[1:][flip] *= -1
    return out


def quat_from_yaw(theta: np.ndarray) -> np.ndarray:
    """Rotations about +Y by angle θ (...,) -> (..., 4); θ = heading maps +Z onto the facing."""
    theta = np.asarray(theta, dtype=np.float64)
    zeros = np.zeros_like(theta)
    return np.stack([np.cos(theta / 2), zeros, np.sin(theta / 2), zeros], axis=-1)


def quat_from_axis_angle(axis_angle: np.ndarray) -> np.ndarray:
    """Axis-angle vectors (..., 3) (direction = axis, norm = angle in radians) -> (..., 4)."""
    aa = check_last(axis_angle, 3, "axis_angle").astype(np.float64)
    angle = vector_norm(aa, keepdims=True)
    # sin(a/2)/a written with np.sinc so that a -> 0 is exact (sinc(x) = sin(pi x)/(pi x)).
    return np.concatenate([np.cos(angle / 2), 0.5 * np.sinc(angle / (2 * np.pi)) * aa], axis=-1)


def quat_to_axis_angle(q: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) -> axis-angle vectors (..., 3), angles in [0, π]."""
    q = qnormalize(q).astype(np.float64)
    q = np.where(q[..., :1] < 0, -q, q)  # pick the representative with angle <= π
    sin_half = vector_norm(q[..., 1:], keepdims=True)
    angle = 2.0 * np.arctan2(sin_half, q[..., :1])
    scale = np.where(sin_half > 1e-12, angle / np.maximum(sin_half, 1e-12), 2.0)
    return q[..., 1:] * scale


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) (normalised here) -> rotation matrices (..., 3, 3)."""
    q = check_last(q, 4, "q").astype(np.float64)
    w, x, y, z = np.moveaxis(q, -1, 0)
    two_s = 2.0 / np.maximum((q * q).sum(-1), EPS)
    m = np.stack(
        [
            1 - two_s * (y * y + z * z), two_s * (x * y - z * w), two_s * (x * z + y * w),
            two_s * (x * y + z * w), 1 - two_s * (x * x + z * z), two_s * (y * z - x * w),
            two_s * (x * z - y * w), two_s * (y * z + x * w), 1 - two_s * (x * x + y * y),
        ],
        axis=-1,
    )  # fmt: skip
    return m.reshape(q.shape[:-1] + (3, 3))


def quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (..., 4) with w >= 0."""
    m = np.asarray(m, dtype=np.float64)
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must have shape (..., 3, 3), got {m.shape}")
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    # Four candidate solutions, each well conditioned when its |component| is largest.
    cands = np.stack(
        [
            np.stack([1 + m00 + m11 + m22, m21 - m12, m02 - m20, m10 - m01], -1),
            np.stack([m21 - m12, 1 + m00 - m11 - m22, m01 + m10, m02 + m20], -1),
            np.stack([m02 - m20, m01 + m10, 1 - m00 + m11 - m22, m12 + m21], -1),
            np.stack([m10 - m01, m02 + m20, m12 + m21, 1 - m00 - m11 + m22], -1),
        ],
        axis=-2,
    )  # (..., 4 candidates, 4)
    diag = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)
    best = np.argmax(diag, axis=-1)
    q = np.take_along_axis(cands, best[..., None, None], axis=-2)[..., 0, :]
    q = qnormalize(q)
    return np.where(q[..., :1] < 0, -q, q)


def matrix_to_rot6d(m: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> HumanML3D 6-D (first two columns), (..., 6)."""
    m = np.asarray(m)
    if m.ndim < 2 or m.shape[-2:] != (3, 3):
        raise ValueError(f"rotation matrices must have shape (..., 3, 3), got {m.shape}")
    return np.concatenate([m[..., :, 0], m[..., :, 1]], axis=-1)


def rot6d_to_matrix(d6: np.ndarray) -> np.ndarray:
    """HumanML3D 6-D (..., 6) -> rotation matrices (..., 3, 3) by Gram-Schmidt (``cont6d_to_matrix``)."""
    d6 = check_last(d6, 6, "rot6d").astype(np.float64)
    x = d6[..., :3] / np.maximum(vector_norm(d6[..., :3], keepdims=True), EPS)
    z = cross(x, d6[..., 3:])
    z /= np.maximum(vector_norm(z, keepdims=True), EPS)
    y = cross(z, x)
    return np.stack([x, y, z], axis=-1)


def quat_to_rot6d(q: np.ndarray) -> np.ndarray:
    """Quaternions (..., 4) -> 6-D (..., 6)."""
    return matrix_to_rot6d(quat_to_matrix(q))


def rot6d_to_quat(d6: np.ndarray) -> np.ndarray:
    """6-D (..., 6) -> unit quaternions (..., 4), w >= 0."""
    return quat_from_matrix(rot6d_to_matrix(d6))
