"""Closed-form stages of the pipeline: the path through the waypoints, the body on the path.

- :func:`route_anchors` picks the waypoints a root path must pass and the frame of each;
  :func:`snap_to_waypoints` bends a whole clip's path exactly through them, and
  :func:`spread_residuals` does it causally for the stream (linear, so a window that moves on by a
  token keeps a constant correction per frame).
- :func:`recompose` places a *local pose* (the body relative to its root, in its own heading
  frame: what the body GPT decodes) on a root path, so the pelvis lies exactly on the path and
  the body faces its direction of travel; :func:`on_bone_lengths` then rebuilds it on the
  skeleton's bone lengths, its hands where the decoder put them.

All functions are deterministic numpy; root paths follow :mod:`motion_env.motion.trajectory`.
Where numba runs, the body's placement (:func:`local_pose_from_features`,
:func:`align_heading_to_travel`, :func:`recompose`, :func:`on_bone_lengths`) and
:func:`smooth_path` run compiled (:mod:`motion_env.generation.compose_jit`), the same numbers.
The feet are cleaned afterwards by :mod:`motion_env.generation.feet`.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.ndimage import gaussian_filter1d

from motion_env.generation.feet import two_bone_ik
from motion_env.models.jit_cache import jit_enabled, note_first_compile
from motion_env.motion.features import FEATURE_DIM, features_to_joints
from motion_env.motion.kinematics import (
    BONE_CHILDREN,
    BONE_PARENTS,
    BONE_SHARE,
    FIT_ITERATIONS,
    fit_bone_lengths,
    rotate_y,
)
from motion_env.motion.rotations import cross, vector_norm
from motion_env.motion.skeleton import (
    BONE_LENGTHS,
    FACE_JOINTS,
    FPS,
    NUM_JOINTS,
    PARENTS,
    RAW_OFFSETS,
)
from motion_env.motion.trajectory import (
    HEADING_SMOOTH_SIGMA,
    root_path_from_joints,
    validate_root_path,
    validate_waypoints,
    wrap_angle,
)
from motion_env.motion.validation import check_joints

# An untimed waypoint is snapped to only where the controller's path passes it this close (m): one
# the path has not reached (yet) is left to the controller rather than dragging the path to it.
SNAP_RADIUS = 0.5
# A whole clip's last untimed waypoint is where the character stands: when the controller's path
# comes to rest (under REST_SPEED, m/s, to its end) within STOP_RADIUS (m) of it, the standing
# body is put on it rather than the point where the path passed it (a jog that turned back to its
# last waypoint passed it and stood 36 cm beyond).
REST_SPEED = 0.2
STOP_RADIUS = 1.0

# ----------------------------------------------------------------------------------------------
# The body on the path
# ----------------------------------------------------------------------------------------------


def local_pose_from_joints(joints: np.ndarray, root_path: np.ndarray | None = None) -> np.ndarray:
    """The body relative to its root path: pelvis XZ at the origin, heading turned to +Z.

    Args:
        joints: (T, 22, 3) world joint positions (or (B, T, 22, 3): B clips of one length).
        root_path: (T, 3) the path to factor out; default :func:`paths.root_path_from_joints`.

    Returns:
        (T, 22, 3) float32 local pose (joint heights unchanged; the pelvis is at x = z = 0).
    """
    joints = check_joints(joints, batched=True)
    path = root_path_from_joints(joints) if root_path is None else validate_root_path(root_path, batched=True)
    if path.shape[:-1] != joints.shape[:-2]:
        raise ValueError(f"root_path has {path.shape[-2]} frames, joints {joints.shape[-3]}")
    local = joints.copy()
    local[..., [0, 2]] -= path[..., None, :2].astype(np.float64)
    return rotate_y(local, -path[..., None, 2].astype(np.float64)).astype(np.float32)


def local_pose_from_features(features: np.ndarray, first: int = 0) -> np.ndarray:
    """Local pose of decoded 263-d features (T, 263) -> (T, 22, 3), or of its frames first..
    only, (T - first, 22, 3) (or B clips of one length, (B, T, 263)).

    The features are turned into joints with :func:`motion.features_to_joints` (their own root
    trajectory), whose root path is then factored out again with :func:`local_pose_from_joints`.
    Going through joints, rather than reading the RIC channels directly, expresses the body in the
    same (smoothed hips-and-shoulders) heading frame the controller is trained on, so the body
    neither gains nor loses a twist when it is put back on a path. With `first` the heading is
    still smoothed over all T frames, from their pelvis, hips and shoulders only: the frames
    first.. are the same numbers as those of the whole (the stream's window, most of which only
    its heading reads).
    """
    features = np.asarray(features, dtype=np.float32)
    compiled = _local_pose_compiled(features, first) if jit_enabled() else None
    if compiled is not None:
        return compiled
    if not first:
        return local_pose_from_joints(features_to_joints(features))
    face = (0, *FACE_JOINTS)  # what root_path_from_joints reads
    skeleton = np.zeros(features.shape[:-1] + (NUM_JOINTS, 3), np.float32)
    skeleton[..., face, :] = features_to_joints(features, only=face)
    path = root_path_from_joints(skeleton)[..., first:, :]
    return local_pose_from_joints(features_to_joints(features, first=first), path)


def _local_pose_compiled(features: np.ndarray, first: int) -> np.ndarray | None:
    """:func:`local_pose_from_features` on :mod:`~motion_env.generation.compose_jit`'s loop, the
    same numbers; None where numpy's path must run to name what is wrong (a shape, a frame index,
    a frame not finite)."""
    if features.ndim not in (2, 3) or features.shape[-1] != FEATURE_DIM:
        return None
    if not (isinstance(first, (int, np.integer)) and 0 <= first < features.shape[-2]):
        return None
    if not np.isfinite(features).all():
        return None
    from motion_env.generation.compose_jit import gaussian_weights, local_pose

    note_first_compile(local_pose, "the body's local pose")
    rows = np.ascontiguousarray(features.reshape(-1, *features.shape[-2:]))
    pose, finite = local_pose(rows, int(first), gaussian_weights(HEADING_SMOOTH_SIGMA), _FACE)
    return pose.reshape(features.shape[:-2] + pose.shape[-3:]) if finite else None


_FACE = np.array(FACE_JOINTS, np.int64)
# The Gaussians (sigma in frames) of align_heading_to_travel: the velocity's, the correction's.
_TRAVEL_SIGMA, _CORRECTION_SIGMA = 2.0, 1.0


def _travel(root_path: np.ndarray, sigma: float = _TRAVEL_SIGMA) -> tuple[np.ndarray, np.ndarray]:
    """Speed (m/s) and direction of travel (heading convention) per frame of a root path (..., T, 3)."""
    if root_path.shape[-2] < 2:
        return np.zeros(root_path.shape[:-1]), root_path[..., 2].astype(np.float64)
    vel = np.gradient(root_path[..., :2].astype(np.float64), axis=-2) * FPS
    vel = gaussian_filter1d(vel, sigma, axis=-2, mode="nearest")
    return np.linalg.norm(vel, axis=-1), np.arctan2(vel[..., 0], vel[..., 1])


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
        (T, 3) float32 root path with the new (unwrapped) heading ((B, T, 3) for B paths).
    """
    path = validate_root_path(root_path, batched=True).astype(np.float64)
    lim = np.deg2rad(max_offset_deg)
    if jit_enabled():
        from motion_env.generation.compose_jit import gaussian_weights, travel_heading

        note_first_compile(travel_heading, "the heading's turn to the travel")
        ramp = np.array([min_speed, max(full_speed - min_speed, 1e-6)], np.float64)
        rows = np.ascontiguousarray(path.reshape(-1, *path.shape[-2:]))
        taps = gaussian_weights(_TRAVEL_SIGMA), gaussian_weights(_CORRECTION_SIGMA)
        return travel_heading(rows, *taps, ramp, float(lim), float(FPS)).reshape(path.shape)
    speed, travel = _travel(path)
    offset = wrap_angle(travel - path[..., 2])
    w_speed = np.clip((speed - min_speed) / max(full_speed - min_speed, 1e-6), 0.0, 1.0)
    w_angle = np.clip((1.5 * lim - np.abs(offset)) / lim, 0.0, 1.0)
    correction = gaussian_filter1d(w_speed * w_angle * offset, _CORRECTION_SIGMA, axis=-1, mode="nearest")
    out = path.copy()
    out[..., 2] = path[..., 2] + correction
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
    local = check_joints(local_pose, "local_pose", batched=True).copy()
    path = validate_root_path(root_path, batched=True)
    if path.shape[:-1] != local.shape[:-2]:
        raise ValueError(f"root_path has {path.shape[-2]} frames, local_pose {local.shape[-3]}")
    if face_travel:
        path = align_heading_to_travel(path)
    if jit_enabled():
        from motion_env.generation.compose_jit import place_on_path

        note_first_compile(place_on_path, "the body's placement on its path")
        rows = np.ascontiguousarray(local.reshape(-1, *local.shape[-3:]))
        paths = np.ascontiguousarray(path.reshape(-1, *path.shape[-2:]), dtype=np.float64)
        return place_on_path(rows, paths).reshape(local.shape)
    local[..., [0, 2]] -= local[..., :1, [0, 2]]
    joints = rotate_y(local, path[..., None, 2].astype(np.float64))
    joints[..., [0, 2]] += path[..., None, :2].astype(np.float64)
    return joints.astype(np.float32)


