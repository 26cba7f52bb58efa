"""Tests of the MuJoCo replay: the humanoid, the fit, the checks, the CLI."""

from __future__ import annotations

import io
import json
import time
from contextlib import redirect_stdout
from pathlib import Path

import mujoco
import numpy as np
import pytest

from motion_env.motion.skeleton import JOINT_NAMES, NUM_JOINTS
from motion_env.motion.types import Motion
from motion_env.replay import corruptions, evaluate, format_report, humanoid, measure
from motion_env.replay.checks import CHECKS, load_thresholds
from motion_env.replay.fit import clip_rest_directions, fit_qpos

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
SAMPLE = DATA / "humanml3d_sample" / "new_joints" / "012314.npy"
BANDAI = DATA / "bandai" / "dataset-2" / "bvh"


def _need(path: Path) -> None:
    if not path.exists():
        pytest.skip(f"real motion capture not found at {path} (../shared/data is absent)")


def _held_out_takes() -> list[Path]:
    """One test-split take per kind: walk, walk-turn-left, walk-turn-right, run (Bandai dataset 2)."""
    from motion_env.data.dataset import split_of

    _need(BANDAI)
    picked = []
    for content in ("walk", "walk-turn-left", "walk-turn-right", "run"):
        files = sorted(BANDAI.glob(f"dataset-2_{content}_*.bvh.gz"))
        test = [f for f in files if split_of(f.name.split(".bvh")[0]) == "test"]
        assert test, f"no test-split {content} take in {BANDAI}"
        picked.append(test[0])
    return picked


def _fk(model: mujoco.MjModel, qpos: np.ndarray) -> np.ndarray:
    """Canonical joint positions (T, 22, 3) of the humanoid, in the motion frame."""
    index = humanoid.model_index(model)
    data = mujoco.MjData(model)
    out = np.zeros((len(qpos), NUM_JOINTS, 3))
    for t, q in enumerate(qpos):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        out[t] = humanoid.from_mujoco(data.site_xpos[index.joint_sites])
    return out


def _standing_clip(seconds: float = 2.0) -> Motion:
    """The humanoid's rest pose held still, as a motion."""
    rest = humanoid.rest_positions().astype(np.float32)
    return Motion(np.repeat(rest[None], round(20 * seconds), axis=0))


# ---------------------------------------------------------------------------------------------
# The model
# ---------------------------------------------------------------------------------------------


def test_model_builds_and_loads() -> None:
    body = humanoid.humanoid_xml()
    assert "floor" not in body and "<light" not in body  # body only; the scene adds them
    assert 'include file="humanoid.xml"' in humanoid.scene_xml()
    model = humanoid.load_model()
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
    heavy = humanoid.load_model(mass=95.0)
    assert heavy.body_mass.sum() == pytest.approx(95.0)
    light = humanoid.load_model(mass=50.0)
    # Proportions are fixed: every segment scales with the total.
    np.testing.assert_allclose(heavy.body_mass[1:] / 95.0, light.body_mass[1:] / 50.0, rtol=1e-5)
    with pytest.raises(ValueError, match="mass"):
        humanoid.humanoid_xml(mass=0.0)


def test_rest_pose_stands_on_the_floor() -> None:
    model = humanoid.load_model()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    index = humanoid.model_index(model)
    # The soles touch the floor, nothing is under it, and heels are behind toes (+X is forward).
    soles = np.concatenate(list(index.foot_geoms.values()))
    bottoms = data.geom_xpos[soles, 2] - model.geom_size[soles, 0]
    np.testing.assert_allclose(bottoms, 0.0, atol=0.005)
    m = measure(_standing_clip(0.5))
    assert m.lowest.min() > -0.005
    heel, toe = m.soles[0, 0], m.soles[0, 1]
    assert heel[0] < toe[0]
    assert data.site_xpos[index.joint_sites[JOINT_NAMES.index("head")], 2] > 1.4


# ---------------------------------------------------------------------------------------------
# The fit
# ---------------------------------------------------------------------------------------------


def test_fit_reproduces_poses_of_the_model() -> None:
    """Random poses of the humanoid -> joint positions -> fit -> the same joint positions."""
    rng = np.random.default_rng(0)
    model = humanoid.load_model()
    qpos = np.tile(model.qpos0, (12, 1))
    index = humanoid.model_index(model)
    for adr in index.ball_qpos:
        axis_angle = rng.normal(scale=0.35, size=(12, 3))
        for t in range(12):
            mujoco.mju_axisAngle2Quat(qpos[t, adr : adr + 4], axis_angle[t], np.linalg.norm(axis_angle[t]))
    for t in range(12):
        mujoco.mju_axisAngle2Quat(qpos[t, 3:7], np.array([0.0, 0.0, 1.0]), rng.uniform(-3, 3))
    qpos[:, :3] += rng.normal(scale=0.5, size=(12, 3))
    joints = _fk(model, qpos)
    rest = clip_rest_directions(joints)
    fitted = humanoid.load_model(rest_directions=rest)
    back = _fk(fitted, fit_qpos(joints, fitted, humanoid.model_index(fitted), rest))
    np.testing.assert_allclose(back, joints, atol=1e-4)


