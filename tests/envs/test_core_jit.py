"""The environments' compiled bookkeeping (:mod:`motion_env.envs.core_jit`) against the numpy
operations it replaces in :class:`~motion_env.envs.core.CharacterBatch`: the same numbers to the
bit, the same calls to the stream, in the same order.

Only the batch's switch is turned (``core.jit_enabled``): the generator's own compiled loops agree
with numpy to float32 rounding, not to the bit, so they stay as they are on both sides.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import motion_env  # noqa: F401 (registers the ids)
from motion_env.envs import core, core_jit
from motion_env.envs.config import EnvConfig
from motion_env.envs.core import CharacterBatch
from motion_env.motion.skeleton import NUM_JOINTS


class _Stream:
    """A stand-in for the generator's stream: frames drawn from a seed, calls recorded."""

    def __init__(self, batch: int, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.root_state = np.zeros((batch, 3), np.float32)  # the batch only reads them
        self.frame_index = np.zeros(batch, np.int64)
        self.calls: list[tuple[Any, ...]] = []

    def step(self, rows: np.ndarray | None = None) -> np.ndarray:
        rows = np.arange(len(self.root_state)) if rows is None else np.asarray(rows)
        joints = self.rng.normal(0.0, 0.3, (len(rows), NUM_JOINTS, 3)).astype(np.float32)
        # Pelvises that wander, jump onto a waypoint now and then and turn past +-pi.
        pelvis = self.root_state[rows, :2] + self.rng.normal(0.0, 0.4, (len(rows), 2)).astype(np.float32)
        onto = self.rng.random(len(rows)) < 0.3
        pelvis[onto] = self.rng.integers(-2, 3, (int(onto.sum()), 2)).astype(np.float32)
        joints[:, 0, 0], joints[:, 0, 2] = pelvis[:, 0], pelvis[:, 1]
        self.root_state[rows, :2] = pelvis
        self.root_state[rows, 2] = (self.root_state[rows, 2] + self.rng.normal(0.0, 1.5, len(rows))).astype(
            np.float32
        )
        self.frame_index[rows] += 1
        self.calls.append(("step", rows.tolist()))
        return joints

    def set_waypoints(self, route: np.ndarray, index: int) -> None:
        self.calls.append(("set_waypoints", index, route.copy()))

    def set_goals(self, points: np.ndarray, rows: np.ndarray) -> None:
        self.calls.append(("set_goals", points.copy(), np.asarray(rows).copy()))

    def reset(self, i: int, *args: Any, **kwargs: Any) -> None:
        self.frame_index[i] = 0

    def caption_features(self, i: int | None = None) -> np.ndarray:
        return (
            np.full(3, 250.0, np.float32)
            if i is not None
            else np.full((len(self.root_state), 3), -250.0, np.float32)
        )


_STATE = ("k", "following", "command_xz", "reached", "pos", "theta", "prev_pos", "prev_theta", "vel",
          "fresh", "progress", "arrivals", "collisions", "frames", "joints")  # fmt: skip


def _episode(seed: int, obstacles: list) -> dict[str, Any]:
    """A batch of four characters on a stand-in stream: routes of one to six waypoints, timed and
    untimed, some on the same spot; each step commands a waypoint (the target, a later one, an
    earlier one), a far point, the last command again or nothing, then emits one to four frames
    (a character restarted now and then); everything the batch holds and says, step by step."""
    rng = np.random.default_rng(seed)
    batch = CharacterBatch(EnvConfig(action_mode="absolute", arrive_radius=0.4, snap_radius=0.2), obstacles)
    stream = _Stream(4, seed)

    def route() -> np.ndarray:
        points = rng.integers(-2, 3, (int(rng.integers(1, 9)), 2)).astype(np.float64)
        times = np.where(rng.random(len(points)) < 0.5, np.nan, np.cumsum(rng.integers(1, 5, len(points))))
        return np.concatenate([points, times[:, None]], axis=1)

    batch.start(type("G", (), {"stream": lambda *a, **k: stream})(), ["a"] * 4, [route() for _ in range(4)],
                np.zeros((4, 3)), seed=0)  # fmt: skip
    record: list[Any] = []
    passes = {"arrival": 0, "time": 0, "several": 0}
    for _ in range(40):
        batch.begin_step()
        actions = rng.normal(0.0, 3.0, (4, 2))
        for b in range(4):
            choice = rng.integers(0, 5)
            if choice < 3:
                j = min(int(batch.k[b]) + int(rng.integers(-1, 3)), int(batch.route_count[b]) - 1)
                actions[b] = batch.route_arr[b, max(j, 0), :2] + rng.normal(0.0, 0.05, 2)
            elif choice == 3:
                actions[b] = batch.command_xz[b] + rng.normal(0.0, 5e-5, 2)
        batch.command(actions, rng.random(4) < 0.8)
        for _ in range(int(rng.integers(1, 5))):
            k, arrivals = batch.k.copy(), batch.arrivals.copy()
            batch.emit_frame()
            passed, bonus = batch.k - k, batch.arrivals - arrivals
            passes["arrival"] += int(bonus.sum())
            passes["time"] += int(np.maximum(passed - bonus, 0).sum())
            passes["several"] += int((passed > 1).sum())
        if rng.random() < 0.2:
            i = int(rng.integers(0, 4))
            batch.restart(i, "b", route(), np.array([0.0, 0.0, 3.0]))
            batch.emit_frame(np.array([i]))
        record.append({name: np.copy(getattr(batch, name)) for name in _STATE})
        record.append(batch.observations())
    return {
        "record": record,
        "calls": stream.calls,
        "trails": [np.array(t) for t in batch.trails],
        "passes": passes,
    }


def _both(
    monkeypatch: pytest.MonkeyPatch, run: Any, needs: tuple[str, ...] = tuple(core_jit.__all__)
) -> dict[bool, Any]:
    """`run()` with the batch's compiled loops on and off; fails unless each of `needs` ran."""
    calls: dict[str, int] = {}
    for name in core_jit.__all__:
        compiled = getattr(core_jit, name)

        def counted(*args: Any, _f: Any = compiled, _name: str = name) -> Any:
            calls[_name] = calls.get(_name, 0) + 1
            return _f(*args)

        monkeypatch.setattr(core_jit, name, counted)
    outputs = {}
    for on in (True, False):
        monkeypatch.setattr(core, "jit_enabled", lambda on=on: on)
        outputs[on] = run()
    assert set(needs) <= set(calls), calls
    return outputs


def _assert_same(a: Any, b: Any, where: str = "") -> None:
    if isinstance(a, dict):
        assert list(a) == list(b), where
        for key in a:
            _assert_same(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_same(x, y, f"{where}[{i}]")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, where
        np.testing.assert_array_equal(a, b, err_msg=where)  # NaN in the same places, else equal
    else:
        assert a == b, where


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_compiled_bookkeeping_gives_what_numpy_gives(monkeypatch, seed):
    obstacles = [] if seed == 0 else [[0.0, 1.0, 0.8], [[1.0, -1.0], [2.0, -1.0], [2.0, 0.5]]]
    out = _both(monkeypatch, lambda: _episode(seed, obstacles))
    _assert_same(out[True], out[False])
    calls = [c[0] for c in out[True]["calls"]]
    # The episodes did what the test is for: snaps, detours, waypoints passed by arrival and by
    # time, and, over the seeds, several in one frame and collisions.
    assert calls.count("set_waypoints") > 10 and calls.count("set_goals") > 10
    passes = out[True]["passes"]
    assert passes["arrival"] > 2 and passes["time"] > 2 and passes["several"] + seed > 0
    assert (sum(r["collisions"].sum() for r in out[True]["record"][::2]) > 0) == bool(obstacles)


def test_the_compiled_observation_clips_as_numpy_does(monkeypatch):
    """Far from the origin, fast, or with joints far from the pelvis: every bound of the
    observation Box is met, on both paths alike."""

    def observe() -> dict[str, np.ndarray]:
        batch = CharacterBatch(EnvConfig(), [])
        rng = np.random.default_rng(0)
        batch.texts = ["a"] * 3
        batch.route_arr = rng.normal(0.0, 3e4, (3, 5, 3))
        batch.route_count = np.array([1, 3, 5])
        batch.k = np.array([0, 1, 4])
        batch.following = np.array([True, False, True])
        batch.pos = np.array([[2e4, -3e4], [1.0, 2.0], [-0.5, 0.25]])
        batch.theta = np.array([0.3, -3.5, 7.0])
        batch.vel = np.array([[150.0, -20.0, 1.0], [-500.0, 0.0, np.nan], [0.1, 0.2, -101.0]])
        batch.joints = (rng.normal(0.0, 8.0, (3, NUM_JOINTS, 3)) + [[[1.0, 0.0, 2.0]]]).astype(np.float32)
        batch.caption = np.array([[250.0, -0.5], [-250.0, 3.0], [1.0, 99.0]], np.float32)
        return batch.observations()

    out = _both(monkeypatch, observe, needs=("observe",))
    _assert_same(out[True], out[False])
    assert np.abs(out[True]["pose"]).max() == 10.0 and np.nanmax(np.abs(out[True]["velocity"])) == 100.0
    assert np.isnan(out[True]["velocity"][1, 2]) and np.abs(out[True]["caption"]).max() == 100.0


@pytest.mark.parametrize("mode", ["learning-default", "absolute", "relative", "vector"])
def test_the_environments_give_the_same_steps_both_ways(monkeypatch, random_generator, mode):
    """The whole env, driven as a learner or a route follower would, vector env and autoreset
    included: observations, rewards and infos to the bit."""
    kwargs = {
        "absolute": {"action_mode": "absolute", "frames_per_step": 1},
        "relative": {"action_mode": "relative"},
    }

    def run() -> list[Any]:
        if mode == "vector":
            env = gym.make_vec("motion_env/Waypoints-v0", num_envs=3, vectorization_mode="vector_entry_point",
                               generator=random_generator, max_episode_steps=6)  # fmt: skip
        else:
            env = gym.make("motion_env/Waypoints-v0", generator=random_generator, **kwargs.get(mode, {}))
        env.action_space.seed(0)
        out = [env.reset(seed=4)]
        for _ in range(15):
            out.append(env.step(env.action_space.sample()))
        env.close()
        return out

    out = _both(monkeypatch, run)
    _assert_same(out[True], out[False])
