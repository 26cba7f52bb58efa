"""Is a motion physically plausible? Checks on its kinematic replay, and the report.

:func:`evaluate` replays a motion on the humanoid (:func:`motion_env.replay.kinematic.measure`)
and runs nine checks, each a per-frame signal compared with a threshold calibrated on real
motion capture (``scripts/calibrate_replay.py`` writes ``motion_env/replay/model/thresholds.json``):

====================  =========================================================================
penetration           depth of the lowest body point below the floor (m)
floating              time in the air (nothing within CONTACT_HEIGHT of the floor) that is not a
                      ballistic flight: the centre of mass does not fall freely (s)
foot_skating          distance a heel or toe slides while on the floor, within one second (m)
self_penetration      depth by which two limbs' capsules overlap (m)
joint_limits          angle by which a joint leaves its human range (degrees)
speed                 fastest joint speed (m/s)
acceleration          largest joint acceleration (m/s^2)
root_force            force on the root that inverse dynamics needs and the floor cannot supply,
                      per kg, averaged over a quarter second (N/kg)
root_torque           the same for the torque (N m/kg)
====================  =========================================================================

A motion is plausible when every check passes. A clip shorter than one window of the longest
check (:data:`MIN_SECONDS`, :func:`min_frames`: 20 frames at 20 fps) is not judged: its report
says ``"judged": False`` and ``"plausible": None``. Physical tracking (:mod:`.tracking`) can be
added to the report but does not decide it.
"""

from __future__ import annotations

import json
from functools import partial
from pathlib import Path

import numpy as np
from scipy.ndimage import minimum_filter1d

from motion_env.motion.kinematics import resample
from motion_env.motion.skeleton import FPS, JOINT_NAMES
from motion_env.motion.types import Motion
from motion_env.replay.humanoid import BALL_JOINTS, DEFAULT_MASS
from motion_env.replay.inputs import check_mass, check_motion
from motion_env.replay.judging import judge_checks, report_head, runs
from motion_env.replay.kinematic import CONTACT_HEIGHT, Measurements, measure
from motion_env.replay.mjcf import MODEL_DIR

GRAVITY = 9.81
CHECKS: tuple[str, ...] = (
    "penetration",
    "floating",
    "foot_skating",
    "self_penetration",
    "joint_limits",
    "speed",
    "acceleration",
    "root_force",
    "root_torque",
)
UNITS = {
    "penetration": "m",
    "floating": "s",
    "foot_skating": "m",
    "self_penetration": "m",
    "joint_limits": "deg",
    "speed": "m/s",
    "acceleration": "m/s^2",
    "root_force": "N/kg",
    "root_torque": "N m/kg",
}
BALLISTIC_TOLERANCE = 0.03  # m: largest deviation of the centre of mass from a free-fall fit
MAX_TAKEOFF_SPEED = 4.5  # m/s upward: about a 1 m rise of the centre of mass, beyond any jump
SKATE_WINDOW = 1.0  # s
SKATE_CONTACT_BAND = 0.02  # m above the local floor
RESIDUAL_WINDOW = 0.25  # s
MIN_SECONDS = max(SKATE_WINDOW, RESIDUAL_WINDOW)
"""The shortest clip the checks can judge (s): one whole window of the longest check, foot
skating's SKATE_WINDOW. Its threshold is a distance slid within that window, calibrated on whole
windows, so a shorter clip could pass a foot sliding as fast as a failing one; and the
accelerations and the root force need frames on both sides of a frame."""
SOLE_NAMES = ("left heel slides", "left toes slide", "right heel slides", "right toes slide")
"""The four sole points of the foot-skating check, as the report words them."""
# How a joint leaves its range, by (joint kind, axis, upper bound?), for the left side and the
# midline in MuJoCo's frame; right limbs swap the words of the x and z axes.
_SAGITTAL_WORDS = {
    "hip": ("swings forwards", "swings backwards"),
    "knee": ("bends backwards", "bends"),
    "ankle": ("flexes toes-up", "points toes-down"),
    "spine": ("bends backwards", "bends forwards"),
    "neck": ("tips backwards", "tips forwards"),
    "collar": ("tips backwards", "tips forwards"),
    "shoulder": ("swings forwards", "swings backwards"),
    "elbow": ("bends", "bends backwards"),
}


def _limit_words(joint: str, axis: int, upper: bool) -> str:
    """How joint `joint` leaves its range about MuJoCo axis `axis` (0 x, 1 y, 2 z)."""
    side, _, kind = joint.partition("_") if joint.startswith(("left_", "right_")) else ("", "", joint)
    kind = "spine" if kind.startswith("spine") else kind
    if axis == 1:
        return _SAGITTAL_WORDS[kind][int(upper)]
    if side == "right":
        upper = not upper
    if not side:
        return (
            ("leans to the left", "leans to the right")[int(upper)]
            if axis == 0
            else (("twists to the right", "twists to the left")[int(upper)])
        )
    if axis == 0:
        return ("moves across the body", "moves out sideways")[int(upper)]
    return ("twists inwards", "twists outwards")[int(upper)]


