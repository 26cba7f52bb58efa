"""Closed-form refinement: the body on the root path, waypoints hit exactly, feet that stay put.

- :func:`recompose` places a *local pose* (the body relative to its root, in its own heading
  frame: what the body GPT decodes) on a root path from the controller, so the pelvis lies exactly
  on the path and the body faces its direction of travel.
- :func:`snap_to_waypoints` bends a root path so it passes exactly through the waypoints.
- :func:`clean_foot_contacts` pins feet in contact and re-solves the legs with two-bone IK.
- :func:`foot_skating_ratio` measures foot skating as PRODUCT.md defines it.

All functions are deterministic numpy; root paths follow :mod:`motion_env.paths`.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.ndimage import gaussian_filter1d

from motion_env.motion import features_to_joints, rotate_y
from motion_env.paths import root_path_from_joints, validate_root_path, validate_waypoints, wrap_angle
from motion_env.skeleton import FOOT_JOINTS, FPS, NUM_JOINTS

# Legs as (hip, knee, ankle, toe).
LEGS: tuple[tuple[int, int, int, int], ...] = ((1, 4, 7, 10), (2, 5, 8, 11))

# PRODUCT.md's foot skating: a foot joint below this height (m) ...
SKATE_HEIGHT = 0.05
# ... that moves more than this (m) horizontally from the previous frame (at 20 fps).
SKATE_STEP = 0.025


def _check_joints(joints: np.ndarray, name: str = "joints") -> np.ndarray:
    joints = np.asarray(joints, dtype=np.float64)
    if joints.ndim != 3 or joints.shape[1:] != (NUM_JOINTS, 3) or joints.shape[0] < 1:
        raise ValueError(f"{name} must have shape (T, {NUM_JOINTS}, 3) with T >= 1, got {joints.shape}")
    return joints


# ----------------------------------------------------------------------------------------------
# The body on the path
# ----------------------------------------------------------------------------------------------


def local_pose_from_joints(joints: np.ndarray, root_path: np.ndarray | None = None) -> np.ndarray:
    """The body relative to its root path: pelvis XZ at the origin, heading turned to +Z.

    Args:
        joints: (T, 22, 3) world joint positions.
        root_path: (T, 3) the path to factor out; default :func:`paths.root_path_from_joints`.

    Returns:
        (T, 22, 3) float32 local pose (joint heights unchanged; the pelvis is at x = z = 0).
    """
    joints = _check_joints(joints)
    path = root_path_from_joints(joints) if root_path is None else validate_root_path(root_path)
    if path.shape[0] != joints.shape[0]:
        raise ValueError(f"root_path has {path.shape[0]} frames, joints {joints.shape[0]}")
    local = joints.copy()
    local[..., [0, 2]] -= path[:, None, :2].astype(np.float64)
    return rotate_y(local, -path[:, None, 2].astype(np.float64)).astype(np.float32)


def local_pose_from_features(features: np.ndarray) -> np.ndarray:
    """Local pose of decoded 263-d features (T, 263) -> (T, 22, 3).

    The features are turned into joints with :func:`motion.features_to_joints` (their own root
    trajectory), whose root path is then factored out again with :func:`local_pose_from_joints`.
    Going through joints, rather than reading the RIC channels directly, expresses the body in the
    same (smoothed hips-and-shoulders) heading frame the controller is trained on, so the body
    neither gains nor loses a twist when it is put back on a path.
    """
    return local_pose_from_joints(features_to_joints(np.asarray(features, dtype=np.float32)))


def _travel(root_path: np.ndarray, sigma: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) and direction of travel (heading convention) per frame of a root path."""
    vel = np.gradient(root_path[:, :2].astype(np.float64), axis=0) * FPS if len(root_path) > 1 else None
    if vel is None:
        return np.zeros(1), root_path[:, 2].astype(np.float64)
    vel = gaussian_filter1d(vel, sigma, axis=0, mode="nearest")
    return np.linalg.norm(vel, axis=1), np.arctan2(vel[:, 0], vel[:, 1])


