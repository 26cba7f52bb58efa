"""The body's mass: where the centre of mass of a (..., 22, 3) joint set lies.

De Leva's segment masses and centres (P. de Leva, "Adjustments to Zatsiorsky-Seluyanov's segment
inertia parameters", J. Biomech. 29(9), 1996), the same as the replay's humanoid
(:mod:`motion_env.replay.humanoid`) carries on its bodies, here as fixed blends of each segment's
two joints, so that the centre of mass is one weighted sum of the joints: the physics stage moves
it, the robot retargeter places the robot's where the human's is.
"""

from __future__ import annotations

import numpy as np

from motion_env.motion.skeleton import NUM_JOINTS

__all__ = ["COM_WEIGHTS", "centre_of_mass"]


def _com_weights() -> np.ndarray:
    """(22,) weights w with centre of mass = sum_j w_j joints_j: de Leva's segment masses and
    centres (as the replay's humanoid, :mod:`motion_env.replay.humanoid`), each segment's centre a
    fixed blend of its two joints."""
    w = np.zeros(NUM_JOINTS)

    def segment(a: int, b: int, mass: float, at: float) -> None:  # centre at a + at * (b - a)
        w[a] += mass * (1.0 - at)
        w[b] += mass * at

    segment(3, 1, 0.1117 * 0.5, 0.6115)  # lower trunk: spine1 to the hips' midpoint
    segment(3, 2, 0.1117 * 0.5, 0.6115)
    segment(6, 3, 0.1000, 0.4502)  # middle trunk
    segment(9, 6, 0.0633, 0.4502)
    segment(12, 9, 0.1396, 0.2999)  # upper trunk
    segment(12, 15, 0.0694, 0.91)  # head: its centre lies just short of the head joint
    limbs = ((1, 4, 7, 10, 13, 16, 18, 20), (2, 5, 8, 11, 14, 17, 19, 21))  # left, right
    for hip, knee, ankle, toe, collar, shoulder, elbow, wrist in limbs:
        segment(hip, knee, 0.1416, 0.4095)
        segment(knee, ankle, 0.0433, 0.4459)
        segment(ankle, toe, 0.0137, 0.5)
        segment(collar, shoulder, 0.0100, 0.5)
        segment(shoulder, elbow, 0.0271, 0.5772)
        segment(elbow, wrist, 0.0162, 0.4574)
        segment(wrist, elbow, 0.0061, -0.27)  # the hand, past the wrist
    return w


COM_WEIGHTS = _com_weights()
"""(22,) joint weights of the centre of mass (they sum to 1): a vertical shift of every joint
shifts the centre of mass by as much."""


def centre_of_mass(joints: np.ndarray) -> np.ndarray:
    """Centre of mass of (..., 22, 3) joints -> (..., 3), within about 2 mm of the replay's."""
    return np.einsum("j,...jc->...c", COM_WEIGHTS, joints)