def min_frames(fps: float = FPS) -> int:
    """The fewest frames a clip at `fps` needs to be judged: :data:`MIN_SECONDS` (20 at 20 fps),
    and at least 3 (a second difference)."""
    return max(3, round(MIN_SECONDS * fps))


def thresholds_path() -> Path:
    """The shipped calibration file."""
    return MODEL_DIR / "thresholds.json"


def load_thresholds(path: str | Path | None = None) -> dict[str, float]:
    """Thresholds per check from a calibration JSON (default: the shipped one)."""
    path = thresholds_path() if path is None else Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no replay thresholds at {path} (run scripts/calibrate_replay.py)")
    data = json.loads(path.read_text())
    try:
        return check_thresholds(data.get("thresholds", data))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None


def check_thresholds(thresholds: dict) -> dict[str, float]:
    """A threshold per check as floats, or ValueError naming the missing or non-number ones."""
    missing = [c for c in CHECKS if c not in thresholds]
    if missing:
        raise ValueError(f"thresholds missing for {missing}")
    out = {}
    for c in CHECKS:
        try:
            out[c] = float(thresholds[c])
        except (TypeError, ValueError):
            out[c] = float("nan")
        if np.isnan(out[c]):
            raise ValueError(f"thresholds[{c!r}] must be a number, got {thresholds[c]!r}")
    return out


# --------------------------------------------------------------------------------------------
# Per-frame signals
# --------------------------------------------------------------------------------------------


