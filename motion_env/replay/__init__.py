"""Physical plausibility of a motion: replay it on a MuJoCo humanoid and report what is wrong.

>>> from motion_env.replay import evaluate
>>> result = evaluate(motion)          # a motion_env.Motion
>>> result["plausible"], result["failed"]

See :mod:`motion_env.replay.evaluate` for the checks, :mod:`.humanoid` for the model,
:mod:`.fit` for joint positions -> qpos, :mod:`.tracking` for PD tracking and :mod:`.video`
for rendering.
"""

from motion_env.replay.checks import (
    CHECKS,
    evaluate,
    evaluate_detailed,
    format_report,
    load_thresholds,
    report,
    signals,
)
from motion_env.replay.humanoid import humanoid_xml, load_model, scene_xml
from motion_env.replay.kinematic import Measurements, measure

__all__ = [
    "CHECKS",
    "Measurements",
    "evaluate",
    "evaluate_detailed",
    "format_report",
    "humanoid_xml",
    "load_model",
    "load_thresholds",
    "measure",
    "report",
    "scene_xml",
    "signals",
]