def align_heading_to_travel(
    root_path: np.ndarray, min_speed: float = 0.3, full_speed: float = 0.6, max_offset_deg: float = 45.0
) -> np.ndarray:
    """Turn the heading of a root path to its direction of travel where the body walks forward.

    Where the path moves (speed ramping from `min_speed` to `full_speed` m/s) and its heading is
    within `max_offset_deg` / 2 of the direction of travel, the heading is replaced by that
    direction (so a forward walk never glides sideways); the correction fades out up to 1.5 *
    `max_offset_deg`, beyond which the offset is deliberate (side steps, walking backwards) and
    kept. Still frames keep their heading (no spin on the spot).

    Returns:
        (T, 3) float32 root path with the new (unwrapped) heading.
    """
    path = validate_root_path(root_path).astype(np.float64)
    speed, travel = _travel(path)
    offset = wrap_angle(travel - path[:, 2])
    lim = np.deg2rad(max_offset_deg)
    w_speed = np.clip((speed - min_speed) / max(full_speed - min_speed, 1e-6), 0.0, 1.0)
    w_angle = np.clip((1.5 * lim - np.abs(offset)) / lim, 0.0, 1.0)
    correction = gaussian_filter1d(w_speed * w_angle * offset, 1.0, mode="nearest")
    out = path.copy()
    out[:, 2] = path[:, 2] + correction
    return out.astype(np.float32)


def recompose(local_pose: np.ndarray, root_path: np.ndarray, face_travel: bool = True) -> np.ndarray:
    """Place a local pose on a root path.

    Args:
        local_pose: (T, 22, 3) the body relative to its root in its own heading frame (facing +Z,
            pelvis at x = z = 0; heights absolute), e.g. :func:`local_pose_from_features` of the
            body GPT's decoded features. Any pelvis XZ left in it is removed.
        root_path: (T, 3) x, z, heading from the path controller.
        face_travel: first turn the heading to the direction of travel where the body moves
            forward (:func:`align_heading_to_travel`).

    Returns:
        (T, 22, 3) float32 world joints: pelvis XZ exactly on the path, legs, height and limbs
        from the local pose.
    """
    local = _check_joints(local_pose, "local_pose").copy()
    path = validate_root_path(root_path)
    if path.shape[0] != local.shape[0]:
        raise ValueError(f"root_path has {path.shape[0]} frames, local_pose {local.shape[0]}")
    if face_travel:
        path = align_heading_to_travel(path)
    local[..., [0, 2]] -= local[:, :1, [0, 2]]
    joints = rotate_y(local, path[:, None, 2].astype(np.float64))
    joints[..., [0, 2]] += path[:, None, :2].astype(np.float64)
    return joints.astype(np.float32)


# ----------------------------------------------------------------------------------------------
# Waypoint snapping
# ----------------------------------------------------------------------------------------------


def waypoint_frames(root_path: np.ndarray, waypoints: np.ndarray | list) -> np.ndarray:
    """The frame at which a path passes each waypoint: (K,) int, -1 for timed ones past the end.

    Timed waypoints: their time rounded to a frame. Untimed: the closest approach, searched from
    the previous waypoint's frame on.
    """
    path = validate_root_path(root_path)
    wp = validate_waypoints(waypoints)
    last = path.shape[0] - 1
    frames = np.full(len(wp), -1, np.int64)
    after = 0
    for k, (x, z, t) in enumerate(wp):
        if np.isnan(t):
            dist = np.linalg.norm(path[after:, :2] - (x, z), axis=1)
            frames[k] = after + int(np.argmin(dist))
        elif int(np.rint(t)) <= last:
            frames[k] = int(np.rint(t))
        if frames[k] >= 0:
            after = int(frames[k])
    return frames


def snap_to_waypoints(
    root_path: np.ndarray, waypoints: np.ndarray | list, keep_start: bool = True
) -> np.ndarray:
    """Bend a root path so it passes exactly through its waypoints.

    The residual (waypoint - path) at each waypoint's frame (:func:`waypoint_frames`) becomes an
    offset curve, interpolated between waypoint frames with a monotone piecewise cubic (PCHIP: C1,
    no overshoot, a steady drift is corrected at a steady rate) and held after the last one. The
    heading turns with the change of the direction of travel, so a body that walked forward still
    does. Timed waypoints past the end of the path are ignored.

    Args:
        root_path: (T, 3) x, z, heading.
        waypoints: (K, 2) or (K, 3), see :func:`paths.validate_waypoints`.
        keep_start: frame 0 stays where it is (the character's current position) unless a
            waypoint is timed at frame 0.

    Returns:
        (T, 3) float32 snapped root path.
    """
    path = validate_root_path(root_path).astype(np.float64)
    wp = validate_waypoints(waypoints).astype(np.float64)
    frames = waypoint_frames(path, wp)
    anchors: dict[int, np.ndarray] = {}
    if keep_start:
        anchors[0] = np.zeros(2)
    for k, f in enumerate(frames):
        if f >= 0:
            anchors[int(f)] = wp[k, :2] - path[f, :2]  # a later waypoint on the same frame wins
    if not anchors:
        return path.astype(np.float32)
    keys = np.array(sorted(anchors))
    res = np.stack([anchors[k] for k in keys])
    if keep_start and keys[0] == 0 and not res[0].any():
        # A still anchor just before the start: PCHIP then leaves frame 0's velocity unchanged too.
        keys, res = np.concatenate([[-1], keys]), np.concatenate([np.zeros((1, 2)), res])
    t = np.arange(path.shape[0])
    if len(keys) == 1:
        offset = np.repeat(res, path.shape[0], axis=0)
    else:
        offset = PchipInterpolator(keys, res, axis=0)(np.clip(t, keys[0], keys[-1]))
    out = path.copy()
    out[:, :2] += offset
    speed0, travel0 = _travel(path)
    speed1, travel1 = _travel(out)
    moving = np.clip((np.minimum(speed0, speed1) - 0.1) / 0.3, 0.0, 1.0)
    turn = gaussian_filter1d(moving * wrap_angle(travel1 - travel0), 1.0, mode="nearest")
    if keep_start:
        turn *= np.clip(t / 4.0, 0.0, 1.0)  # the current frame's heading stays, then eases in
    out[:, 2] += turn
    return out.astype(np.float32)