# The arms as (shoulder, elbow, wrist).
ARMS: tuple[tuple[int, int, int], ...] = ((16, 18, 20), (17, 19, 21))
# How much an arm's reach is scaled to the skeleton's arm at most (either way): the decoder's
# arms are a few per cent short, but where a forearm collapses (decoded 8 cm long for 27 cm) the
# ratio means nothing.
ARM_SCALE = 1.05
# The bias (m) towards bending back and out that an arm's elbow gets (see on_bone_lengths).
ARM_BEND_HINT = 0.01
# How much of the bend an arm needs but its decoded elbow does not show the bias fills in
# (two_bone_ik's hint_fill: all of it where the decoded arm shows none, little where it shows most).
ARM_BEND_FILL = 1.0
# bend_elbows_one_way keeps an elbow on the side it flexes to in full from these on: the arm's
# |sin| to the chest's left-right axis, and the share of it that points down. The rule fades out
# to none at 0.3 (an arm held out sideways) and at 0.2 (12° under the horizontal: a raised arm's
# elbow, as in a wave, passes its line all the time, and the shoulder turns that far).
ELBOW_SAGITTAL = 0.7
ELBOW_DOWN = 0.6


def on_bone_lengths(joints: np.ndarray) -> np.ndarray:
    """Decoded joints rebuilt on the skeleton's bone lengths, the wrists where the decoder put them.

    :func:`~motion_env.motion.kinematics.fit_bone_lengths` moves each joint about as little as the
    lengths need (a rebuild from the pelvis outward made the joints far from it jitter). Where the
    decoder shrinks a forearm or upper arm to a third of its length for a few frames (as a hand is
    raised fast), the direction of that short bone swings, and at full length it swung the wrist
    through 10-20 cm in a frame: the wrists' pops of generated clips (100 m/s^2 where the decoded
    wrist moves at 40). Here each arm is re-solved with :func:`~motion_env.generation.feet.two_bone_ik`
    so that the wrist keeps its decoded place relative to the shoulder (the shoulder-wrist vector
    scaled by the arm's length over the decoded one, within ARM_SCALE), the elbow bending in the
    decoded elbow's plane. Per frame, so the stream does the same.

    joints: (..., 22, 3) -> float32 of the same shape.
    """
    if jit_enabled():
        return _on_bone_lengths_compiled(joints)
    decoded = np.asarray(joints, dtype=np.float64)
    out = fit_bone_lengths(joints).astype(np.float64)
    shape = out.shape
    flat, dec = out.reshape(-1, shape[-2], 3), decoded.reshape(-1, shape[-2], 3)
    chains, goals, hints = [], [], []
    for shoulder, elbow, wrist in ARMS:
        length = np.linalg.norm(flat[:, elbow] - flat[:, shoulder], axis=-1) + np.linalg.norm(
            flat[:, wrist] - flat[:, elbow], axis=-1
        )
        decoded_length = np.linalg.norm(dec[:, elbow] - dec[:, shoulder], axis=-1) + np.linalg.norm(
            dec[:, wrist] - dec[:, elbow], axis=-1
        )
        scale = np.clip(length / np.maximum(decoded_length, 1e-9), 1.0 / ARM_SCALE, ARM_SCALE)
        goals.append(flat[:, shoulder] + (dec[:, wrist] - dec[:, shoulder]) * scale[:, None])
        # An arm the decoder holds straight but short has no bend of its own to keep: its elbow
        # bends back and out (a 1 cm bias), rather than to whichever side noise puts it.
        outward = flat[:, shoulder] - flat[:, ARMS[1 - ARMS.index((shoulder, elbow, wrist))][0]]
        outward[:, 1] = 0.0
        back = np.cross(outward, [0.0, 1.0, 0.0]) * (-1.0 if shoulder == ARMS[0][0] else 1.0)
        hint = back / np.maximum(np.linalg.norm(back, axis=-1, keepdims=True), 1e-9)
        hint += 0.5 * outward / np.maximum(np.linalg.norm(outward, axis=-1, keepdims=True), 1e-9)
        hints.append(hint)
        chains.append((shoulder, elbow, wrist))
    # A decoded arm much shorter than the skeleton's but held straight (both bones at half
    # length as a hand is thrown up) must bend far to keep the wrist where it was decoded: its own
    # bend is noise, which flipped the elbow from one side to the other between frames (250
    # m/s^2). ARM_BEND_FILL grows the bias with the bend it needs and does not show, so such an
    # arm bends back and out. Both arms in one IK call (each reads and writes its own elbow and
    # wrist; the IK is per frame).
    shoulders, elbows, wrists = (np.concatenate([flat[:, c[j]] for c in chains]) for j in range(3))
    new_elbow, new_wrist = two_bone_ik(
        shoulders, elbows, wrists, np.concatenate(goals), np.concatenate(hints),
        hint_weight=ARM_BEND_HINT, hint_fill=ARM_BEND_FILL,
    )  # fmt: skip
    n = len(flat)
    for k, (_, elbow, wrist) in enumerate(chains):
        flat[:, elbow], flat[:, wrist] = new_elbow[k * n : (k + 1) * n], new_wrist[k * n : (k + 1) * n]
    bend_elbows_one_way(flat)
    return flat.reshape(shape).astype(np.float32)


