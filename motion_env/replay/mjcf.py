"""The compiled MuJoCo model of the replay: ``model/scene.xml`` around the generated body.

- :data:`MODEL_DIR`: the Menagerie-style folder ``motion_env/replay/model/`` (``scene.xml``,
  ``humanoid.xml``, ``thresholds.json``, ``README.md``);
- :func:`load_model`: the scene with the body of :func:`motion_env.replay.humanoid.humanoid_xml`
  for a mass and a rest pose, compiled once per pair and copied per call;
- :func:`model_index`: the ids of the canonical joints, ball joints and geoms in that model;
- :func:`write_body_xml`: rewrite ``model/humanoid.xml``, the default body, after a change to
  :mod:`motion_env.replay.humanoid` (``python -c "from motion_env.replay.mjcf import
  write_body_xml; write_body_xml()"``); a test checks that the file matches the generator.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import mujoco
import numpy as np

from motion_env.motion.skeleton import JOINT_NAMES, NUM_JOINTS
from motion_env.replay.humanoid import (
    BALL_JOINTS,
    DEFAULT_MASS,
    JOINT_TO_BODY,
    check_directions,
    humanoid_xml,
)

MODEL_DIR = Path(str(resources.files("motion_env.replay").joinpath("model")))
BODY_XML = MODEL_DIR / "humanoid.xml"


def scene_xml() -> str:
    """The static scene (floor, light, cameras) that includes ``humanoid.xml``."""
    return (MODEL_DIR / "scene.xml").read_text()


def write_body_xml(path: str | Path = BODY_XML) -> Path:
    """Write the default body (:func:`humanoid_xml` with its defaults) to `path`."""
    path = Path(path)
    path.write_text(humanoid_xml())
    return path


@functools.lru_cache(maxsize=16)
def _compiled(mass: float, rest_key: bytes | None) -> mujoco.MjModel:
    dirs = None if rest_key is None else np.frombuffer(rest_key).reshape(NUM_JOINTS, 3)
    body = humanoid_xml(mass, dirs)
    return mujoco.MjModel.from_xml_string(scene_xml(), assets={"humanoid.xml": body.encode()})


def load_model(mass: float = DEFAULT_MASS, rest_directions: np.ndarray | None = None) -> mujoco.MjModel:
    """The compiled scene + humanoid (a fresh copy each call, safe to modify).

    Arguments as :func:`motion_env.replay.humanoid.humanoid_xml`.
    """
    key = None if rest_directions is None else check_directions(rest_directions).tobytes()
    return _compiled(float(mass), key).__copy__()


@dataclass(frozen=True)
class ModelIndex:
    """Addresses into a compiled humanoid model, in canonical joint order where it applies."""

    joint_sites: np.ndarray  # (22,) site id of each canonical joint
    joint_bodies: np.ndarray  # (22,) body id carrying each canonical joint
    ball_qpos: np.ndarray  # (len(BALL_JOINTS),) qpos address of each ball joint (4 values)
    ball_dof: np.ndarray  # (len(BALL_JOINTS),) dof address of each ball joint (3 values)
    floor_geom: int
    body_geoms: np.ndarray  # ids of the humanoid's geoms
    foot_geoms: dict[str, np.ndarray]  # "left"/"right" -> sole geom ids


def model_index(model: mujoco.MjModel) -> ModelIndex:
    """Look up the ids of the canonical joints, ball joints and geoms in `model`."""

    def oid(kind: mujoco.mjtObj, name: str) -> int:
        i = mujoco.mj_name2id(model, kind, name)
        if i < 0:
            raise ValueError(f"the MuJoCo model has no {kind.name[5:].lower()} named {name!r}")
        return i

    site = mujoco.mjtObj.mjOBJ_SITE
    body = mujoco.mjtObj.mjOBJ_BODY
    joint = mujoco.mjtObj.mjOBJ_JOINT
    geom = mujoco.mjtObj.mjOBJ_GEOM
    floor = oid(geom, "floor")
    ball = [oid(joint, JOINT_NAMES[j]) for j in BALL_JOINTS]
    return ModelIndex(
        joint_sites=np.array([oid(site, n) for n in JOINT_NAMES]),
        joint_bodies=np.array([oid(body, JOINT_TO_BODY[n]) for n in JOINT_NAMES]),
        ball_qpos=np.array([model.jnt_qposadr[i] for i in ball]),
        ball_dof=np.array([model.jnt_dofadr[i] for i in ball]),
        floor_geom=floor,
        body_geoms=np.array([g for g in range(model.ngeom) if model.geom_bodyid[g] > 0]),
        foot_geoms={s: np.array([oid(geom, f"{s}_sole{k}") for k in range(2)]) for s in ("left", "right")},
    )
