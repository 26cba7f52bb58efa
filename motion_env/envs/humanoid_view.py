"""The env's picture drawn with the MuJoCo humanoid of :mod:`motion_env.replay` (render_style="humanoid").

Each frame's joint positions are fitted to the humanoid's joint angles
(:func:`motion_env.replay.fit.fit_qpos`) and drawn offscreen by ``mujoco.Renderer``, with the
trail, the waypoints, the target and the obstacles added to the scene as extra geoms. Offscreen
OpenGL needs ``MUJOCO_GL=egl`` (or ``osmesa``) on a machine without a display; it is set to "egl"
when unset, before mujoco is first imported.
"""

from __future__ import annotations

import os

import numpy as np

_TRAIL_RGBA = np.array([0.36, 0.49, 0.98, 1.0], np.float32)
_WAYPOINT_RGBA = np.array([0.61, 0.21, 0.71, 1.0], np.float32)
_TARGET_RGBA = np.array([0.84, 0.2, 0.42, 1.0], np.float32)
_OBSTACLE_RGBA = np.array([0.53, 0.56, 0.59, 0.9], np.float32)
_OBSTACLE_HEIGHT = 0.8
_TRAIL_EVERY = 4  # draw every 4th trail point (a dot per 0.2 s)


class HumanoidView:
    """An offscreen MuJoCo renderer of the replay humanoid, reused across frames.

    Raises:
        RuntimeError: MuJoCo cannot open an offscreen OpenGL context here.
    """

    def __init__(self, width: int, height: int) -> None:
        os.environ.setdefault("MUJOCO_GL", "egl")
        import mujoco

        from motion_env.replay.humanoid import load_model, model_index

        self._mujoco = mujoco
        self.model = load_model()
        self.index = model_index(self.model)
        self.data = mujoco.MjData(self.model)
        self.model.vis.global_.offwidth = max(self.model.vis.global_.offwidth, width)
        self.model.vis.global_.offheight = max(self.model.vis.global_.offheight, height)
        try:
            self.renderer = mujoco.Renderer(self.model, height=height, width=width)
        except Exception as exc:  # mujoco raises FatalError, not exported as a type everywhere
            raise RuntimeError(
                f"MuJoCo could not open an offscreen OpenGL context ({exc}); set MUJOCO_GL=egl or osmesa "
                "before Python imports mujoco, or use render_style='stick'"
            ) from exc
        self.camera = mujoco.MjvCamera()
        self.camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.camera.distance, self.camera.azimuth, self.camera.elevation = 5.0, 150.0, -18.0

    def draw(
        self,
        joints: np.ndarray,
        trail: np.ndarray | None = None,
        target: np.ndarray | None = None,
        waypoints: np.ndarray | None = None,
        obstacles: np.ndarray | None = None,
    ) -> np.ndarray:
        """RGB image (height, width, 3) uint8 of one pose (22, 3) and the scene around it.

        trail: (N, 2) x, z walked so far; target: (2,); waypoints: (K, 2+); obstacles: (M, 3) circles.
        """
        from motion_env.replay.fit import fit_qpos

        mujoco = self._mujoco
        qpos = fit_qpos(np.asarray(joints, np.float64)[None], self.model, self.index)[0]
        self.data.qpos[:] = qpos
        mujoco.mj_forward(self.model, self.data)
        pelvis = np.asarray(joints, np.float64)[0]
        # MuJoCo's frame: x = motion z (forward), y = motion x (left), z = up.
        self.camera.lookat[:] = (pelvis[2], pelvis[0], 0.9)
        self.renderer.update_scene(self.data, self.camera)
        scene = self.renderer.scene
        eye = np.eye(3).reshape(-1)

        def add(
            kind: int, size: tuple[float, float, float], xz: np.ndarray, z: float, rgba: np.ndarray
        ) -> None:
            if scene.ngeom >= scene.maxgeom:
                return
            pos = np.array([xz[1], xz[0], z], np.float64)
            mujoco.mjv_initGeom(scene.geoms[scene.ngeom], kind, np.array(size, np.float64), pos, eye, rgba)
            scene.ngeom += 1

        sphere, cylinder = mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER
        if trail is not None and len(trail):
            for point in np.asarray(trail)[::_TRAIL_EVERY]:
                add(sphere, (0.03, 0.03, 0.03), point, 0.02, _TRAIL_RGBA)
        if waypoints is not None:
            for point in np.asarray(waypoints)[:, :2]:
                add(cylinder, (0.15, 0.15, 0.01), point, 0.01, _WAYPOINT_RGBA)
        if target is not None:
            add(cylinder, (0.06, 0.06, 0.4), np.asarray(target), 0.4, _TARGET_RGBA)
        if obstacles is not None:
            for x, z, r in np.asarray(obstacles):
                add(
                    cylinder,
                    (r, r, 0.5 * _OBSTACLE_HEIGHT),
                    np.array([x, z]),
                    0.5 * _OBSTACLE_HEIGHT,
                    _OBSTACLE_RGBA,
                )
        return self.renderer.render().copy()

    def close(self) -> None:
        self.renderer.close()