def _on_bone_lengths_compiled(joints: np.ndarray) -> np.ndarray:
    """:func:`on_bone_lengths` on :mod:`~motion_env.generation.compose_jit`'s loops, the same
    numbers: fit_bone_lengths' rounds each a compiled step and numpy's matrix product (kept, so
    that its sums are numpy's), then the rebuild, the arms and the elbows compiled."""
    from motion_env.generation.compose_jit import arms_on_lengths, bone_excess

    note_first_compile(arms_on_lengths, "the body's bone lengths")
    checked = check_joints(joints, batched=True)  # fit_bone_lengths' check: float64
    flat = np.ascontiguousarray(checked.reshape(-1, NUM_JOINTS, 3))
    x = np.ascontiguousarray(np.moveaxis(flat.astype(np.float32), -2, 0)).reshape(NUM_JOINTS, -1)
    for _ in range(FIT_ITERATIONS):
        x = x - BONE_SHARE @ bone_excess(x, _BONE_TARGET, BONE_CHILDREN, BONE_PARENTS)
    out = arms_on_lengths(
        x, np.ascontiguousarray(flat[:, 0]), flat, _LENGTHS, _REST, _PARENTS, _ARMS, _SIDES, _ARM_CONSTANTS
    )
    return out.reshape(checked.shape)


