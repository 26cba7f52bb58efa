"""A corpus of bad inputs against the public API: each raises the exact exception type, with a
message that names the argument (and, for files, the file and the field).

The command line's handling of the same mistakes (one line, exit code 2, checked before the model
loads) is tested in tests/test_cli*.py.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import motion_env
from motion_env.generation.request import MAX_FRAMES, MAX_SPEED, check_batch_request
from motion_env.motion import features_to_joints, joints_to_features
from motion_env.motion.trajectory import MAX_COORDINATE

ROUTE = [[0.0, 2.0, 40], [2.0, 4.0, 100]]


@pytest.fixture
def gen(random_generator):
    return random_generator


def _generate(**changes: Any) -> Callable[[Any], Any]:
    def call(gen: Any) -> Any:
        kwargs = {"text": "a person walks", "waypoints": ROUTE, "num_frames": 120, "seed": 0, **changes}
        return gen.generate(**kwargs)

    return call


# (case id, call taking the test generator, exception type, regex the message must match)
GENERATE_CASES = [
    ("text not a string", _generate(text=3), TypeError, r"text must be a string"),
    ("text empty", _generate(text="   "), ValueError, r"text is empty"),
    ("num_frames None", _generate(num_frames=None), TypeError, r"num_frames must be a whole number"),
    ("num_frames str", _generate(num_frames="200"), TypeError, r"num_frames"),
    ("num_frames bool", _generate(num_frames=True), TypeError, r"num_frames"),
    ("num_frames fraction", _generate(num_frames=2.5), ValueError, r"num_frames must be a whole number"),
    ("num_frames zero", _generate(num_frames=0), ValueError, r"num_frames must be between 1 and"),
    ("num_frames huge", _generate(num_frames=10**6), ValueError, rf"between 1 and {MAX_FRAMES}"),
    ("num_frames inf", _generate(num_frames=math.inf), ValueError, r"num_frames"),
    ("seed too big", _generate(seed=2**100), ValueError, r"seed must be in \[0, 2\*\*64\)"),
    ("seed negative", _generate(seed=-1), ValueError, r"seed must be in"),
    ("seed fraction", _generate(seed=1.5), TypeError, r"seed must be an integer"),
    ("seed str", _generate(seed="3"), TypeError, r"seed must be an integer"),
    (
        "waypoints 1-d",
        _generate(waypoints=[1.0, 2.0]),
        ValueError,
        r"waypoints must have shape .K, 2. or .K, 3.",
    ),
    ("waypoints empty", _generate(waypoints=[]), ValueError, r"waypoints is empty"),
    ("waypoints text", _generate(waypoints=[["a", "b"]]), ValueError, r"waypoints must be a numeric"),
    (
        "waypoints NaN x",
        _generate(waypoints=[[np.nan, 1.0]]),
        ValueError,
        r"waypoints have NaN or infinite x/z",
    ),
    ("waypoints far", _generate(waypoints=[[1e9, 0.0, 10]]), ValueError, rf"within {MAX_COORDINATE:g} m"),
    (
        "waypoints time inf",
        _generate(waypoints=[[0, 1, np.inf]]),
        ValueError,
        r"waypoint times must be finite",
    ),
    ("waypoints time negative", _generate(waypoints=[[0, 1, -5]]), ValueError, r"must be >= 0"),
    (
        "waypoints not increasing",
        _generate(waypoints=[[0, 1, 40], [1, 1, 20]]),
        ValueError,
        r"strictly increasing",
    ),
    ("waypoints in seconds", _generate(waypoints=[[0, 5, 2], [5, 10, 4]]), ValueError, r"asks for 50 m/s"),
    ("waypoints too fast", _generate(waypoints=[[0, 100, 10]]), ValueError, rf"at most {MAX_SPEED:g} m/s"),
    ("start wrong shape", _generate(start=[0, 0]), ValueError, r"start must be \(x, z, heading\)"),
    ("start NaN", _generate(start=[0, np.nan, 0]), ValueError, r"start must be finite"),
    ("start far", _generate(start=[2e4, 0, 0]), ValueError, r"start: x and z must lie within"),
    ("start text", _generate(start="origin"), ValueError, r"start must be three numbers"),
    ("infeasible mode", _generate(infeasible="ignore"), ValueError, r"infeasible must be one of"),
]


@pytest.mark.parametrize(
    ("call", "error", "match"), [c[1:] for c in GENERATE_CASES], ids=[c[0] for c in GENERATE_CASES]
)
def test_generate_rejects(gen, call, error, match) -> None:
    with pytest.raises(error, match=match):
        call(gen)


def test_batch_and_stream_reject(gen) -> None:
    with pytest.raises(TypeError, match="texts must be a list"):
        gen.generate_batch("a person walks", num_frames=10)
    with pytest.raises(ValueError, match="texts is empty"):
        gen.generate_batch([], num_frames=10)
    with pytest.raises(ValueError, match=r"starts must have shape \(2, 3\)"):
        gen.generate_batch(["a", "b"], num_frames=10, starts=np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"starts has NaN or infinite values at rows \[1\]"):
        gen.generate_batch(["a", "b"], num_frames=10, starts=[[0, 0, 0], [np.inf, 0, 0]])
    with pytest.raises(ValueError, match="a list of 2 entries"):
        gen.generate_batch(["a", "b"], [ROUTE, ROUTE, ROUTE], num_frames=10)
    with pytest.raises(ValueError, match="waypoints of character 1"):
        gen.generate_batch(["a", "b"], [ROUTE, [[0, 1, -1]]], num_frames=10)
    stream = gen.stream(["a person walks"], seed=0)
    with pytest.raises(ValueError, match="asks for"):
        stream.set_waypoints([[0, 50, 5]])
    with pytest.raises(IndexError, match="character index 3 out of range"):
        stream.set_text("a person runs", index=3)
    with pytest.raises(ValueError, match="text is empty"):
        stream.set_text("  ")


def test_impossible_timing_is_retimed_on_request(gen) -> None:
    with pytest.warns(
        UserWarning, match=r"waypoints, row 0 \(x=0, z=5, frame 2\) asks for 50 m/s.*retimed to frame"
    ):
        m = gen.generate("a person walks", [[0, 5, 2]], num_frames=60, seed=0, infeasible="warn")
    assert m.num_frames == 60


def test_a_waypoint_after_the_clip_is_announced(gen) -> None:
    with pytest.warns(UserWarning, match=r"timed at frame 400, after the clip's last frame 119"):
        gen.generate("a person walks", [[0, 2, 400]], num_frames=120, seed=0)


def test_the_stream_takes_one_caption_as_a_string(gen) -> None:
    assert gen.stream("a person walks", seed=0).step().shape == (1, 22, 3)


def test_request_checks_need_no_model() -> None:
    req = check_batch_request(["a person walks"], ROUTE, 120, 0, None)
    assert req.num_frames == 120 and req.routes[0].shape == (2, 3)


# --------------------------------------------------------------------------------------------
# Motion files and the motion math
# --------------------------------------------------------------------------------------------


def _npz(path: Path, **arrays: Any) -> Path:
    np.savez(path, **{"joints": np.zeros((3, 22, 3), np.float32), **arrays})
    return path


@pytest.mark.parametrize(
    ("arrays", "match"),
    [
        ({"fps": np.array([20.0, 20.0])}, r"field 'fps' must be one number"),
        ({"fps": np.array(-5.0)}, r"Motion.fps must be a positive number"),
        ({"meta": np.array("plain text")}, r"field 'meta' must be a JSON object"),
        ({"meta": np.array(json.dumps([1, 2]))}, r"field 'meta' must be a JSON object of strings, got list"),
        ({"text": np.array([1, 2])}, r"field 'text' must be one string"),
        ({"waypoints": np.zeros(4)}, r"Motion.waypoints must have shape"),
    ],
)
def test_motion_load_names_the_file_and_the_field(tmp_path: Path, arrays: dict, match: str) -> None:
    path = _npz(tmp_path / "clip.npz", **arrays)
    with pytest.raises(ValueError, match=match) as info:
        motion_env.Motion.load(path)
    assert str(path) in str(info.value)


def test_motion_files_that_are_not_motions(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no motion file at"):
        motion_env.Motion.load(tmp_path / "missing.npz")
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(ValueError, match="not a readable .npz file"):
        motion_env.Motion.load(tmp_path / "text.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="no 'joints' array"):
        motion_env.Motion.load(tmp_path / "other.npz")
    with pytest.raises(ValueError, match="unknown motion file type"):
        motion_env.load_motion(tmp_path / "clip.csv")


def test_motion_math_rejects_nan() -> None:
    features = np.zeros((5, 263))
    features[2, 7] = np.nan
    with pytest.raises(ValueError, match=r"features has NaN or infinite values at frames \[2\]"):
        features_to_joints(features)
    joints = np.zeros((4, 22, 3))
    joints[1, 3, 0] = np.inf
    with pytest.raises(ValueError, match=r"joints has NaN or infinite values at frames \[1\]"):
        joints_to_features(joints)
    with pytest.raises(ValueError, match=r"Motion.joints has NaN"):
        motion_env.Motion(np.full((2, 22, 3), np.nan))
    with pytest.raises(ValueError, match=r"features must have shape \(\.\.\., T, 263\)"):
        features_to_joints(np.zeros((5, 262)))


# --------------------------------------------------------------------------------------------
# Environments
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("action", "error", "match"),
    [
        (np.array([1 + 2j, 0.0, 0.0]), TypeError, r"action must be real numbers.*complex"),
        (np.array(["a", "b"]), TypeError, r"action must be real numbers"),
        (np.array([None, None], dtype=object), TypeError, r"action must be real numbers"),
        (np.array([np.nan, 0.0, 1.0], np.float32), ValueError, r"action has NaN or infinite values"),
        (np.zeros(2, np.float32), ValueError, r"action must have shape \(3,\) \(x, z, follow\)"),
        (np.zeros((1, 1, 3), np.float32), ValueError, r"action must have shape \(3,\)"),
    ],
)
def test_env_rejects_bad_actions(gen, action, error, match) -> None:
    env = gym.make("motion_env/Waypoints-v0", generator=gen)
    env.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Gymnasium's own checker warns about the dtype first
        with pytest.raises(error, match=match):
            env.step(action)


def test_env_rejects_bad_options_and_settings(gen) -> None:
    env = gym.make("motion_env/Waypoints-v0", generator=gen)
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(seed=0, options={"route": [[0, 1]]})
    with pytest.raises(ValueError, match="text is empty"):
        env.reset(seed=0, options={"text": ""})
    with pytest.raises(ValueError, match="asks for"):
        env.reset(seed=0, options={"waypoints": [[0, 30, 3]]})
    with pytest.raises(ValueError, match=r"obstacles\[0\]"):
        gym.make("motion_env/Waypoints-v0", generator=gen, obstacles=[[0, 0, -1]])
    with pytest.raises(ValueError, match="action_mode must be one of"):
        gym.make("motion_env/Waypoints-v0", generator=gen, action_mode="polar")
    with pytest.raises(ValueError, match="frames_per_step must be an integer >= 1"):
        gym.make("motion_env/Waypoints-v0", generator=gen, frames_per_step=0)
    with pytest.raises(TypeError, match="unknown arguments"):
        gym.make_vec("motion_env/Waypoints-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     generator=gen, speed=3)  # fmt: skip


# ----------------------------------------------------------------------------------------------
# Joint targets and objectives (issue #10)
# ----------------------------------------------------------------------------------------------


def _targets(frames: int = 120) -> np.ndarray:
    return np.full((frames, 22, 3), np.nan, np.float32)


def _with(frame: int, joint: int, value: Any) -> np.ndarray:
    t = _targets()
    t[frame, joint] = value
    return t


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        (
            {"joint_targets": np.zeros((120, 21, 3))},
            ValueError,
            r"joint_targets must have shape \(num_frames, 22, 3\)",
        ),
        (
            {"joint_targets": _targets(130)},
            ValueError,
            "130 frames, the clip has num_frames=120 .targets outside",
        ),
        (
            {"joint_targets": _with(5, 21, [0, np.inf, 0])},
            ValueError,
            r"infinite value at frame 5, joint 21 \(right_wrist\)",
        ),
        (
            {"joint_targets": _with(7, 15, [0, np.nan, 0])},
            ValueError,
            r"only some coordinates at frame 7, joint 15 \(head\)",
        ),
        ({"joint_targets": _with(7, 15, [1e6, 1, 0])}, ValueError, "within 10000 m"),
        ({"joint_targets": "left hand up"}, ValueError, "joint_targets must"),
        ({"objectives": motion_env.objectives.KeepOut(center=(0, 0), radius=1)}, TypeError, "must be a list"),
        ({"objectives": [3.0]}, TypeError, r"objectives\[0\] is a float, not an objective"),
        (
            {"objectives": [lambda j: j[:, 0, 1]]},
            ValueError,
            r"objectives\[0\] returned a tensor of shape \(120,\)",
        ),
        ({"objectives": [lambda j: 1.0]}, TypeError, r"objectives\[0\] returned a float"),
        ({"objectives": [lambda j: j.sum() * np.nan]}, ValueError, "finite cost"),
        (
            {"objectives": [lambda j: j.no_such_method()]},
            ValueError,
            r"objectives\[0\] .* raised AttributeError",
        ),
    ],
)
def test_bad_joint_targets_and_objectives(gen, kwargs, error, match) -> None:
    with pytest.raises(error, match=match):
        _generate(**kwargs)(gen)


def test_bad_targets_in_a_batch_name_the_character(gen) -> None:
    with pytest.raises(ValueError, match="joint_targets of character 1 has an infinite value"):
        gen.generate_batch(["a", "b"], num_frames=120, joint_targets=[None, _with(3, 0, [np.inf, 0, 0])])
    with pytest.raises(ValueError, match="unknown joint name 'hand'"):
        motion_env.objectives.HeightLimit("hand", max_height=1.0)


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("a person walks forward " * 450, "characters long"),  # 10 kB: the encoder reads the start
        ("🏃💨", "no letters"),
        ("一个人在走路", "not in the Latin script"),
        ("une personne court très vite", "French"),
        ("a person walks und dann läuft sie sehr schnell", "German"),
    ],
)
def test_odd_captions_warn_once_and_still_move(pretrained_generator, text: str, why: str) -> None:
    """Very long captions, emoji, other scripts, other and mixed languages: a warning naming the
    nearest known actions (once per caption), then a motion along the route, never a crash."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        clips = [pretrained_generator.generate(text, ROUTE, num_frames=100, seed=s) for s in (0, 1)]
    messages = [
        str(w.message) for w in caught if issubclass(w.category, UserWarning) and "caption" in str(w.message)
    ]
    assert len(messages) == 1 and why in messages[0] and "nearest known actions" in messages[0], messages
    assert pretrained_generator.caption_warning(text) == messages[0]
    for clip in clips:
        root = clip.joints[:, 0, [0, 2]]
        assert np.isfinite(clip.joints).all() and np.linalg.norm(root[-1] - root[0]) > 2.0  # route: 2.8 m


def test_a_route_faster_than_the_data_warns_naming_the_frames() -> None:
    from motion_env.generation.request import SPRINT_SPEED, check_request

    with pytest.warns(UserWarning, match=r"row 0 .* asks for 6 m/s between frames 0 and 20: faster than"):
        check_request("a person runs", [[0, 6, 20]], 40, 0, None)
    assert SPRINT_SPEED < 6 < MAX_SPEED
