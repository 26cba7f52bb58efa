"""Is a robot trajectory physically plausible? The replay's checks, on a robot's ``qpos``.

>>> from motion_env.replay.robot import evaluate_robot
>>> result = evaluate_robot(qpos, "path/to/unitree_g1/scene.xml", fps=50)   # or an MjModel
>>> result["plausible"], result["failed"]

:func:`evaluate_robot` measures the trajectory frame by frame (:func:`.robot_kinematic.measure_robot`)
and runs seven checks, each a per-frame signal compared with a threshold; the report has the shape
of the humanoid's (:func:`motion_env.replay.evaluate`), built by the same helpers (:mod:`.judging`):

====================  =========================================================================
joint_limits          angle by which a limited hinge (or ball) joint leaves the model's
                      ``jnt_range`` (degrees)
penetration           depth of the lowest point of any collision geom below the floor (m)
floating              time in the air (no collision geom within CONTACT_HEIGHT of the floor) that
                      is not a ballistic flight of the centre of mass (s)
foot_skating          distance a heel or toe of a foot slides while on the floor, within 1 s (m)
self_collision        deepest contact between two of the robot's own geoms (m)
root_force            force on the free root that inverse dynamics needs and the floor cannot
                      supply, per kg of robot, averaged over a quarter second (N/kg)
root_torque           the same for the torque (N m/kg)
====================  =========================================================================

Thresholds: the humanoid's calibrated ones (``model/thresholds.json``) where the quantity means
the same (:data:`SHARED_CHECKS`); the robot's own (``model/robot_thresholds.json``, the reasons
in the file) for ``joint_limits`` (a hard stop: 0 violations, 0.01 degrees for rounding) and
``self_collision`` (2 cm). A clip shorter than :func:`~motion_env.replay.plausibility.min_frames` at its
rate (1 s) is not judged, as for the humanoid. The frames of the report are the frames of
`qpos`: the joint ranges, the floor, floating and the self-collisions are checked on every one of
them; foot skating and the root force and torque, built on steps and accelerations, on the clip
resampled to 20 fps like the humanoid's, where their thresholds were calibrated
(:func:`robot_signals`).
"""

from __future__ import annotations

import json
from functools import partial
from pathlib import Path

import mujoco
import numpy as np

from motion_env.replay.judging import judge_checks, report_head
from motion_env.replay.mjcf import MODEL_DIR
from motion_env.replay.plausibility import (
    NOTHING_FOUND,
    RESIDUAL_WINDOW,
    SOLE_NAMES,
    floating_signal,
    load_thresholds,
    min_frames,
    moving_average,
    shared_words,
    skating_signal,
)
from motion_env.replay.robot_kinematic import RobotMeasurements, measure_robot

ROBOT_CHECKS: tuple[str, ...] = (
    "joint_limits",
    "penetration",
    "floating",
    "foot_skating",
    "self_collision",
    "root_force",
    "root_torque",
)
SHARED_CHECKS: tuple[str, ...] = ("penetration", "floating", "foot_skating", "root_force", "root_torque")
"""The checks whose quantity means the same on the robot as on the humanoid: they take the
humanoid's calibrated thresholds (the robot's mass is its own, in the per-kg ones)."""
ROBOT_UNITS = {
    "joint_limits": "deg",
    "penetration": "m",
    "floating": "s",
    "foot_skating": "m",
    "self_collision": "m",
    "root_force": "N/kg",
    "root_torque": "N m/kg",
}
_ROBOT_NOTHING_FOUND = {
    **NOTHING_FOUND,
    "floating": "the robot always touches the floor, or is in a ballistic flight",
    "joint_limits": "every joint stays within its range",
    "self_collision": "no two parts of the robot collide",
}


def robot_thresholds_path() -> Path:
    """The robot's own thresholds (``joint_limits``, ``self_collision``), with the reasons."""
    return MODEL_DIR / "robot_thresholds.json"


def load_robot_thresholds(thresholds: dict[str, float] | str | Path | None = None) -> dict[str, float]:
    """A threshold per robot check.

    None: :data:`SHARED_CHECKS` from the humanoid's shipped calibration, the rest from
    :func:`robot_thresholds_path`. A path: a humanoid calibration JSON (as ``motion-env replay
    --thresholds``) for the shared checks only (its ``joint_limits`` is a human range and does not
    apply). A dict: those defaults with its entries for any of :data:`ROBOT_CHECKS` instead (other
    keys ignored). ValueError for a value that is not a number.
    """
    path = None if isinstance(thresholds, dict) else thresholds
    human = load_thresholds(path)
    own = json.loads(robot_thresholds_path().read_text())["thresholds"]
    out = {c: float(human[c]) if c in SHARED_CHECKS else float(own[c]) for c in ROBOT_CHECKS}
    given = thresholds if isinstance(thresholds, dict) else {}
    for c, value in given.items():
        if c not in ROBOT_CHECKS:
            continue
        try:
            out[c] = float(value)
        except (TypeError, ValueError):
            out[c] = float("nan")
        if np.isnan(out[c]):
            raise ValueError(f"thresholds[{c!r}] must be a number, got {value!r}")
    return out


def replay_frames(m: RobotMeasurements) -> np.ndarray:
    """(T,) for each frame of `m`, the nearest frame of ``m.replay`` (the clip at 20 fps), or
    itself when the clip is at 20 fps."""
    if m.replay is None:
        return np.arange(m.num_frames)
    index = np.rint(np.arange(m.num_frames) * m.replay.fps / m.fps).astype(int)
    return np.clip(index, 0, m.replay.num_frames - 1)