_LENGTHS = np.asarray(BONE_LENGTHS, np.float64)
_BONE_TARGET = _LENGTHS[BONE_CHILDREN].astype(np.float32)
_REST = RAW_OFFSETS.astype(np.float64)
_PARENTS = np.array([max(p, 0) for p in PARENTS], np.int64)
_ARMS = np.array(ARMS, np.int64)
_SIDES = np.array([-1.0, 1.0])  # each arm's sign on np.cross(outward, up): ARMS[0]'s turned
# arms_on_lengths' numbers: the arm's scale range, the bend's hint and fill, the elbows' fades
_ARM_CONSTANTS = np.array(
    [1.0 / ARM_SCALE, ARM_SCALE, ARM_BEND_HINT, ARM_BEND_FILL, ELBOW_SAGITTAL, ELBOW_DOWN]
)


def bend_elbows_one_way(joints: np.ndarray) -> None:
    """Put every elbow (in place; (N, 22, 3) float64) on the side of its shoulder-wrist line that
    an elbow flexes towards: behind a hanging arm, above an arm swung back, below an arm held
    forward (the arm's posterior in the chest's sagittal plane). An elbow on the other side, a
    forearm bent backwards, is mirrored across the line's plane with the chest's left-right axis.

    The decoder bends a short, nearly straight arm backwards by 20-25° on a run's last strides,
    and :func:`on_bone_lengths`, which keeps the wrist where it was decoded, folded that bend to
    80°: a shoulder the MuJoCo replay found twisted inwards 60° past a human's range. A mirror
    keeps the wrist, both bone lengths and the bend's angle, and is continuous (an elbow on the
    line stays), so an elbow that crosses the line between frames does not jump. Only a lowered
    arm's: an arm held out sideways has no sagittal posterior (the mirror fades out between
    ELBOW_SAGITTAL, 0.7 or 44° from the left-right axis, and 0.3), and a raised arm's elbow
    crosses its line all the time in a wave, where the shoulder turns far enough (mirrored, the
    fold's kink popped validation goodbyes: 8 -> 25 % of clips; it fades out between ELBOW_DOWN,
    0.6 of the arm pointing down, and 0.2).
    """
    shoulders, elbows, wrists = ([arm[k] for arm in ARMS] for k in range(3))
    left = joints[:, shoulders[0]] - joints[:, shoulders[1]]
    left[:, 1] = 0.0
    left = (left / np.maximum(vector_norm(left, keepdims=True), 1e-9))[:, None]  # (N, 1, 3)
    base = joints[:, shoulders]  # (N, 2, 3): both arms at once
    arm = joints[:, wrists] - base
    arm /= np.maximum(vector_norm(arm, keepdims=True), 1e-9)
    rel = joints[:, elbows] - base
    along = (rel * arm).sum(-1, keepdims=True) * arm
    off = rel - along  # the elbow's offset from the shoulder-wrist line
    back = cross(left, arm)  # the posterior; its length is the arm's sine to left-right
    sagittal = vector_norm(back)
    back /= np.maximum(sagittal, 1e-9)[..., None]
    weight = np.clip((sagittal - 0.3) / (ELBOW_SAGITTAL - 0.3), 0.0, 1.0)
    weight *= np.clip((-arm[..., 1] - 0.2) / (ELBOW_DOWN - 0.2), 0.0, 1.0)
    wrong = np.maximum(0.0, -(off * back).sum(-1))  # how far in front of the line it stands
    if not (wrong * weight).any():
        return
    mirrored = off + (2.0 * weight * wrong)[..., None] * back
    size = vector_norm(mirrored, keepdims=True)
    radius = vector_norm(off, keepdims=True)
    # (a half-faded mirror of an elbow right in front of its line can vanish: left as it is)
    moved = np.where(size > 1e-9, mirrored * radius / np.maximum(size, 1e-9), off)
    joints[:, elbows] = base + along + moved


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
# Which waypoints a path is bent through
# ----------------------------------------------------------------------------------------------


