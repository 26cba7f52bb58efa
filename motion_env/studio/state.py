"""What the studio's session hands the page (:class:`Snapshot`, :class:`Stats`) and the checks of
what a user sends it (characters, joints, points on the floor, numbers in a range)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from motion_env.motion.skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS
from motion_env.studio.geometry import ARENA_HALF_SIZE
from motion_env.studio.robot_view import RobotPose

__all__ = [
    "Snapshot",
    "Stats",
    "check_index",
    "check_joint",
    "check_number",
    "check_xz",
    "start_positions",
]

START_SPACING = 1.5  # metres between the characters of a crowd at the start


@dataclass(frozen=True)
class Snapshot:
    """What the page draws after a tick (arrays are copies; B characters).

    Attributes:
        frame: frames emitted in this episode.
        joints: (B, 22, 3) the pose just emitted.
        trails: B arrays (N, 2) of pelvis (x, z), oldest first.
        routes: B arrays (K, 3) of waypoints (x, z, frame; NaN untimed).
        next_waypoint: B indices of the waypoint each character heads for.
        reached: B flags: the last waypoint has been reached.
        goals: B goals (x, z) of the A* agent, or None.
        obstacles: (N, 3) circles x, z, radius.
        captions: B captions.
        version: changes whenever routes, goals, obstacles or joint targets change (the page
            redraws them then).
        joint_targets: B arrays (K, 5) of the joint targets still drawn: frame, joint index, x, y, z
            (a target stays for a second after its frame).
        robot: the robot view's pose (of one character), or None (no robot, or before its first
            frame).
    """

    frame: int
    joints: np.ndarray
    trails: list[np.ndarray]
    routes: list[np.ndarray]
    next_waypoint: list[int]
    reached: list[bool]
    goals: list[np.ndarray | None]
    obstacles: np.ndarray
    captions: list[str]
    version: tuple
    joint_targets: list[np.ndarray]
    robot: RobotPose | None = None


@dataclass(frozen=True)
class Stats:
    """The live numbers of one character (see :meth:`StudioSession.stats`)."""

    frame: int
    step_ms: float  # the last frame's generator step
    step_ms_max: float  # the slowest step of the last second (a token is decoded every 4th frame)
    speed_mps: float  # pelvis speed over the last second, on the floor
    to_next_m: float | None  # to the waypoint the character heads for (None: no route)
    waypoints_left: int
    targets_left: int = 0  # joint targets whose frame is still ahead
    control: str = ""  # how well the emitted joint targets were met (MotionStream.control_summary)
    head_limit: float | None = None  # metres, the head's height limit (None: none)


def check_joint(joint: Any) -> int:
    if isinstance(joint, str) and joint.strip() in JOINT_INDEX:
        return JOINT_INDEX[joint.strip()]
    if not isinstance(joint, bool) and isinstance(joint, int | np.integer) and 0 <= joint < NUM_JOINTS:
        return int(joint)
    raise ValueError(f"there is no joint {joint!r}: pick one of {', '.join(JOINT_NAMES)}")


def check_number(value: Any, low: float, high: float, what: str, unit: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = float("nan")
    if not (np.isfinite(number) and low <= number <= high):
        raise ValueError(f"{what} must be from {low:g} to {high:g} {unit}, got {value!r}")
    return number


def start_positions(count: int) -> np.ndarray:
    """(B, 3) starts: a row along x, everyone facing +Z."""
    starts = np.zeros((count, 3), np.float32)
    starts[:, 0] = (np.arange(count) - (count - 1) / 2) * START_SPACING
    return starts


def check_index(index: Any, count: int) -> int:
    if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 <= index < count:
        raise IndexError(f"there is no character {index!r} (this studio has {count})")
    return int(index)


def check_xz(xz: Any, what: str = "point") -> np.ndarray:
    arr = np.asarray(xz, np.float64).reshape(-1)
    if arr.shape != (2,) or not np.isfinite(arr).all():
        raise ValueError(f"a {what} must be two finite numbers (x, z), got {xz!r}")
    if np.abs(arr).max() > ARENA_HALF_SIZE:
        raise ValueError(
            f"the {what} ({arr[0]:.1f}, {arr[1]:.1f}) is off the floor: keep within "
            f"{ARENA_HALF_SIZE:g} m of the centre"
        )
    return arr
