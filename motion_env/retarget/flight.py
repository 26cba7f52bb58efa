"""Flight phases on the robot: while neither foot is on the floor, the centre of mass falls freely.

The retargeter sets each frame's root height from the feet (:mod:`.floor`): while the human is in
the air, the robot's body rises and falls with its lowest foot, scaled. That arc is not a free
fall: the human's feet tuck and reach relative to their centre of mass, and the robot is smaller
than the human but keeps the human's timing, so the scaled arc falls at about half of g. No
floor can supply the difference, and a tracking controller cannot follow it: the robot replay
(:func:`motion_env.replay.evaluate_robot`) reads it as a root force of 4 to 16 N/kg in the
flights of a run, over the humanoid's calibrated 4.5 N/kg.

:func:`ballistic_lift` replaces the height of the robot's centre of mass in each flight by the
parabola under gravity through its heights at take-off and landing (the frames on the floor on
either side); a flight at either end of the clip keeps the end it has and the vertical speed
that fits its arc best. The root moves by the same amount, so the legs and arms keep their
poses relative to the body.
"""

from __future__ import annotations

import numpy as np

__all__ = ["AIR_CLEARANCE", "GRAVITY", "MAX_FLIGHT", "ballistic_lift", "flights"]

GRAVITY = 9.81  # m/s^2
AIR_CLEARANCE = 0.02
"""A frame is a flight when the lower of the robot's foot targets (the human's scaled foot
clearance, :attr:`.ik_goals.Targets.floor_height`) is this high (m): a human stance reads a few
millimetres of clearance, a flight of a run 3 to 7 cm."""
MAX_FLIGHT = 0.7
"""Seconds: a longer time with both feet up is not a flight (a 45 cm standing jump is in the air
0.6 s) but a body held up by what the floor model does not know, or a clip that floats; it is
left as it is (the robot replay judges it) rather than made a jump metres high."""


def flights(in_air: np.ndarray) -> list[tuple[int, int]]:
    """The runs of True in `in_air` (T,), each as ``(first, last)`` frame indices, inclusive."""
    edges = np.diff(np.concatenate([[0], in_air.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1).tolist(), (np.flatnonzero(edges == -1) - 1).tolist()))


def ballistic_lift(com_height: np.ndarray, in_air: np.ndarray, fps: float) -> np.ndarray:
    """(T,) height (m) to add to each frame's root so that the centre of mass falls freely in every
    flight (`in_air`, (T,) bool), from `com_height` (T,) at `fps`; 0 on the frames on the floor.

    A flight between two frames on the floor gets the parabola of acceleration -GRAVITY through
    the centre's heights there. A flight that reaches the first or the last frame is pinned at
    its floor end only, with the vertical speed that fits its heights best (least squares); a
    clip all in the air, and a flight longer than :data:`MAX_FLIGHT`, are left as they are.
    """
    com_height = np.asarray(com_height, dtype=np.float64)
    lift = np.zeros_like(com_height)
    n = len(com_height)
    for first, last in flights(np.asarray(in_air, dtype=bool)):
        if (last - first + 1) / fps > MAX_FLIGHT:
            continue
        before, after = first - 1, last + 1
        frames = np.arange(first, last + 1)
        if before >= 0 and after < n:
            t, span = (frames - before) / fps, (after - before) / fps
            chord = com_height[before] + (com_height[after] - com_height[before]) * t / span
            arc = chord + 0.5 * GRAVITY * t * (span - t)
        elif before >= 0 or after < n:
            pin = before if before >= 0 else after
            t = (frames - pin) / fps
            fall = com_height[pin] - 0.5 * GRAVITY * t**2
            speed = float(np.dot(t, com_height[frames] - fall) / np.dot(t, t))
            arc = fall + speed * t
        else:
            continue
        lift[frames] = arc - com_height[frames]
    return lift