def route_anchors(
    path: np.ndarray,
    route: np.ndarray,
    first: int = 0,
    open_end: bool = False,
    steered: np.ndarray | None = None,
) -> np.ndarray:
    """The waypoints a root path is snapped to, each timed at the frame where the path should pass it.

    Args:
        path: (T, 3) root path whose frame 0 is episode frame `first`.
        route: (K, 3) waypoints ahead (episode frame times, NaN = untimed), in order.
        first: episode frame of the path's frame 0 (which stays where it is).
        open_end: the path goes on after its last frame (streaming look-ahead): an untimed
            waypoint closest at the last frame is still being approached and is not snapped.
        steered: (T, 3) the controller's own path that `path` was smoothed from, where untimed
            waypoints are looked for (default `path`): the controller steers through them, but
            smoothing a sharp turn (a waypoint behind the character) cuts its corner by more
            than SNAP_RADIUS, which would leave the waypoint unreached.

    Returns:
        (M, 3) float32 x, z and the frame (of `path`) of each anchor, frames increasing: timed
        waypoints inside the path; untimed ones at their closest approach (searched after the
        previous anchor) when it is within SNAP_RADIUS. The first untimed waypoint the path
        does not reach ends the list (the ones after it are not reached in order either).
        Without `open_end`, an untimed last waypoint near which the path comes to rest is
        anchored where it comes to rest (REST_SPEED, STOP_RADIUS), shifted so that the rest of
        the path stands on it on average.
    """
    last = len(path) - 1
    steered = path if steered is None else steered
    anchors: list[tuple[float, float, float]] = []
    after = 0
    for n, (x, z, t) in enumerate(route):
        rest = None if open_end or n < len(route) - 1 or not np.isnan(t) else _rest_frame(steered, after)
        if rest is not None and np.hypot(*(steered[rest, :2] - (x, z))) <= STOP_RADIUS:
            # The stance from `rest` on, not its first frame, stands on the waypoint (a standing
            # pelvis sways a few cm): the anchor is placed so that the stance's mean lands there.
            x, z = np.array([x, z]) + path[rest, :2] - path[rest:, :2].mean(axis=0)
            k = rest
        elif np.isnan(t):
            dist = np.linalg.norm(steered[after:, :2] - (x, z), axis=1)
            k = after + int(np.argmin(dist))
            if dist[k - after] > SNAP_RADIUS or (open_end and k == last):
                break
        else:
            k = int(np.rint(t)) - first
            if k > last:
                break
        if k <= 0 or (anchors and k <= anchors[-1][2]):
            continue  # at or before a frame that is already fixed
        anchors.append((float(x), float(z), float(k)))
        after = k
    return np.array(anchors, np.float32).reshape(-1, 3)


