"""A motion as a reference for the replay humanoid: :func:`save_humanoid_npz` (robot-ready `.npz`).

The joint positions are fitted to the humanoid of :mod:`motion_env.replay.humanoid` by the replay's
own fit (:func:`motion_env.replay.fit.fit_qpos`, with the clip's pelvis and chest shape,
:func:`~motion_env.replay.fit.clip_rest_directions`), so the file holds what the replay checks.
Everything is in MuJoCo's frame (Z up, the character faces +X, :func:`humanoid.to_mujoco`),
metres, quaternions ``(w, x, y, z)``, at the motion's own frame rate. The keys are listed in
:data:`FIELDS` and in ``docs/conventions.md`` ("Export").
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from motion_env.motion.features import FOOT_CONTACT_THRESHOLD, joints_to_features
from motion_env.motion.skeleton import FOOT_CONTACT, FOOT_JOINTS, FPS, JOINT_NAMES
from motion_env.replay.fit import clip_rest_directions, fit_qpos
from motion_env.replay.humanoid import BALL_JOINTS, DEFAULT_MASS, humanoid_xml, to_mujoco
from motion_env.replay.inputs import check_mass, check_motion
from motion_env.replay.mjcf import load_model, model_index

__all__ = ["FIELDS", "foot_contacts", "humanoid_reference", "save_humanoid_npz"]

FIELDS: dict[str, str] = {
    "fps": "float32 scalar: frames per second (the motion's)",
    "qpos": "float64 (T, nq): the humanoid's MuJoCo qpos (free joint, then the ball joints)",
    "root_pos": "float32 (T, 3): pelvis position, MuJoCo world frame (x forward, y left, z up), m",
    "root_quat_wxyz": "float32 (T, 4): pelvis world rotation, (w, x, y, z)",
    "joint_names": "str (K,): the ball joints (canonical joint names), in qpos order",
    "joint_quat_wxyz": "float32 (T, K, 4): each ball joint's rotation relative to its parent body, wxyz",
    "contact_names": "str (4,): left_ankle, left_foot, right_ankle, right_foot",
    "foot_contacts": "bool (T, 4): the 263-d features' contact rule (foot joint slower than ~0.9 m/s)",
    "joint_positions": "float32 (T, 22, 3): the motion's joints in MuJoCo's frame (the fit's targets), m",
    "fit_error": "float32 (T, 22): distance of each model joint from its target after the fit, m",
    "rest_directions": "float32 (22, 3): rest bone directions of the body the qpos is for (motion frame)",
    "mass": "float32 scalar: the body's mass, kg",
    "humanoid_xml": "str scalar: that body's MJCF (motion_env.replay.humanoid.humanoid_xml)",
    "meta": "str scalar: JSON object: the motion's text and meta, and these conventions",
}
"""The keys of the `.npz` written by :func:`save_humanoid_npz` and what each holds."""


def foot_contacts(joints: np.ndarray, fps: float) -> np.ndarray:
    """(T, 4) bool contacts of (left ankle, left toe, right ankle, right toe), as the features'.

    The rule of :func:`motion_env.motion.joints_to_features` (HumanML3D's): a foot joint is in
    contact at frame t when it moves less than about 4.5 cm to frame t + 1 at 20 fps (the
    threshold is scaled to keep that speed at other rates); the last frame repeats the one before.
    """
    if len(joints) < 2:
        return np.ones((len(joints), len(FOOT_JOINTS)), dtype=bool)
    threshold = FOOT_CONTACT_THRESHOLD * (FPS / fps) ** 2
    contacts = joints_to_features(joints, feet_threshold=threshold)[:, FOOT_CONTACT] > 0.5
    return np.concatenate([contacts, contacts[-1:]], axis=0)


def humanoid_reference(motion: Any, mass: float = DEFAULT_MASS) -> dict[str, np.ndarray]:
    """The arrays of :data:`FIELDS` for `motion` (a :class:`motion_env.Motion`) on the humanoid.

    Raises ValueError for joints with NaN or infinite values (naming the frames), a rate that is
    not > 0, or a mass that is not a positive number.
    """
    joints, fps = check_motion(motion)
    mass = check_mass(mass)
    rest = clip_rest_directions(joints)
    model = load_model(mass, rest)
    index = model_index(model)
    qpos = fit_qpos(joints, model, index, rest)

    data = mujoco.MjData(model)
    targets = to_mujoco(joints)
    fitted = np.zeros_like(targets)
    for t in range(len(qpos)):
        data.qpos[:] = qpos[t]
        mujoco.mj_kinematics(model, data)
        fitted[t] = data.site_xpos[index.joint_sites]

    order = np.argsort(index.ball_qpos)  # the ball joints as qpos holds them (the body tree's order)
    joint_quats = np.stack([qpos[:, index.ball_qpos[k] : index.ball_qpos[k] + 4] for k in order], axis=1)
    info = {"text": getattr(motion, "text", None), "motion_meta": dict(getattr(motion, "meta", {}) or {})}
    info |= {
        "frame": "MuJoCo: x forward, y left, z up; metres",
        "quaternions": "w, x, y, z",
        "fields": FIELDS,
    }
    return {
        "fps": np.float32(fps),
        "qpos": qpos,
        "root_pos": qpos[:, 0:3].astype(np.float32),
        "root_quat_wxyz": qpos[:, 3:7].astype(np.float32),
        "joint_names": np.array([JOINT_NAMES[BALL_JOINTS[k]] for k in order]),
        "joint_quat_wxyz": joint_quats.astype(np.float32),
        "contact_names": np.array([JOINT_NAMES[j] for j in FOOT_JOINTS]),
        "foot_contacts": foot_contacts(joints, fps),
        "joint_positions": targets.astype(np.float32),
        "fit_error": np.linalg.norm(fitted - targets, axis=-1).astype(np.float32),
        "rest_directions": rest.astype(np.float32),
        "mass": np.float32(mass),
        "humanoid_xml": np.array(humanoid_xml(mass, rest)),
        "meta": np.array(json.dumps(info)),
    }


def save_humanoid_npz(motion: Any, path: str | Path, mass: float = DEFAULT_MASS) -> Path:
    """Write :func:`humanoid_reference` of `motion` to `path` (must end in ``.npz``; replaced if
    it exists; missing folders are made). Returns the path.

    Raises ValueError for another suffix or a bad motion / mass, OSError (naming the file) when it
    cannot be written.
    """
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise ValueError(f"{path}: a humanoid reference file name must end in .npz")
    arrays = humanoid_reference(motion, mass)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("wb") as fh:
            np.savez(fh, **arrays)
    except OSError as exc:
        raise OSError(f"{path}: cannot write the humanoid reference ({exc.strerror or exc})") from exc
    return path
