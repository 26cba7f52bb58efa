"""The perspective camera of the stick-figure pictures, and where it looks in a video.

- :class:`Camera`: a view direction, distance and lens, looking at a floor point;
- :func:`follow_centers`: the smoothed pelvis path a following camera looks at;
- :func:`framing_camera`: the nearest camera (same direction) that keeps a whole scene in view.

World conventions (see :mod:`motion_env.motion.skeleton`): metres, Y up, floor at y = 0, the
character faces +Z at heading 0 and its left is +X.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Annotated

import numpy as np

from motion_env.motion.validation import CheckedConfig, PositiveFloat


@dataclass(frozen=True)
class Camera(CheckedConfig):
    """A perspective camera looking at a target point from a fixed direction.

    Attributes:
        azimuth_deg: direction from the target to the eye, degrees from +Z towards +X (a
            character facing +Z is seen from its front-left for values in (0, 90)).
        elevation_deg: how far the eye is above the target, degrees above the horizon.
        distance: eye-to-target distance in metres.
        focal: projection scale; the image half-height spans 1 / focal of the depth
            (vertical field of view = 2 atan(1 / focal)).
        look_height: height in metres of the point the camera looks at.
    """

    azimuth_deg: float = 55.0
    elevation_deg: Annotated[float, "(-89, 89)"] = 18.0
    distance: PositiveFloat = 4.8
    focal: PositiveFloat = 2.4
    look_height: float = 0.8

    def basis(self) -> np.ndarray:
        """(3, 3) rows: the camera's right, up and forward unit vectors in world coordinates."""
        az, el = math.radians(self.azimuth_deg), math.radians(self.elevation_deg)
        to_eye = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
        forward = -to_eye
        right = np.cross(forward, [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return np.stack([right, up, forward])

    def eye(self, center_xz: np.ndarray) -> np.ndarray:
        """(3,) eye position when looking at the floor point `center_xz` (2,) at `look_height`."""
        target = np.array([center_xz[0], self.look_height, center_xz[1]])
        return target - self.distance * self.basis()[2]


def follow_centers(root_xz: np.ndarray, fps: float, window_s: float = 1.5) -> np.ndarray:
    """(T, 2) camera targets: the pelvis path smoothed by a centred moving average.

    Following the raw pelvis would shake the whole picture with every step's sway.
    """
    n = max(1, int(round(window_s * fps)) | 1)
    pad = n // 2
    padded = np.concatenate([np.repeat(root_xz[:1], pad, 0), root_xz, np.repeat(root_xz[-1:], pad, 0)])
    csum = np.cumsum(np.concatenate([np.zeros((1, 2)), padded]), axis=0)
    return (csum[n:] - csum[:-n]) / n


def framing_camera(points: np.ndarray, camera: Camera, aspect: float) -> tuple[Camera, np.ndarray]:
    """A camera (same direction) and floor centre (2,) that keep all (N, 3) points in view."""
    lo, hi = points.min(0), points.max(0)
    center = (lo[[0, 2]] + hi[[0, 2]]) / 2
    camera = replace(camera, look_height=float((lo[1] + hi[1]) / 2))
    basis = camera.basis()

    def fits(distance: float) -> bool:
        eye = np.array([center[0], camera.look_height, center[1]]) - distance * basis[2]
        cam = (points - eye) @ basis.T
        if (cam[:, 2] < 0.5).any():
            return False
        screen = camera.focal * cam[:, :2] / cam[:, 2:]
        # Leave room for the title at the top and the frame counter at the bottom.
        return bool((np.abs(screen[:, 0]) < 0.92 * aspect).all() and (np.abs(screen[:, 1]) < 0.8).all())

    near, far = 0.5, 1.0
    while not fits(far) and far < 1e4:
        far *= 2
    for _ in range(30):  # bisection: the smallest distance that still frames everything
        mid = (near + far) / 2
        near, far = (near, mid) if fits(mid) else (mid, far)
    return replace(camera, distance=far), center
