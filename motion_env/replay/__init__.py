"""Physical plausibility of a motion: replay it on a MuJoCo humanoid and report what is wrong.

>>> from motion_env.replay import evaluate
>>> result = evaluate(motion)          # a motion_env.Motion
>>> result["plausible"], result["failed"]

What is where:

- :mod:`.plausibility`: the nine checks, :func:`evaluate` / :func:`evaluate_detailed`, the report and
  the thresholds (``model/thresholds.json``);
- :mod:`.humanoid`: the body generated from the canonical skeleton (:func:`humanoid_xml`);
- :mod:`.mjcf`: the compiled model (``model/scene.xml`` + the body, :func:`load_model`) and
  the ids into it;
- ``model/``: the Menagerie-style model folder (scene, default body, thresholds, README);
- :mod:`.fit`: joint positions -> qpos; :mod:`.kinematic`: per-frame measurements;
  :mod:`.tracking`: PD tracking; :mod:`.corruptions`: physically wrong versions of a motion;
- :mod:`.inputs`: the checks of a motion, a mass, a rate that the public functions make first;
- :mod:`.robot`: :func:`evaluate_robot`, the checks on a robot's ``qpos`` (its model, e.g.
  ``motion_env/retarget/robots/unitree_g1/scene.xml``), measured by :mod:`.robot_kinematic`;
  :mod:`.judging`: what the humanoid's and the robot's reports share (:func:`format_report`).

A clip shorter than :func:`~motion_env.replay.plausibility.min_frames` (20 frames, 1 s at 20 fps) is
not judged: ``result["judged"]`` is False and ``result["plausible"]`` None.

Videos of a replay are drawn by :func:`motion_env.render.humanoid.render_humanoid_video`.
"""

from motion_env.replay.humanoid import humanoid_xml
from motion_env.replay.judging import format_report
from motion_env.replay.kinematic import Measurements, measure
from motion_env.replay.mjcf import load_model, scene_xml
from motion_env.replay.plausibility import (
    CHECKS,
    evaluate,
    evaluate_detailed,
    load_thresholds,
    min_frames,
    report,
    signals,
)
from motion_env.replay.robot import evaluate_robot

__all__ = [
    "CHECKS",
    "Measurements",
    "evaluate",
    "evaluate_detailed",
    "evaluate_robot",
    "format_report",
    "humanoid_xml",
    "load_model",
    "load_thresholds",
    "measure",
    "min_frames",
    "report",
    "scene_xml",
    "signals",
]