# ----------------------------------------------------------------------------------------------
# Foot contacts
# ----------------------------------------------------------------------------------------------


def foot_skating_ratio(joints: np.ndarray, height: float = SKATE_HEIGHT, step: float = SKATE_STEP) -> float:
    """Share of frames in which a foot joint (ankle or toe) below `height` m moves more than `step` m.

    PRODUCT.md's definition: frame t (t >= 1) skates when any of the four foot joints is below
    `height` at t and its XZ moved more than `step` from t-1 (20 fps). Returns 0 for a single frame.
    """
    joints = _check_joints(joints)
    if joints.shape[0] < 2:
        return 0.0
    feet = joints[:, list(FOOT_JOINTS)]  # (T, 4, 3)
    low = feet[1:, :, 1] < height
    moved = np.linalg.norm(feet[1:, :, [0, 2]] - feet[:-1, :, [0, 2]], axis=-1) > step
    return float((low & moved).any(axis=1).mean())


def detect_foot_contacts(joints: np.ndarray, margin: float = 0.03, max_speed: float = 1.0) -> np.ndarray:
    """Foot contacts from height and speed: (T, 22, 3) -> (T, 4) bool for FOOT_JOINTS.

    A foot joint is in contact when it is within `margin` m of its own resting height (the 5th
    percentile of its height over the clip, so a clip that floats or sinks still works) and moves
    slower than `max_speed` m/s; isolated single frames are dropped.
    """
    joints = _check_joints(joints)
    feet = joints[:, list(FOOT_JOINTS)]
    rest = np.percentile(feet[..., 1], 5, axis=0)
    step = np.zeros(feet.shape[:2])
    if len(feet) > 1:
        d = np.linalg.norm(np.diff(feet[..., [0, 2]], axis=0), axis=-1)
        step[1:] = d
        step[0] = d[0]
    contact = (feet[..., 1] < rest + margin) & (step * FPS < max_speed)
    lone = contact.copy()
    lone[1:-1] &= ~contact[:-2] & ~contact[2:]
    if len(contact) > 2:
        contact[1:-1] &= ~lone[1:-1]
    return contact


def _segments(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) runs of True."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0], strict=True))


