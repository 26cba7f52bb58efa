"""The mapping table of a robot: which robot body or site tracks which part of the human.

One JSON file per robot (``robots/<name>/retarget.json``), so a new robot is a table and not new
code::

    {
      "robot": "unitree_g1",
      "model": "scene.xml",                 # the MJCF, relative to the table
      "root": "pelvis",                     # the body with the free joint
      "feet": {"left": "left_ankle_roll_link", "right": "right_ankle_roll_link"},
      "home": "stand",                      # keyframe: first guess and posture (optional)
      "posture_cost": 0.05,                 # pull of every joint towards the home pose
      "tasks": [
        {"frame": "BODY_25:LHip", "type": "site", "human": "left_hip", "position_cost": 5},
        {"frame": "pelvis", "type": "body", "orientation": "pelvis", "orientation_cost": 5},
        ...
      ]
    }

A task's ``human`` is a joint of the canonical skeleton whose position the frame follows;
``orientation`` is a human segment (:data:`motion_env.retarget.human.FRAMES`) whose orientation it
follows. A task with zero costs is a reference point only: it measures the robot's limb lengths
but is not tracked. Both hips and both ankles are required (they place and size the robot); an
arm or leg joint needs the limb's root (hip, shoulder) in the table too.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from motion_env.motion.skeleton import JOINT_INDEX
from motion_env.retarget.human import FRAMES, LIMBS

__all__ = ["FRAME_TYPES", "RobotTable", "Task", "describe_table", "read_table"]

FRAME_TYPES = ("body", "site")


@dataclass(frozen=True)
class Task:
    """One tracked robot frame (see the module docstring for the fields)."""

    frame: str
    type: str = "body"
    human: str | None = None
    position_cost: float = 0.0
    orientation: str | None = None
    orientation_cost: float = 0.0

    def __post_init__(self) -> None:
        where = f"task {self.frame!r}"
        if self.type not in FRAME_TYPES:
            raise ValueError(f"{where}: type must be one of {FRAME_TYPES}, got {self.type!r}")
        if self.human is not None and self.human not in JOINT_INDEX:
            raise ValueError(f"{where}: human joint {self.human!r} is not one of {sorted(JOINT_INDEX)}")
        if self.orientation is not None and self.orientation not in FRAMES:
            raise ValueError(f"{where}: orientation {self.orientation!r} is not one of {FRAMES}")
        for name in ("position_cost", "orientation_cost"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not value >= 0:
                raise ValueError(f"{where}: {name} must be a number >= 0, got {value!r}")
        if self.position_cost > 0 and self.human is None:
            raise ValueError(f"{where}: a position_cost needs the human joint it follows ('human')")
        if self.orientation_cost > 0 and self.orientation is None:
            raise ValueError(f"{where}: an orientation_cost needs the human segment it follows")


@dataclass(frozen=True)
class RobotTable:
    """A robot's mapping table: the model file, its root and feet, and the tracked frames."""

    robot: str
    model: Path
    root: str
    feet: dict[str, str]  # "left", "right" -> the foot body (its subtree's geoms stand on the floor)
    tasks: tuple[Task, ...]
    home: str | None = None
    posture_cost: float = 0.05
    source: str = field(default="", compare=False)  # where the table came from, for messages

    def __post_init__(self) -> None:
        where = self.source or self.robot
        if not isinstance(self.feet, dict) or set(self.feet) != {"left", "right"}:
            raise ValueError(f"{where}: 'feet' must be {{'left': <foot body>, 'right': <foot body>}}")
        if not (isinstance(self.posture_cost, (int, float)) and self.posture_cost >= 0):
            raise ValueError(f"{where}: posture_cost must be a number >= 0, got {self.posture_cost!r}")
        mapped = {t.human for t in self.tasks if t.human is not None}
        missing = [j for j in ("left_hip", "right_hip", "left_ankle", "right_ankle") if j not in mapped]
        if missing:
            raise ValueError(f"{where}: no legs found: the table maps no robot frame to {missing}")
        for limb, names in LIMBS.items():
            if mapped & set(names[1:]) and names[0] not in mapped:
                raise ValueError(f"{where}: the {limb} is tracked but its root {names[0]!r} is not mapped")

    def point(self, human: str) -> Task | None:
        """The task that follows human joint `human`, if any."""
        return next((t for t in self.tasks if t.human == human), None)


def read_table(path: str | Path) -> RobotTable:
    """Read and check a mapping table (JSON), or ValueError naming the file and the field."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no robot mapping table at {path}")
    try:
        raw: dict[str, Any] = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not valid JSON ({exc})") from exc
    known = {"robot", "model", "root", "feet", "tasks", "home", "posture_cost", "description"}
    unknown = sorted(set(raw) - known)
    if unknown:
        raise ValueError(f"{path}: unknown fields {unknown} (known: {sorted(known)})")
    for key in ("model", "root", "feet", "tasks"):
        if key not in raw:
            raise ValueError(f"{path}: missing field {key!r}")
    try:
        tasks = tuple(Task(**task) for task in raw["tasks"])
    except (TypeError, ValueError) as exc:  # TypeError: a task with an unknown key
        raise ValueError(f"{path}: {exc}") from exc
    return RobotTable(
        robot=str(raw.get("robot", path.parent.name)),
        model=(path.parent / raw["model"]).resolve(),
        root=str(raw["root"]),
        feet=raw["feet"],
        tasks=tasks,
        home=raw.get("home"),
        posture_cost=raw.get("posture_cost", 0.05),
        source=str(path),
    )


def describe_table(table: RobotTable) -> str:
    """The mapping as text, one line per task: which robot frame follows which human joint or
    segment, and at what cost; then the limbs the table does not track."""
    lines = [
        f"robot {table.robot}: {table.source or table.model}",
        f"  root body {table.root}; feet {table.feet['left']} (left), {table.feet['right']} (right)",
    ]
    for t in table.tasks:
        follows = []
        if t.human is not None:
            cost = f" (cost {t.position_cost:g})" if t.position_cost else ""
            follows.append(f"{t.human} position{cost}")
        if t.orientation is not None:
            follows.append(f"{t.orientation} orientation (cost {t.orientation_cost:g})")
        role = ", ".join(follows) if t.position_cost or t.orientation_cost else "reference only"
        lines.append(f"  {t.type} {t.frame:<28} <- {role}")
    mapped = {t.human for t in table.tasks if t.human is not None}
    for limb, names in LIMBS.items():
        missing = [n for n in names if n not in mapped and n.split("_", 1)[1] != "foot"]
        if missing:
            lines.append(f"  not tracked: {', '.join(missing)} ({limb.replace('_', ' ')})")
    return "\n".join(lines)
