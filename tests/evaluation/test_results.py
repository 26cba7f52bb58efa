"""The results of `motion-env eval control` and `eval captions`: their tables and their JSON form
(what ``--json`` writes: the command, the results, the caption reader)."""

from __future__ import annotations

import argparse
import json

import numpy as np

from motion_env.cli.evaluate import _write_result
from motion_env.evaluation.control import CONTROL_HEAD, ControlResult, off_the_floor
from motion_env.evaluation.recognition import RecognitionResult
from motion_env.motion.skeleton import FOOT_JOINTS

ROW_KEYS = (
    "mean_error_cm", "target_miss_rate", "clip_miss_rate", "foot_skating", "real_foot_skating",
    "skating_ratio", "max_jump_ratio", "clips_jump_over_1_25", "max_jump_cm", "real_max_jump_cm",
    "max_bone_change_pct", "seconds_per_clip", "max_seconds_per_clip",
)  # fmt: skip
OVERALL_KEYS = (
    "mean_error_cm", "mean_of_settings_cm", "worst_setting_cm", "target_miss_rate", "max_jump_ratio",
    "max_skating_ratio", "max_bone_change_pct", "max_seconds_per_clip",
)  # fmt: skip
OBJECTIVE = {
    "clips": 2, "max_violation_cm": 1.5, "held_rate": 1.0, "route_finished_rate": None, "foot_skating": 0.1,
    "foot_skating_without": 0.1, "max_jump_m": 0.02, "max_jump_without_m": 0.02,
    "lowest_foot_cm_in_limit": 3.25, "seconds_per_clip": 0.5,
}  # fmt: skip


def _control(objectives: dict | None) -> ControlResult:
    return ControlResult(
        no_targets={k: 0.5 for k in ROW_KEYS},
        settings={"pelvis / 1 frame": {k: 1.25 for k in ROW_KEYS}},
        overall={k: 2.0 for k in OVERALL_KEYS},
        objectives=objectives,
        refine={"space": "latent"},
        split="test",
        takes=["a", "b"],
        machine={"cores": 2},
        seconds=3.0,
    )


def _recognition() -> RecognitionResult:
    turn = {"turn_deg_named_way": {"mean": 80.0, "min": 50.0, "max": 110.0}, "share_60_120": 0.75}
    return RecognitionResult(
        table={"templates": {"action": 0.9, "style": 0.5, "pair_top3": 0.8, "clips": 12}},
        per_label={},
        specific={
            "templates": {"walk-turn-left": turn, "wave-right-hand": {"named_hand_highest": 1.0}},
            "runs_untimed_route": {
                "templates": {"mean": 2.5, "min": 2.0, "max": 3.0, "share_at_least_2.3": 0.5}
            },
        },
        frames={"walk": 120},
        actions=["walk"],
        styles=["normal"],
        split="test",
        classifier={"path": "shipped"},
        seconds=1.0,
    )


def test_control_tables_list_every_setting_and_the_objectives_when_run() -> None:
    lines = _control({"keep out": OBJECTIVE}).format().splitlines()
    assert lines[0] == CONTROL_HEAD
    assert lines[1].startswith("no targets") and lines[2].startswith("pelvis / 1 frame")
    assert "1.25" in lines[2] and lines[4].startswith("overall: mean error 2.00 cm")
    assert lines[-1].startswith("keep out") and " - " in lines[-1] and "3.2" in lines[-1]
    assert "objective" not in _control(None).format()


def test_control_names_the_takes_off_the_floor_and_the_error_without_them() -> None:
    result = _control(None)
    assert "off the floor" not in result.format()
    result.overall.update(
        takes_off_the_floor=["b"], on_the_floor_mean_error_cm=0.31, on_the_floor_worst_setting_cm=0.9
    )
    line = result.format().splitlines()[5]
    assert line.startswith("without the 1 of 2 takes off the floor (b:") and "0.31 cm" in line


def test_a_climb_is_off_the_floor_a_jump_is_not() -> None:
    joints = np.zeros((60, 22, 3), np.float32)
    joints[:, :, 1] = 0.9
    joints[:, list(FOOT_JOINTS), 1] = 0.05
    assert not off_the_floor(joints)
    jump = joints.copy()
    jump[20:29, :, 1] += 0.5  # 9 frames in the air, the feet 55 cm up
    assert not off_the_floor(jump)
    climb = joints.copy()
    climb[20:30, :, 1] += 0.5  # 10 frames: held up
    assert off_the_floor(climb)


def test_control_json_keeps_the_tables_names() -> None:
    data = json.loads(json.dumps(_control(None).to_dict()))
    assert "no targets" in data and "no_targets" not in data and "objectives" not in data
    assert data["settings"]["pelvis / 1 frame"]["mean_error_cm"] == 1.25 and data["seconds"] == 3.0
    assert json.loads(json.dumps(_control({"keep out": OBJECTIVE}).to_dict()))["objectives"]["keep out"]


def test_recognition_table_then_turns_waves_and_runs() -> None:
    text = _recognition().format()
    assert "| templates | 0.90 | 0.50 | 0.80 | 12 |" in text
    assert "templates: walk-turn-left 80 deg (50 to 110; 75% in 60-120); wave-right-hand: named hand" in text
    assert text.splitlines()[-1] == "run speed, templates: 2.50 m/s (2.00 to 3.00), 50% >= 2.3 m/s"


def test_json_holds_the_command_the_results_and_the_caption_reader(tmp_path) -> None:
    args = argparse.Namespace(
        eval_command="captions", json=str(tmp_path / "r.json"), data="d", split="test", seed=0, model=None,
        caption_reader=None,
    )  # fmt: skip
    _write_result(args, _recognition(), ("data", "split", "seed", "model"))
    data = json.loads((tmp_path / "r.json").read_text())
    assert data["command"] == "motion-env eval captions --data d --split test --seed 0"
    assert data["caption_reader"] == "default" and data["table"]["templates"]["clips"] == 12
    # eval control has no --caption-reader: no reader is recorded.
    control = argparse.Namespace(eval_command="control", json=str(tmp_path / "c.json"), seed=1)
    _write_result(control, _control(None), ("seed",))
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["command"] == "motion-env eval control --seed 1" and "caption_reader" not in data