def test_fit_error_is_small_on_a_real_clip() -> None:
    _need(SAMPLE)
    motion = Motion(np.load(SAMPLE))
    m = measure(motion)
    assert m.fit_error.mean() < 0.01 and m.fit_error.max() < 0.03  # metres
    result = evaluate(motion)
    assert result["fit_error"]["mean_cm"] < 1.0


# ---------------------------------------------------------------------------------------------
# The checks, on a synthetic clip (no data needed) and on real held-out takes
# ---------------------------------------------------------------------------------------------


def test_standing_still_is_plausible_and_corruptions_are_named() -> None:
    clip = _standing_clip(3.0)
    ok = evaluate(clip)
    assert ok["plausible"], ok["summary"]
    assert ok["checks"]["root_force"]["value"] < 0.5  # the floor carries the weight
    floating = evaluate(corruptions.raised(clip))
    assert not floating["plausible"] and "floating" in floating["failed"]
    assert "root_force" in floating["failed"]  # nothing holds the body up
    sunk = evaluate(corruptions.sunk(clip))
    assert sunk["failed"] == ["penetration"]
    assert sunk["checks"]["penetration"]["value"] == pytest.approx(0.15, abs=0.01)


def test_report_is_json_with_frames_and_words() -> None:
    clip = corruptions.raised(_standing_clip(3.0), start=20)
    result = evaluate(clip)
    json.dumps(result)  # serialisable as it is
    check = result["checks"]["floating"]
    assert set(check) == {"value", "threshold", "unit", "passed", "frames", "worst_frame", "message"}
    assert check["frames"] == [[20, 39]] and check["value"] == pytest.approx(1.0)
    assert "frames 20-39" in check["message"] and "in the air" in check["message"]
    assert set(result["checks"]) == set(CHECKS)
    text = format_report(result, title="clip")
    assert "NOT PLAUSIBLE" in text and "floating" in text


def test_held_out_real_takes_are_plausible_and_corruptions_caught() -> None:
    thresholds = load_thresholds()
    for path in _held_out_takes():
        from motion_env.io.bvh import load_bvh

        motion = load_bvh(path)
        real = evaluate(motion, thresholds=thresholds)
        assert real["plausible"], f"{path.name}: {real['summary']}"
        for name, corrupt in corruptions.ALL.items():
            failed = set(evaluate(corrupt(motion), thresholds=thresholds)["failed"])
            assert failed & corruptions.CAUGHT_BY[name], f"{path.name} {name}: failed {sorted(failed)}"


def test_evaluate_of_ten_seconds_is_fast() -> None:
    _need(BANDAI)
    from motion_env.io.bvh import load_bvh

    motion = load_bvh(BANDAI / "dataset-2_walk_normal_001.bvh.gz")  # 9 s
    motion = Motion(np.concatenate([motion.joints, motion.joints[-1:].repeat(200 - motion.num_frames, 0)]))
    evaluate(motion)  # warm-up: model compilation is cached per shape
    start = time.perf_counter()
    evaluate(motion)
    assert time.perf_counter() - start < 3.0


def test_tracking_keeps_a_standing_take_up() -> None:
    _need(BANDAI)
    from motion_env.io.bvh import load_bvh
    from motion_env.replay.tracking import track

    motion = load_bvh(BANDAI / "dataset-2_raise-up-both-hands_normal_001.bvh.gz")
    result = track(motion)
    assert not result["fell"] and result["stayed_up_s"] == pytest.approx(motion.duration)
    assert result["mean_joint_error_cm"] < 10.0
    falling = track(corruptions.raised(motion, height=1.0, seconds=10.0, start=0))
    assert falling["stayed_up_s"] <= motion.duration


# ---------------------------------------------------------------------------------------------
# Command line
# ---------------------------------------------------------------------------------------------


def test_cli_json_and_video(tmp_path: Path) -> None:
    from motion_env.cli import main

    clip = corruptions.raised(_standing_clip(1.5), seconds=0.5, start=10)
    path = clip.save(tmp_path / "clip.npz")
    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["replay", str(path), "--json"]) == 0
    result = json.loads(out.getvalue())
    assert result["plausible"] is False and "floating" in result["failed"]

    out = io.StringIO()
    with redirect_stdout(out):
        assert main(["replay", str(path)]) == 0
    assert "NOT PLAUSIBLE" in out.getvalue()

    video = tmp_path / "clip.mp4"
    with redirect_stdout(io.StringIO()):
        code = main(["replay", str(path), "--video", str(video)])
    if code == 2 and not video.exists():
        pytest.skip("offscreen OpenGL rendering is unavailable here (MUJOCO_GL=egl or osmesa)")
    assert code == 0
    import imageio.v2 as imageio

    frames = imageio.mimread(video)
    assert len(frames) == clip.num_frames
    red = frames[15][..., 0].astype(int) - frames[15][..., 1]
    assert (red > 120).sum() > (frames[2][..., 0].astype(int) - frames[2][..., 1] > 120).sum()


def test_cli_reports_a_bad_file(tmp_path: Path) -> None:
    from motion_env.cli import main

    assert main(["replay", str(tmp_path / "missing.npz")]) == 2