def _rest_frame(path: np.ndarray, after: int) -> int | None:
    """The frame after `after` from which `path` stays under REST_SPEED to its end, None when it
    is still moving at its end or never moved after `after` (nothing to stop from)."""
    speed = np.linalg.norm(np.diff(path[after:, :2], axis=0), axis=1) * FPS
    moving = np.flatnonzero(speed >= REST_SPEED)
    if len(moving) == 0 or moving[-1] == len(speed) - 1:
        return None
    return after + int(moving[-1]) + 1


def smooth_path(path: np.ndarray, sigma: float) -> np.ndarray:
    """(..., T, 3) root path smoothed in time by a Gaussian of `sigma` frames; frame 0 stays exact.

    The path is extended past both ends by point reflection (``2 p[0] - p[k]``), which keeps a
    steady walk steady and makes the smoothed first frame the first frame itself.
    """
    if sigma <= 0 or path.shape[-2] < 2:
        return path
    pad = min(int(4 * sigma) + 1, path.shape[-2] - 1)
    if jit_enabled() and path.ndim in (2, 3) and path.shape[-1] == 3:
        from motion_env.generation.compose_jit import gaussian_weights, smooth_paths

        note_first_compile(smooth_paths, "the path's smoothing")
        rows = np.ascontiguousarray(np.asarray(path, np.float64).reshape(-1, *path.shape[-2:]))
        return smooth_paths(rows, pad, gaussian_weights(sigma)).reshape(path.shape).astype(path.dtype)
    widths = [(0, 0)] * (path.ndim - 2) + [(pad, pad), (0, 0)]
    padded = np.pad(np.asarray(path, np.float64), widths, mode="reflect", reflect_type="odd")
    out = gaussian_filter1d(padded, sigma, axis=-2, mode="nearest", truncate=4.0)
    return out[..., pad:-pad, :].astype(path.dtype)


def snap_route(path: np.ndarray, route: np.ndarray | None, steered: np.ndarray | None = None) -> np.ndarray:
    """A whole clip's root path bent through the route's anchors (:func:`snap_to_waypoints`);
    `steered`: the controller's path before smoothing (:func:`route_anchors`)."""
    if route is None:
        return path
    anchors = route_anchors(path, route, steered=steered)
    return path if len(anchors) == 0 else snap_to_waypoints(path, anchors, keep_start=True)


def spread_residuals(path: np.ndarray, anchors: np.ndarray) -> np.ndarray:
    """Bend `path` (frame 0 fixed) through `anchors` (M, 3: x, z, frame) with linear residuals.

    The residual at each anchor is spread linearly from the previous one (frame 0: zero) and held
    after the last. Linear rather than :func:`snap_to_waypoints`' PCHIP curve because the stream's
    window moves on by a token at a time: a linear share of the residual committed with each token
    leaves the same rate for the rest, so the correction per frame stays constant.
    """
    path = np.array(path, dtype=np.float64)
    if len(anchors):
        keys = np.concatenate([[0.0], anchors[:, 2]])
        res = np.concatenate([np.zeros((1, 2)), anchors[:, :2] - path[anchors[:, 2].astype(int), :2]])
        t = np.arange(len(path))
        path[:, 0] += np.interp(t, keys, res[:, 0])
        path[:, 1] += np.interp(t, keys, res[:, 1])
    return path
