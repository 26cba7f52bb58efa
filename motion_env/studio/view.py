"""The 3-D scene of the studio page, drawn with viser: floor, characters, trails, routes, obstacles,
joint targets.

:class:`SceneView` owns every scene node. It is built once per studio and then told, once per
frame, what a :class:`~motion_env.studio.session.Snapshot` holds; only what moved is sent (the
figures every frame, the trails every few frames, waypoints and obstacles when they change), since
every node update is a message to every open tab.

Colours are the stick-figure videos' (:mod:`motion_env.render.drawing`): left limbs blue, right
limbs orange, the spine dark grey, the trail blue, waypoints purple, the next one pink; a joint
target is a red sphere on a thin stem from the floor, labelled with its joint and time, grey once met.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import viser

from motion_env.motion.skeleton import FPS, JOINT_INDEX, JOINT_NAMES
from motion_env.render.drawing import (
    HIGHLIGHT_COLOR,
    MAX_LABELLED_WAYPOINTS,
    OBSTACLE_COLOR,
    PASSED_COLOR,
    SPINE_COLOR,
    TARGET_COLOR,
    TRAIL_COLOR,
    WAYPOINT_COLOR,
    hex_rgb,
)
from motion_env.studio.geometry import ARENA_HALF_SIZE, bone_colors, bone_segments, joint_colors
from motion_env.studio.robot_view import RobotView
from motion_env.studio.state import Snapshot

__all__ = ["SceneView"]

_HEAD = JOINT_INDEX["head"]
_TRAIL_EVERY = 4  # frames between trail updates: a trail is up to 1200 points
_FLOOR_Y = 0.01  # lines on the floor sit just above it, so that the floor does not hide them
_GOAL_COLOR = "#2f9e44"
_OBSTACLE_HEIGHT = 0.8


def _rgb(color: str) -> tuple[int, int, int]:
    r, g, b = (int(round(v * 255)) for v in hex_rgb(color))
    return r, g, b


def _on_floor(xz: np.ndarray, y: float = _FLOOR_Y) -> np.ndarray:
    """(N, 2) floor points -> (N, 3) world points just above the floor."""
    xz = np.asarray(xz, np.float32).reshape(-1, 2)
    return np.stack([xz[:, 0], np.full(len(xz), y, np.float32), xz[:, 1]], axis=1)


def _polyline(points: np.ndarray) -> np.ndarray:
    """(N, 3) points -> (N - 1, 2, 3) segments (one degenerate segment for fewer than 2 points)."""
    if len(points) < 2:
        points = np.repeat(points[:1] if len(points) else np.zeros((1, 3), np.float32), 2, axis=0)
    return np.stack([points[:-1], points[1:]], axis=1).astype(np.float32)


def _add_floor(scene: viser.SceneApi) -> viser.MeshHandle:
    """The floor and its grid (1 m sections of 0.5 m cells); returns the floor.

    The floor is a real mesh: clicks on it are where the camera ray meets y = 0, and a drag with
    shift held draws a path on it.
    """
    size = 2 * ARENA_HALF_SIZE
    verts = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32) * ARENA_HALF_SIZE
    verts[:, 1] = -0.002
    floor = scene.add_mesh_simple(
        "/floor",
        verts,
        np.array([[0, 2, 1], [0, 3, 2]], np.uint32),
        color=(238, 240, 243),
        side="double",
        cast_shadow=False,
        receive_shadow=False,
    )
    scene.add_grid(
        "/grid",
        width=size,
        height=size,
        plane="xz",
        cell_size=0.5,
        section_size=1.0,
        cell_color=(205, 208, 214),
        section_color=(150, 155, 165),
        shadow_opacity=0.0,
    )
    return floor


def _floor_line(
    scene: viser.SceneApi, name: str, color: str, thickness: float, visible: bool = True
) -> viser.LineSegmentsHandle:
    """A line on the floor, empty until its first points."""
    return scene.add_line_segments(
        name, _polyline(_on_floor(np.zeros((1, 2)))), _rgb(color), thickness=thickness, visible=visible
    )


# A cylinder's axis in viser is its local +Z; the studio's world is Y up.
_Z_TO_Y = (np.cos(-np.pi / 4), np.sin(-np.pi / 4), 0.0, 0.0)


class SceneView:
    """The scene nodes of one studio, shared by every tab.

    Args:
        server: the viser server.
        count: how many characters.
        on_drag_waypoint: called as (character, waypoint, event) while a waypoint sphere is dragged.
    """

    def __init__(
        self,
        server: viser.ViserServer,
        count: int,
        on_drag_waypoint: Callable[[int, int, viser.SceneNodeDragEvent], None],
    ) -> None:
        self._server = server
        self._count = count
        self._on_drag_waypoint = on_drag_waypoint
        server.scene.set_up_direction("+y")
        self.floor = _add_floor(server.scene)
        self._bones: list = []  # per character: its nodes
        self._joints: list = []
        self._heads: list = []
        self._trails: list = []
        self._ahead: list = []
        self._labels: list = []  # a number over each head, for a crowd
        for i in range(count):
            self._add_character(i)
        self._waypoint_nodes: list[list] = [[] for _ in range(count)]
        self._goal_nodes: list = [None] * count
        self._target_nodes: list[list] = [[] for _ in range(count)]
        self._obstacle_nodes: list = []
        self._drawn_version: tuple | None = None
        self._drawn_obstacles: np.ndarray = np.zeros((0, 3))
        self.robot = RobotView(server.scene)
        self._on_robot: int | None = None  # the character the robot stands in for

    def _add_character(self, i: int) -> None:
        """Character i's nodes: bones, joints, head, trail, the line to its next waypoints and, in a
        crowd, its number; their points come with the first frame."""
        scene = self._server.scene
        zero = np.zeros((22, 3), np.float32)
        self._bones.append(
            scene.add_line_segments(
                f"/character{i}/bones", bone_segments(zero), bone_colors(), thickness=0.045
            )
        )
        self._joints.append(
            scene.add_point_cloud(
                f"/character{i}/joints",
                zero,
                joint_colors(),
                point_size=0.06,
                point_shape="rounded",
                precision="float32",
            )
        )
        self._heads.append(scene.add_icosphere(f"/character{i}/head", 0.1, _rgb(SPINE_COLOR), subdivisions=2))
        self._trails.append(_floor_line(scene, f"/character{i}/trail", TRAIL_COLOR, 0.03))
        self._ahead.append(_floor_line(scene, f"/character{i}/ahead", TARGET_COLOR, 0.02, visible=False))
        if self._count > 1:
            self._labels.append(scene.add_label(f"/character{i}/label", str(i + 1), anchor="bottom-center"))

    # ------------------------------------------------------------------ per frame
    def draw(self, snap: Snapshot) -> None:
        """Show `snap`: the figures always, the rest when it changed."""
        with self._server.atomic():
            for i in range(self._count):
                joints = snap.joints[i]
                self._bones[i].points = bone_segments(joints)
                self._joints[i].points = joints
                self._heads[i].position = joints[_HEAD] + np.array([0.0, 0.06, 0.0], np.float32)
                if self._labels:
                    self._labels[i].position = joints[_HEAD] + np.array([0.0, 0.3, 0.0], np.float32)
                if snap.frame % _TRAIL_EVERY == 0:
                    self._trails[i].points = _polyline(_on_floor(snap.trails[i]))
                self._draw_ahead(i, snap)
            self._draw_robot(snap)
            if snap.version != self._drawn_version:
                self._drawn_version = snap.version
                for i in range(self._count):
                    self._draw_route(i, snap)
                    self._draw_goal(i, snap.goals[i])
                    self._draw_targets(i, snap)
                    if self._labels:
                        self._labels[i].text = f"{i + 1}: {_short(snap.captions[i])}"
                if not np.array_equal(snap.obstacles, self._drawn_obstacles):
                    self._draw_obstacles(snap.obstacles)

    def _draw_robot(self, snap: Snapshot) -> None:
        """The robot view: the robot in place of its character's figure (the trail stays)."""
        on = None if snap.robot is None else snap.robot.character
        if on != self._on_robot:
            for i in range(self._count):
                for nodes in (self._bones, self._joints, self._heads):
                    nodes[i].visible = i != on
            self._on_robot = on
        self.robot.draw(snap.robot)

    def _draw_ahead(self, i: int, snap: Snapshot) -> None:
        route, k = snap.routes[i], snap.next_waypoint[i]
        node = self._ahead[i]
        if not len(route) or snap.reached[i]:
            node.visible = False
            return
        pelvis = snap.joints[i, 0, [0, 2]]
        node.points = _polyline(_on_floor(np.concatenate([pelvis[None], route[k:, :2]])))
        node.visible = True

    def _draw_route(self, i: int, snap: Snapshot) -> None:
        scene = self._server.scene
        for node in self._waypoint_nodes[i]:
            node.remove()  # and its label, a child node
        nodes = self._waypoint_nodes[i] = []
        route, k = snap.routes[i], snap.next_waypoint[i]
        dense = len(route) > MAX_LABELLED_WAYPOINTS  # a drawn path: small dots, no numbers
        for j, (x, z, t) in enumerate(route):
            passed = j < k or (snap.reached[i] and j == len(route) - 1)
            color = PASSED_COLOR if passed else TARGET_COLOR if j == k else WAYPOINT_COLOR
            sphere = scene.add_icosphere(
                f"/character{i}/waypoint{j}",
                0.06 if dense else 0.12,
                _rgb(color),
                subdivisions=2,
                position=(float(x), 0.12, float(z)),
            )
            sphere.on_drag("left")(self._drag_handler(i, j))
            nodes.append(sphere)
            if not dense:
                when = "" if np.isnan(t) else f" ({t / FPS:.1f} s)"
                who = f"{i + 1}." if self._count > 1 else ""
                scene.add_label(
                    f"/character{i}/waypoint{j}/label",
                    f"{who}{j + 1}{when}",
                    position=(0.0, 0.2, 0.0),
                    anchor="bottom-center",
                )

    def _drag_handler(self, i: int, j: int) -> Callable[[viser.SceneNodeDragEvent], None]:
        def handle(event: viser.SceneNodeDragEvent) -> None:
            self._on_drag_waypoint(i, j, event)

        return handle

    def _draw_goal(self, i: int, goal: np.ndarray | None) -> None:
        if self._goal_nodes[i] is not None:
            self._goal_nodes[i].remove()
            self._goal_nodes[i] = None
        if goal is not None:
            self._goal_nodes[i] = self._server.scene.add_cylinder(
                f"/character{i}/goal",
                radius=0.3,
                height=0.04,
                color=_rgb(_GOAL_COLOR),
                wxyz=_Z_TO_Y,
                position=(float(goal[0]), 0.02, float(goal[1])),
            )

    def _draw_targets(self, i: int, snap: Snapshot) -> None:
        """Character i's joint targets: a sphere where the joint is asked to be, a stem down to the
        floor, a label (joint and time); grey once its frame has been played."""
        scene = self._server.scene
        for node in self._target_nodes[i]:
            node.remove()  # and its label, a child node
        nodes = self._target_nodes[i] = []
        who = f"{i + 1}." if self._count > 1 else ""
        for k, (frame, j, x, y, z) in enumerate(snap.joint_targets[i]):
            color = _rgb(PASSED_COLOR if frame < snap.frame else HIGHLIGHT_COLOR)
            where = (float(x), float(y), float(z))
            sphere = scene.add_icosphere(
                f"/character{i}/jtarget{k}", 0.05, color, subdivisions=2, position=where
            )
            scene.add_label(
                f"/character{i}/jtarget{k}/label",
                f"{who}{JOINT_NAMES[int(j)]} ({frame / FPS:.1f} s)",
                position=(0.0, 0.08, 0.0),
                anchor="bottom-center",
            )
            stem = np.array([[[x, _FLOOR_Y, z], [x, y, z]]], np.float32)
            nodes += [
                sphere,
                scene.add_line_segments(f"/character{i}/jtarget{k}_stem", stem, color, thickness=0.01),
            ]

    def _draw_obstacles(self, obstacles: np.ndarray) -> None:
        for node in self._obstacle_nodes:
            node.remove()
        self._obstacle_nodes = [
            self._server.scene.add_cylinder(
                f"/obstacles/{k}",
                radius=float(r),
                height=_OBSTACLE_HEIGHT,
                color=_rgb(OBSTACLE_COLOR),
                wxyz=_Z_TO_Y,
                position=(float(x), _OBSTACLE_HEIGHT / 2, float(z)),
                opacity=0.85,
            )
            for k, (x, z, r) in enumerate(obstacles)
        ]
        self._drawn_obstacles = obstacles.copy()


def _short(text: str, length: int = 40) -> str:
    return text if len(text) <= length else text[: length - 1] + "…"
