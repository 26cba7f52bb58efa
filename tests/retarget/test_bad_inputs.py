"""Bad inputs to `motion_env.retarget`: each a clear error naming the problem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import motion_env
from motion_env.motion.types import Motion

_BOX = """<mujoco><worldbody><body name="crate"><freejoint/><geom type="box" size=".2 .2 .2"/>
<body name="lid"><joint type="hinge"/><geom type="box" size=".2 .2 .01"/></body></body>
</worldbody></mujoco>"""


def test_not_a_humanoid(tmp_path: Path, waving_clip) -> None:
    path = tmp_path / "crate.xml"
    path.write_text(_BOX)
    with pytest.raises(ValueError, match="no legs found in .*crate.xml"):
        motion_env.retarget(waving_clip(frames=4), robot=path)


def test_unknown_robot_lists_the_known_ones(waving_clip) -> None:
    with pytest.raises(ValueError, match=r"unknown robot 'nao'.*\['booster_t1', 'unitree_g1'\]"):
        motion_env.retarget(waving_clip(frames=4), robot="nao")


def test_missing_model_file(tmp_path: Path, waving_clip) -> None:
    with pytest.raises(FileNotFoundError, match="no robot model at"):
        motion_env.retarget(waving_clip(frames=4), robot=tmp_path / "robot.xml")


def test_nan_frames(waving_clip) -> None:
    joints = waving_clip(frames=6).joints.copy()
    joints[3, 5] = np.nan
    with pytest.raises(ValueError, match=r"motion has NaN or infinite values at frames \[3\]"):
        motion_env.retarget(joints)
    clip = Motion(waving_clip(frames=6).joints)
    clip.joints[4, 0, 1] = np.inf  # a Motion changed after it was made
    with pytest.raises(ValueError, match=r"NaN or infinite values at frames \[4\]"):
        motion_env.retarget(clip)


def test_one_frame(waving_clip) -> None:
    with pytest.raises(ValueError, match="motion has 1 frame; retargeting needs a clip of at least 2"):
        motion_env.retarget(waving_clip(frames=1))


@pytest.mark.parametrize("fps", [0, -50, float("nan"), float("inf"), True, "50"])
def test_bad_fps(fps, waving_clip) -> None:
    with pytest.raises(ValueError, match="fps must be a positive number"):
        motion_env.retarget(waving_clip(frames=4), fps=fps)


def test_bad_types(waving_clip) -> None:
    with pytest.raises(TypeError, match="motion must be a motion_env.Motion"):
        motion_env.retarget("walk.npz")
    with pytest.raises(ValueError, match=r"motion must have shape \(T, 22, 3\)"):
        motion_env.retarget(np.zeros((5, 21, 3)))
    with pytest.raises(TypeError, match="robot must be a robot name or a path"):
        motion_env.retarget(waving_clip(frames=4), robot=7)


def test_legs_without_a_free_root(tmp_path: Path, waving_clip) -> None:
    legs = "".join(
        f'<body name="{side}_hip" pos="0 {y} 0.9"><joint type="hinge"/><geom size=".05"/>'
        f'<body name="{side}_knee" pos="0 0 -0.4"><joint type="hinge"/><geom size=".05"/>'
        f'<body name="{side}_ankle" pos="0 0 -0.4"><joint type="hinge"/><geom size=".05"/>'
        "</body></body></body>"
        for side, y in (("left", 0.1), ("right", -0.1))
    )
    path = tmp_path / "fixed.xml"
    path.write_text(f'<mujoco><worldbody><body name="pelvis">{legs}</body></worldbody></mujoco>')
    with pytest.raises(ValueError, match="needs exactly one free joint"):
        motion_env.retarget(waving_clip(frames=4), robot=path)


def test_a_table_without_legs(tmp_path: Path, waving_clip) -> None:
    import json

    from motion_env.retarget.robot import ROBOTS_DIR, TABLE_NAME

    raw = json.loads((ROBOTS_DIR / "unitree_g1" / TABLE_NAME).read_text())
    raw["model"] = str(ROBOTS_DIR / "unitree_g1" / "scene.xml")
    raw["tasks"] = [t for t in raw["tasks"] if not t.get("human", "").endswith("ankle")]
    path = tmp_path / "no_ankles.json"
    path.write_text(json.dumps(raw))
    with pytest.raises(ValueError, match=r"no_ankles.json: no legs found: .*'left_ankle', 'right_ankle'"):
        motion_env.retarget(waving_clip(frames=4), robot=path)