def moving_average(x: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average over `width` frames (fewer at the ends), (T,) -> (T,)."""
    if width <= 1 or len(x) == 0:
        return x.copy()
    kernel = np.ones(width)
    num = np.convolve(x, kernel, mode="same")
    den = np.convolve(np.ones_like(x), kernel, mode="same")
    return num / den


def _is_ballistic(com: np.ndarray, dt: float) -> bool:
    """Does the centre of mass (n, 3) over an airborne stretch follow a free fall?"""
    n = len(com)
    tau = np.arange(n) * dt
    basis = np.stack([np.ones(n), tau], axis=1)
    target = com.copy()
    target[:, 2] += 0.5 * GRAVITY * tau**2  # free fall: z + g t^2 / 2 is linear in t, x and y too
    coef, *_ = np.linalg.lstsq(basis, target, rcond=None)
    deviation = np.abs(basis @ coef - target).max() if n > 2 else 0.0
    return bool(deviation <= BALLISTIC_TOLERANCE and coef[1, 2] <= MAX_TAKEOFF_SPEED)


def floating_signal(lowest: np.ndarray, com: np.ndarray, fps: float) -> np.ndarray:
    """(T,) length in seconds of the non-ballistic airborne stretch each frame is in (else 0),
    from the height of the lowest body point (T,) and the centre of mass (T, 3)."""
    dt = 1.0 / fps
    out = np.zeros(len(lowest))
    for a, b in runs(lowest > CONTACT_HEIGHT):
        if not _is_ballistic(com[a : b + 1], dt):
            out[a : b + 1] = (b - a + 1) * dt
    return out


def skating_signal(soles: np.ndarray, lowest: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """(T,) largest distance one sole point (soles: (T, 4, 3), in the order of SOLE_NAMES) slid on
    the floor within SKATE_WINDOW around each frame, and (T,) which sole point; lowest: (T,)
    height of the lowest body point.

    A heel or toe is on the floor when it is within CONTACT_HEIGHT of the floor and within
    SKATE_CONTACT_BAND of the lowest body point of the surrounding second (which follows a floor
    that a mocap take sees tilted). A frame counts the smaller of the point's two steps around
    it, so a foot that lands or takes off fast between two frames, a frame away from the floor,
    adds little; a foot that keeps sliding adds all of it.
    """
    n = len(soles)
    if n < 3:
        return np.zeros(n), np.zeros(n, dtype=int)
    width = max(1, round(SKATE_WINDOW * fps))
    floor = minimum_filter1d(lowest, size=width, mode="nearest")
    z = soles[..., 2]  # (T, 4)
    on_floor = (z < CONTACT_HEIGHT) & (z < floor[:, None] + SKATE_CONTACT_BAND)
    step = np.linalg.norm(np.diff(soles[..., :2], axis=0), axis=-1)  # (T-1, 4): t -> t+1
    slide = np.zeros((n, 4))
    slide[1:-1] = np.minimum(step[:-1], step[1:]) * (on_floor[:-2] & on_floor[1:-1] & on_floor[2:])
    windowed = np.stack([np.convolve(slide[:, k], np.ones(width), mode="same") for k in range(4)], axis=1)
    return windowed.max(axis=1), windowed.argmax(axis=1)


def _frame_speeds(m: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """(T, 22) joint speed around each frame (the faster of the steps in and out) and (T, 22)
    joint acceleration (second difference; the end frames copy their neighbours)."""
    n = m.num_frames
    speed = np.zeros((n, m.joints.shape[1]))
    accel = np.zeros_like(speed)
    if n >= 2:
        step = np.linalg.norm(np.diff(m.joints, axis=0), axis=-1) * m.fps  # (T-1, 22)
        speed[1:] = step
        speed[:-1] = np.maximum(speed[:-1], step)
    if n >= 3:
        accel[1:-1] = np.linalg.norm(m.joints[2:] - 2 * m.joints[1:-1] + m.joints[:-2], axis=-1) * m.fps**2
        accel[0], accel[-1] = accel[1], accel[-2]
    return speed, accel


def signals(m: Measurements) -> dict[str, np.ndarray]:
    """Per-frame signal (T,) of every check, in the units of :data:`UNITS`; a check fails on the
    frames where its signal exceeds the threshold, and its value is the signal's maximum."""
    speed, accel = _frame_speeds(m)
    width = max(1, round(RESIDUAL_WINDOW * m.fps))
    return {
        "penetration": np.maximum(-m.lowest, 0.0),
        "floating": floating_signal(m.lowest, m.com, m.fps),
        "foot_skating": skating_signal(m.soles, m.lowest, m.fps)[0],
        "self_penetration": m.self_depth,
        "joint_limits": np.rad2deg(m.limit_excess.max(axis=1)),
        "speed": speed.max(axis=1),
        "acceleration": accel.max(axis=1),
        "root_force": moving_average(m.residual_force, width),
        "root_torque": moving_average(m.residual_torque, width),
    }


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


def _part(geom: str) -> str:
    """A geom's name in words: 'left_sole0' -> 'left foot'."""
    return geom.replace("sole0", "foot").replace("sole1", "foot").replace("_", " ")


NOTHING_FOUND = {
    "penetration": "nothing goes below the floor",
    "floating": "the body always touches the floor, or is in a ballistic flight",
    "foot_skating": "no foot slides on the floor",
    "self_penetration": "no two limbs pass through each other",
    "joint_limits": "every joint stays within a human range",
}
"""What a check says when its signal is 0 on every frame (the others always name their worst)."""


def shared_words(name: str, value: float, threshold: float, body: str, part: str = "") -> tuple[str, str]:
    """``(what, allowed)`` of a check the humanoid and a robot share (penetration, floating,
    foot_skating, root_force, root_torque) at its worst frame, where it is `value`.

    body: "body" or "robot"; part: the geom that sinks (penetration) or the sole that slides
    (foot_skating), in words.
    """
    if name == "penetration":
        return f"the {part} sinks {100 * value:.1f} cm into the floor", f"{100 * threshold:.1f} cm"
    if name == "floating":
        what = f"the {body} stays {value:.2f} s in the air without falling like a thrown body"
        return what, f"{threshold:.2f} s"
    if name == "foot_skating":
        what = f"the {part} {100 * value:.0f} cm along the floor within {SKATE_WINDOW:g} s"
        return what, f"{100 * threshold:.0f} cm"
    kind = "force" if name == "root_force" else "torque"
    unit = UNITS[name]
    what = f"the {body} needs an external {kind} of {value:.1f} {unit} that the floor cannot give"
    return what, f"{threshold:.1f} {unit}"


def _findings(m: Measurements, name: str, worst: int, value: float, threshold: float) -> tuple[str, str]:
    """``(what, allowed)``: what a check found at its `worst` frame, where it is `value`, in words."""
    if name == "self_penetration":
        a, b = (_part(s) for s in m.self_pair[worst])
        what = f"the {a} and the {b} overlap by {100 * value:.1f} cm"
        allowed = f"{100 * threshold:.1f} cm"
    elif name == "joint_limits":
        k = int(np.argmax(m.limit_excess[worst]))
        axis = int(m.limit_axis[worst, k])
        joint = JOINT_NAMES[BALL_JOINTS[k]]
        words = _limit_words(joint, axis // 2, bool(axis % 2))
        what = f"the {joint.replace('_', ' ')} {words} {value:.0f} degrees beyond a human range"
        allowed = f"{threshold:.0f} degrees"
    elif name in ("speed", "acceleration"):
        speed, accel = _frame_speeds(m)
        table = speed if name == "speed" else accel
        joint = JOINT_NAMES[int(np.argmax(table[worst]))].replace("_", " ")
        unit = "m/s" if name == "speed" else "m/s^2"
        verb = "moves at" if name == "speed" else "accelerates at"
        what = f"the {joint} {verb} {value:.1f} {unit}"
        allowed = f"{threshold:.1f} {unit}"
    elif name == "penetration":
        what, allowed = shared_words(name, value, threshold, "body", _part(m.lowest_geom[worst]))
    elif name == "foot_skating":
        point = SOLE_NAMES[int(skating_signal(m.soles, m.lowest, m.fps)[1][worst])]
        what, allowed = shared_words(name, value, threshold, "body", point)
    else:  # floating, root_force, root_torque
        what, allowed = shared_words(name, value, threshold, "body")
    return what, allowed


def report(m: Measurements, thresholds: dict[str, float]) -> dict:
    """The plausibility report (a JSON-serialisable dict) of measured motion `m`.

    A clip shorter than :func:`min_frames` gets ``"judged": False`` and ``"plausible": None``; its
    checks are still run and reported (``failed`` lists the ones that fail anyway), but they are
    no verdict: too few frames can neither show a check passing nor, for the finite differences
    behind speeds, accelerations and root forces, always show one failing.
    """
    thresholds = check_thresholds(thresholds)
    sig = signals(m)
    checks = judge_checks(CHECKS, sig, thresholds, UNITS, m.fps, NOTHING_FOUND, partial(_findings, m))
    err = m.fit_error
    worst_joint = int(np.argmax(err.max(axis=0)))
    return {
        **report_head(checks, m.num_frames, m.fps, min_frames(m.fps), m.mass),
        "fit_error": {
            "mean_cm": float(100 * err.mean()),
            "max_cm": float(100 * err.max()),
            "worst_joint": JOINT_NAMES[worst_joint],
        },
        "checks": checks,
        "tracking": None,
    }


def evaluate_detailed(
    motion: Motion,
    mass: float = DEFAULT_MASS,
    thresholds: dict[str, float] | str | Path | None = None,
    track: bool = False,
) -> tuple[Measurements, dict]:
    """:func:`evaluate`, also returning the per-frame measurements (e.g. for a video).

    The thresholds are calibrated at 20 fps, where finite-difference speeds and accelerations
    mean the same as in the calibration; a motion at another rate is resampled to 20 fps first
    (the report then says so, and its frames count at 20 fps).
    """
    if not isinstance(motion, Motion):
        raise TypeError(f"evaluate expects a motion_env.Motion, got {type(motion).__name__}")
    check_motion(motion)  # its arrays may have changed since it was made
    mass = check_mass(mass)
    thresholds = check_thresholds(thresholds) if isinstance(thresholds, dict) else load_thresholds(thresholds)
    source_fps = motion.fps
    if abs(motion.fps - FPS) > 1e-6:
        joints = resample(motion.joints, motion.fps, FPS)
        motion = Motion(joints=joints, fps=FPS, text=motion.text, meta=motion.meta)
    m = measure(motion, mass)
    out = report(m, thresholds)
    if source_fps != motion.fps:
        out["resampled_from_fps"] = source_fps
    if track:
        from motion_env.replay.tracking import track as run_tracking

        out["tracking"] = run_tracking(motion, mass=mass, measurements=m)
    return m, out


def evaluate(
    motion: Motion,
    mass: float = DEFAULT_MASS,
    thresholds: dict[str, float] | str | Path | None = None,
    track: bool = False,
) -> dict:
    """Replay `motion` on a MuJoCo humanoid of `mass` kg and report what is physically wrong.

    Returns a JSON-serialisable dict: ``plausible`` (bool, or None when not judged),
    ``judged`` (False for a clip shorter than ``min_frames``, 20 frames = 1 s at 20 fps: too
    short for the checks' windows), ``min_frames``, ``summary`` (one line; for a clip not judged
    "too short to judge: N frames, at least M needed (X s)"), ``failed`` (check names),
    ``fit_error`` (how far the humanoid's joints are from the motion's, cm), ``checks`` (per
    check: ``value``, ``threshold``, ``unit``, ``passed``, ``frames`` as inclusive [first, last]
    ranges, ``worst_frame``, ``message``) and ``tracking`` (None, or the result of
    :func:`motion_env.replay.tracking.track` when `track`).
    thresholds: a dict per check, or a calibration JSON path; default the shipped calibration.

    Raises ValueError, naming the argument, for joints with NaN or infinite values (and the
    frames where they are), a rate that is not > 0, a mass that is not a positive number or
    thresholds missing a check; TypeError when `motion` is not a :class:`Motion`.
    """
    return evaluate_detailed(motion, mass, thresholds, track)[1]