def _pinned(xz: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Per frame, the mean XZ of the contact run it belongs to (NaN outside runs)."""
    out = np.full_like(xz, np.nan)
    for a, b in _segments(mask):
        out[a:b] = xz[a:b].mean(axis=0)
    return out


def two_bone_ik(
    hip: np.ndarray,
    knee: np.ndarray,
    ankle: np.ndarray,
    target: np.ndarray,
    bend_hint: np.ndarray | None = None,
) -> tuple:
    """Analytic two-bone IK per frame: hip fixed, bone lengths kept, the ankle moved to the target.

    The knee keeps the side it bent to, measured against the leg's *original* hip-ankle axis:
    measured against the new axis, a nearly straight leg's bend direction is noise, and the knee
    can flip backwards or sideways (hip twists of 90 degrees on runs). An optional `bend_hint`
    (e.g. the direction the toes point) adds a 5 cm bias, so a straight leg bends that way.

    All (N, 3); returns (new knee, new ankle).
    """
    l1 = np.linalg.norm(knee - hip, axis=-1)
    l2 = np.linalg.norm(ankle - knee, axis=-1)
    to = target - hip
    d = np.linalg.norm(to, axis=-1)
    d_clamped = np.clip(d, np.abs(l1 - l2) + 1e-4, l1 + l2 - 1e-4)
    u = to / np.maximum(d, 1e-9)[:, None]
    leg = ankle - hip
    axis0 = leg / np.maximum(np.linalg.norm(leg, axis=-1, keepdims=True), 1e-9)
    bend = (knee - hip) - ((knee - hip) * axis0).sum(-1, keepdims=True) * axis0
    if bend_hint is not None:
        hint_n = np.linalg.norm(bend_hint, axis=-1, keepdims=True)
        bend = bend + 0.05 * bend_hint / np.maximum(hint_n, 1e-9)
    pole = bend - (bend * u).sum(-1, keepdims=True) * u
    pole_n = np.linalg.norm(pole, axis=-1, keepdims=True)
    # A straight leg with no hint has no bend plane: bend the knee along the original shin.
    fallback = (ankle - knee) - ((ankle - knee) * u).sum(-1, keepdims=True) * u
    pole = np.where(pole_n > 1e-6, pole / np.maximum(pole_n, 1e-9), fallback)
    pole = pole / np.maximum(np.linalg.norm(pole, axis=-1, keepdims=True), 1e-9)
    a = (l1**2 - l2**2 + d_clamped**2) / (2 * d_clamped)
    h = np.sqrt(np.maximum(l1**2 - a**2, 0.0))
    new_knee = hip + a[:, None] * u + h[:, None] * pole
    new_ankle = hip + d_clamped[:, None] * u
    return new_knee, new_ankle


def clean_foot_contacts(joints: np.ndarray, contacts: np.ndarray | None = None, blend: int = 3) -> np.ndarray:
    """Remove foot skating: pin feet in contact and re-solve the legs with two-bone IK.

    While an ankle is in contact its XZ is pinned to the mean XZ of its contact run; while only
    the toe is, the ankle is placed so the toe stays pinned (heel lifting off). The ankle's height
    is kept; the leg is re-solved with the hip fixed and the knee in the leg's own plane; the toe
    moves with the ankle. The correction fades in and out over `blend` frames around each run.

    Args:
        joints: (T, 22, 3) world joints.
        contacts: (T, 4) or (T-1, 4) contact flags for (left ankle, left toe, right ankle, right
            toe), e.g. the features' contact channels (> 0.5); None: :func:`detect_foot_contacts`.
        blend: frames over which the correction fades.

    Returns:
        (T, 22, 3) float32 joints with the same pelvis, spine and arms.
    """
    joints = _check_joints(joints)
    n = joints.shape[0]
    if contacts is None:
        contacts = detect_foot_contacts(joints)
    contacts = np.asarray(contacts) > 0.5
    if contacts.ndim != 2 or contacts.shape[1] != 4 or contacts.shape[0] not in (n, n - 1):
        raise ValueError(f"contacts must have shape ({n}, 4) or ({n - 1}, 4), got {contacts.shape}")
    if contacts.shape[0] == n - 1:  # features have one frame less: the last frame keeps the last flags
        contacts = np.concatenate([contacts, contacts[-1:]], axis=0)
    out = joints.copy()
    for leg, (hip, knee, ankle, toe) in enumerate(LEGS):
        c_ankle, c_toe = contacts[:, 2 * leg], contacts[:, 2 * leg + 1]
        pin_ankle = _pinned(joints[:, ankle, [0, 2]], c_ankle)
        pin_toe = _pinned(joints[:, toe, [0, 2]], c_toe & ~c_ankle)
        foot_vec = joints[:, ankle, [0, 2]] - joints[:, toe, [0, 2]]
        target = np.where(np.isnan(pin_ankle), pin_toe + foot_vec, pin_ankle)
        offset = np.nan_to_num(target - joints[:, ankle, [0, 2]])  # (T, 2)
        held = ~np.isnan(target[:, 0])
        if not held.any():
            continue
        # Fade: each free frame takes the offset of the nearest held frame, scaled down with distance.
        idx = np.arange(n)
        held_idx = idx[held]
        pos = np.clip(np.searchsorted(held_idx, idx), 1, len(held_idx)) - 1
        nxt = np.clip(pos + 1, 0, len(held_idx) - 1)
        prev_f, next_f = held_idx[pos], held_idx[nxt]
        nearest = np.where(np.abs(idx - prev_f) <= np.abs(next_f - idx), prev_f, next_f)
        gap = np.abs(idx - nearest)
        weight = np.clip(1.0 - gap / (blend + 1.0), 0.0, 1.0)
        offset = offset[nearest] * weight[:, None]
        goal = joints[:, ankle].copy()
        goal[:, [0, 2]] += offset
        new_knee, new_ankle = two_bone_ik(joints[:, hip], joints[:, knee], joints[:, ankle], goal)
        out[:, knee] = new_knee
        out[:, toe] = joints[:, toe] + (new_ankle - joints[:, ankle])
        out[:, ankle] = new_ankle
    return out.astype(np.float32)