def robot_signals(m: RobotMeasurements) -> dict[str, np.ndarray]:
    """Per-frame signal (T,) of every robot check, in the units of :data:`ROBOT_UNITS`, on the
    frames of `m`.

    ``joint_limits``, ``penetration``, ``floating`` and ``self_collision`` hold on every frame as
    given. ``foot_skating``, ``root_force`` and ``root_torque``, sums of steps and finite-difference
    accelerations, are computed at 20 fps (``m.replay``), the rate of the humanoid's calibration:
    at 50 fps the same steps add up more jitter and second differences magnify it 6 times. Each
    frame takes the value of its nearest 20-fps frame.
    """
    r = m.replay or m
    back = replay_frames(m)
    width = max(1, round(RESIDUAL_WINDOW * r.fps))
    excess = np.rad2deg(m.limit_excess)
    return {
        "joint_limits": excess.max(axis=1) if excess.shape[1] else np.zeros(m.num_frames),
        "penetration": np.maximum(-m.lowest, 0.0),
        "floating": floating_signal(m.lowest, m.com, m.fps),
        "foot_skating": skating_signal(r.soles, r.lowest, r.fps)[0][back],
        "self_collision": m.self_depth,
        "root_force": moving_average(r.residual_force, width)[back],
        "root_torque": moving_average(r.residual_torque, width)[back],
    }


def _words(name: str) -> str:
    return name.replace("_", " ")


def _findings(m: RobotMeasurements, name: str, worst: int, value: float, threshold: float) -> tuple[str, str]:
    """``(what, allowed)``: what a check found at its `worst` frame, where it is `value`, in words."""
    if name == "joint_limits":
        k = int(np.argmax(m.limit_excess[worst]))
        low, high = np.rad2deg(m.limit_ranges[k])
        count = int((np.rad2deg(m.limit_excess) > threshold).sum())
        what = (
            f"{_words(m.limit_joints[k])} is {value:.2f} degrees outside its range "
            f"[{low:.1f}, {high:.1f}] degrees ({count} joint-frames beyond the allowance in all)"
        )
        allowed = f"{threshold:g} degrees"
    elif name == "self_collision":
        a, b = (_words(s) for s in m.self_pair[worst])
        what = f"the {a} and the {b} collide {100 * value:.1f} cm deep"
        allowed = f"{100 * threshold:.1f} cm"
    elif name == "penetration":
        what, allowed = shared_words(name, value, threshold, "robot", _words(m.lowest_geom[worst]))
    elif name == "foot_skating":
        r = m.replay or m
        point = SOLE_NAMES[int(skating_signal(r.soles, r.lowest, r.fps)[1][replay_frames(m)[worst]])]
        what, allowed = shared_words(name, value, threshold, "robot", point)
    else:  # floating, root_force, root_torque
        what, allowed = shared_words(name, value, threshold, "robot")
    return what, allowed


def robot_report(m: RobotMeasurements, thresholds: dict[str, float]) -> dict:
    """The plausibility report (a JSON-serialisable dict) of measured robot trajectory `m`."""
    sig = robot_signals(m)
    checks = judge_checks(
        ROBOT_CHECKS, sig, thresholds, ROBOT_UNITS, m.fps, _ROBOT_NOTHING_FOUND, partial(_findings, m)
    )
    return {
        **report_head(checks, m.num_frames, m.fps, min_frames(m.fps), m.mass),
        "robot": m.name,
        "feet": list(m.feet),
        "floor_height": m.floor,
        "checks": checks,
    }


def evaluate_robot(
    qpos: np.ndarray,
    model: mujoco.MjModel | str | Path,
    fps: float,
    thresholds: dict[str, float] | str | Path | None = None,
    feet: tuple[str, str] | None = None,
    measurements: bool = False,
) -> dict | tuple[RobotMeasurements, dict]:
    """Judge robot trajectory `qpos` (T, model.nq) at `fps` on `model` (a ``mujoco.MjModel`` or
    the path of an MJCF scene, free root first: x, y, z, qw, qx, qy, qz, then the joints).

    Returns a JSON-serialisable dict shaped like :func:`motion_env.replay.evaluate`'s:
    ``plausible`` (bool, or None when not judged), ``judged`` (False for a clip shorter than
    ``min_frames``, 1 s of frames), ``min_frames``, ``summary``, ``failed`` (check names),
    ``frames``, ``fps``, ``duration_s``, ``mass_kg`` (the robot's), ``robot`` (the model's name),
    ``feet`` (the foot bodies of the skating check), ``floor_height`` and ``checks`` (per check of
    :data:`ROBOT_CHECKS`: ``value``, ``threshold``, ``unit``, ``passed``, ``frames`` as inclusive
    [first, last] ranges, ``worst_frame``, ``message``).
    thresholds: see :func:`load_robot_thresholds`; feet: the (left, right) foot bodies, found
    from the body names by default (:func:`.robot_kinematic.find_feet`); measurements: also
    return the per-frame :class:`RobotMeasurements`, as ``(measurements, report)``.

    Raises ValueError for a qpos of a wrong shape, with NaN or infinite values (naming the
    frames) or a root quaternion far from unit length, a rate that is not > 0, a model without a
    free root first, feet it cannot find, or thresholds that are not numbers;
    FileNotFoundError for a model path that does not exist.
    """
    thresholds = load_robot_thresholds(thresholds)
    m = measure_robot(qpos, model, fps, feet)
    report = robot_report(m, thresholds)
    return (m, report) if measurements else report
