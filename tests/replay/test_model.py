"""Tests of the replay model: the generated body (replay.humanoid), the compiled scene
(replay.mjcf) and the Menagerie-style folder motion_env/replay/model/."""

from __future__ import annotations

import json

import mujoco
import numpy as np
import pytest

from motion_env.motion.skeleton import JOINT_NAMES
from motion_env.replay import humanoid, measure
from motion_env.replay.mjcf import BODY_XML, MODEL_DIR, load_model, model_index, scene_xml
from motion_env.replay.plausibility import CHECKS, load_thresholds, thresholds_path


def test_model_builds_and_loads() -> None:
    body = humanoid.humanoid_xml()
    assert "floor" not in body and "<light" not in body  # body only; the scene adds them
    assert 'include file="humanoid.xml"' in scene_xml()
    model = load_model()
    assert model.nbody == 1 + len(humanoid.BODY_JOINTS)
    assert model.nq == 7 + 4 * len(humanoid.BALL_JOINTS) and model.nv == 6 + 3 * len(humanoid.BALL_JOINTS)
    assert model.body_mass.sum() == pytest.approx(humanoid.DEFAULT_MASS)
    assert set(humanoid.JOINT_TO_BODY) == set(JOINT_NAMES)
    for name in JOINT_NAMES:  # every canonical joint has a site, every body joint a ball joint
        assert mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name) >= 0
    for j in humanoid.BALL_JOINTS:
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, JOINT_NAMES[j])
        assert model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_BALL and model.jnt_limited[jid]
    assert np.all(model.body_inertia[1:] > 0)


def test_mass_is_a_parameter() -> None:
    heavy = load_model(mass=95.0)
    assert heavy.body_mass.sum() == pytest.approx(95.0)
    light = load_model(mass=50.0)
    # Proportions are fixed: every segment scales with the total.
    np.testing.assert_allclose(heavy.body_mass[1:] / 95.0, light.body_mass[1:] / 50.0, rtol=1e-5)
    with pytest.raises(ValueError, match="mass"):
        humanoid.humanoid_xml(mass=0.0)
    with pytest.raises(ValueError, match="unit vectors"):
        load_model(rest_directions=2.0 * humanoid.REST_DIRECTIONS)


def test_rest_pose_stands_on_the_floor(standing_clip) -> None:
    model = load_model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    index = model_index(model)
    # The soles touch the floor, nothing is under it, and heels are behind toes (+X is forward).
    soles = np.concatenate(list(index.foot_geoms.values()))
    bottoms = data.geom_xpos[soles, 2] - model.geom_size[soles, 0]
    np.testing.assert_allclose(bottoms, 0.0, atol=0.005)
    m = measure(standing_clip(0.5))
    assert m.lowest.min() > -0.005
    heel, toe = m.soles[0, 0], m.soles[0, 1]
    assert heel[0] < toe[0]
    assert data.site_xpos[index.joint_sites[JOINT_NAMES.index("head")], 2] > 1.4


def test_model_folder_holds_scene_body_thresholds_and_readme() -> None:
    files = {p.name for p in MODEL_DIR.iterdir()}
    assert files >= {"README.md", "scene.xml", "humanoid.xml", "thresholds.json"}
    # The shipped body file is the generator's default body: rebuild it with
    # `python -c "from motion_env.replay.mjcf import write_body_xml; write_body_xml()"`.
    assert BODY_XML.read_text() == humanoid.humanoid_xml(), "model/humanoid.xml is out of date"
    # Opened from the folder (as a viewer would), the scene includes that file.
    from_files = mujoco.MjModel.from_xml_path(str(MODEL_DIR / "scene.xml"))
    generated = load_model()
    assert from_files.nbody == generated.nbody and from_files.ngeom == generated.ngeom
    np.testing.assert_allclose(from_files.body_mass, generated.body_mass)
    assert thresholds_path() == MODEL_DIR / "thresholds.json"
    assert set(json.loads(thresholds_path().read_text())["thresholds"]) == set(CHECKS)
    assert set(load_thresholds()) == set(CHECKS)


def test_write_body_xml(tmp_path) -> None:
    from motion_env.replay.mjcf import write_body_xml

    out = write_body_xml(tmp_path / "humanoid.xml")
    assert out.read_text() == BODY_XML.read_text()
