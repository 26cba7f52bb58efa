"""MotionGenerator: whole clips, batches, streaming, validation and weight round trips.

The tests run on MotionGenerator.random() (tiny untrained models, the real MiniLM text encoder);
one test checks the shipped weights when they are packaged.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_env.generation.balance import StreamBalance
from motion_env.generation.generator import WEIGHT_FILES, MotionGenerator, SamplingConfig
from motion_env.motion.kinematics import pelvis_shape
from motion_env.motion.skeleton import FPS, NUM_JOINTS
from motion_env.motion.types import Motion

ROUTE = [[0.0, 2.0, 40], [2.0, 4.0, 100]]


@pytest.fixture
def gen(random_generator: MotionGenerator) -> MotionGenerator:
    return random_generator


def _pelvis_xz(joints: np.ndarray) -> np.ndarray:
    return joints[..., 0, :][..., [0, 2]]


def test_generate_shapes_and_metadata(gen: MotionGenerator) -> None:
    m = gen.generate("a person walks forward", waypoints=ROUTE, num_frames=37, seed=0)
    assert isinstance(m, Motion)
    assert m.joints.shape == (37, NUM_JOINTS, 3) and m.joints.dtype == np.float32
    assert m.fps == FPS
    assert np.isfinite(m.joints).all()
    assert m.text == "a person walks forward"
    np.testing.assert_allclose(m.waypoints[:, :2], np.array(ROUTE)[:, :2])
    assert m.meta["seed"] == "0" and "untrained" in m.meta


def test_generate_is_seeded(gen: MotionGenerator) -> None:
    a = gen.generate("a person jogs", waypoints=ROUTE, num_frames=30, seed=5)
    b = gen.generate("a person jogs", waypoints=ROUTE, num_frames=30, seed=5)
    c = gen.generate("a person jogs", waypoints=ROUTE, num_frames=30, seed=6)
    np.testing.assert_array_equal(a.joints, b.joints)
    assert np.abs(a.joints - c.joints).max() > 1e-4
    assert gen.generate("a person jogs", num_frames=5).meta["seed"] != ""  # seed=None draws one


def test_start_and_timed_waypoints_are_met(gen: MotionGenerator) -> None:
    start = (1.0, -2.0, 0.7)
    m = gen.generate(
        "a person walks", waypoints=[[1.5, 0.0, 30], [3.0, 1.0, 60]], num_frames=61, seed=1, start=start
    )
    np.testing.assert_allclose(_pelvis_xz(m.joints)[0], start[:2], atol=1e-5)
    # The untrained controller wanders anywhere; the snap still puts the pelvis on timed waypoints.
    np.testing.assert_allclose(_pelvis_xz(m.joints)[[30, 60]], [[1.5, 0.0], [3.0, 1.0]], atol=1e-4)


def test_batch_rows_match_single_clips(gen: MotionGenerator) -> None:
    texts = ["a person walks", "someone runs in a circle", "a person waves"]
    routes = [ROUTE, None, [[1.0, 1.0]]]
    batch = gen.generate_batch(texts, routes, num_frames=24, seed=3, starts=np.zeros((3, 3)))
    assert [m.text for m in batch] == texts
    single = gen.generate(texts[0], ROUTE, num_frames=24, seed=3)
    np.testing.assert_allclose(batch[0].joints, single.joints, atol=1e-5)
    assert batch[1].waypoints is None and batch[2].waypoints.shape == (1, 3)


def test_stream_shapes_and_root_path_match_whole_clips(gen: MotionGenerator, monkeypatch) -> None:
    texts = ["a person walks", "a person runs"]
    stream = gen.stream(texts, seed=2)
    assert stream.batch_size == 2
    np.testing.assert_array_equal(stream.frame_index, [0, 0])
    frames = np.stack([stream.step() for _ in range(30)], axis=1)  # (B, T, 22, 3)
    assert frames.shape == (2, 30, NUM_JOINTS, 3) and frames.dtype == np.float32
    np.testing.assert_array_equal(stream.frame_index, [30, 30])
    assert stream.root_state.shape == (2, 3)
    np.testing.assert_allclose(stream.root_state[:, :2], _pelvis_xz(frames[:, -1]), atol=1e-5)
    # Without waypoints the streamed root path is the whole-clip one: same controller rollout,
    # same per-character generators; both then shift it a little for balance (generation.balance:
    # whole clips over the clip, the stream token by token), the same way, not by the same amount.
    balanced = gen.generate_batch(texts, num_frames=30, seed=2)
    with monkeypatch.context() as m:
        m.setattr(type(gen.pipeline), "balance", lambda self, features, path, route, n: path)
        m.setattr(
            StreamBalance, "shift_rows", lambda self, rows, joints, *a: np.zeros((*joints.shape[:2], 2))
        )
        clips = gen.generate_batch(texts, num_frames=30, seed=2)
        stream = gen.stream(texts, seed=2)
        unshifted = np.stack([stream.step() for _ in range(30)], axis=1)
    for b in range(2):
        np.testing.assert_allclose(_pelvis_xz(unshifted[b]), _pelvis_xz(clips[b].joints), atol=1e-4)
        assert np.abs(_pelvis_xz(balanced[b].joints) - _pelvis_xz(clips[b].joints)).max() < 0.2
        assert 0.0 < np.abs(_pelvis_xz(frames[b]) - _pelvis_xz(clips[b].joints)).max() < 0.2


def test_clips_and_streams_keep_one_pelvis_shape(gen: MotionGenerator) -> None:
    # The random decoder's hips wander along the spine from frame to frame; each clip and each
    # streamed character gets one pelvis shape (the clip's median, the stream's first token's),
    # which the feet and physics stages after the composition leave as it is.
    clip = gen.generate("a person walks", num_frames=40, seed=5).joints
    shape = pelvis_shape(clip)
    assert np.ptp(shape) < 1e-4  # 1.1 mm without the hold
    stream = gen.stream(["a person walks", "a person runs"], seed=5)
    frames = np.stack([stream.step() for _ in range(16)], axis=1)
    stream.reset(1, "a person waves")
    later = np.stack([stream.step() for _ in range(12)], axis=1)
    for b in range(2):
        assert np.ptp(pelvis_shape(frames[b])) < 1e-4 and np.ptp(pelvis_shape(later[b])) < 1e-4
    np.testing.assert_allclose(pelvis_shape(later[0]), pelvis_shape(frames[0])[0], atol=1e-4)


def test_streamed_path_is_smoothed_as_whole_clips_and_passes_timed_waypoints(
    pretrained_generator, monkeypatch
) -> None:
    # The trained controller brakes and surges where it passes a timed waypoint; the stream smooths
    # its path before bending it through them (PATH_SMOOTHING), as whole clips do: the root
    # accelerates far less (30.9 -> 11.2 m/s^2 at most here) and still passes them exactly.
    from motion_env.generation import stream_paths

    route = [[0.0, 2.5, 20], [0.3, 5.2, 40], [0.5, 8.0, 60]]

    def root_accel_and_misses() -> tuple[np.ndarray, float]:
        stream = pretrained_generator.stream(["a person runs"], [route], seed=3)
        xz = _pelvis_xz(np.stack([stream.step()[0] for _ in range(61)]))
        misses = max(np.linalg.norm(xz[f] - [x, z]) for x, z, f in route)
        return np.linalg.norm(np.diff(xz, n=2, axis=0), axis=-1) * FPS**2, misses

    assert root_accel_and_misses()[1] < 1e-4  # the balance keeps the waypoints' frames in place
    # The balance's shift, which moves the pelvis for the floor's push, is left out here.
    monkeypatch.setattr(
        StreamBalance, "shift_rows", lambda self, rows, joints, *a: np.zeros((*joints.shape[:2], 2))
    )
    smoothed, missed = root_accel_and_misses()
    monkeypatch.setattr(stream_paths, "PATH_SMOOTHING", 0.0)
    raw, raw_missed = root_accel_and_misses()
    assert missed < 1e-4 and raw_missed < 1e-4
    assert smoothed.max() < 0.6 * raw.max() and smoothed.mean() < 0.6 * raw.mean()


def test_stream_is_seeded(gen: MotionGenerator) -> None:
    def run() -> np.ndarray:
        s = gen.stream(["a person walks", "a person jumps"], [ROUTE, None], seed=11)
        out = []
        for t in range(26):
            if t == 9:
                s.set_text("a person runs", index=1)
            out.append(s.step())
        return np.stack(out)

    np.testing.assert_array_equal(run(), run())


def test_stream_stays_continuous_when_steered(gen: MotionGenerator) -> None:
    stream = gen.stream(["a person walks"] * 2, [[[0.5, 0.5]], None], seed=4)
    frames = []
    for t in range(48):
        if t == 10:  # mid-token: the change acts from the next token on
            stream.set_text("a person runs fast", index=0)
            stream.set_waypoints([[-1.0, 1.0], [0.0, 3.0]], index=1)
        if t == 27:
            stream.set_waypoints([[5.0, 5.0], [8.0, 2.0]])
            stream.set_text("an old man shuffles")
        frames.append(stream.step())
    frames = np.stack(frames, axis=1)
    pelvis_step = np.linalg.norm(np.diff(_pelvis_xz(frames), axis=1), axis=-1)  # (B, T-1)
    # A steering call moves no emitted pose and makes the path jump nowhere: the pelvis moves
    # like before the call (the untrained controller drifts ~1 cm per frame; the far untimed
    # waypoints are left to it, not snapped to).
    assert pelvis_step.max() < 0.05
    pose_step = np.abs(np.diff(frames, axis=1)).max(axis=(2, 3))
    assert pose_step.max() < 0.2
    assert stream.texts == ["an old man shuffles"] * 2


def test_stream_reset_restarts_one_character(gen: MotionGenerator) -> None:
    stream = gen.stream(["a person walks", "a person runs"], seed=0)
    for _ in range(7):
        stream.step()
    stream.reset(1, "a person waves", waypoints=[[1.0, 3.0, 40]], start=(2.0, 1.0, 0.5))
    np.testing.assert_array_equal(stream.frame_index, [7, 0])
    np.testing.assert_allclose(stream.root_state[1], [2.0, 1.0, 0.5])
    frame = stream.step()
    np.testing.assert_allclose(_pelvis_xz(frame[1]), [2.0, 1.0], atol=1e-5)
    np.testing.assert_array_equal(stream.frame_index, [8, 1])
    for _ in range(40):
        frame = stream.step()
    np.testing.assert_allclose(_pelvis_xz(frame[1]), [1.0, 3.0], atol=1e-4)  # frame 40 of its episode


@pytest.mark.parametrize(
    ("waypoints", "match"),
    [
        ([[0.0, np.nan, 10]], "NaN or infinite"),
        ([[0.0, np.inf]], "NaN or infinite"),
        ([1.0, 2.0], "shape"),
        ([[0.0, 1.0, 2.0, 3.0]], "shape"),
        ([[0.0, 1.0, 50], [1.0, 2.0, 20]], "increasing"),
        ([[0.0, 1.0, -5]], ">= 0"),
        ([], "empty"),
    ],
)
def test_bad_waypoints_are_rejected(gen: MotionGenerator, waypoints: list, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        gen.generate("a person walks", waypoints=waypoints, num_frames=10)
    with pytest.raises(ValueError, match=match):
        gen.stream(["a person walks"], seed=0).set_waypoints(waypoints)
    with pytest.raises(ValueError, match=match):
        gen.generate_batch(["a person walks", "a person runs"], [None, waypoints], num_frames=10)


def test_bad_arguments_are_rejected(gen: MotionGenerator) -> None:
    with pytest.raises(ValueError, match="empty"):
        gen.generate("   ", num_frames=10)
    with pytest.raises(ValueError, match="num_frames"):
        gen.generate("a person walks", num_frames=0)
    with pytest.raises(ValueError, match="start"):
        gen.generate("a person walks", num_frames=10, start=(0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="start"):
        gen.generate("a person walks", num_frames=10, start=(0.0, 1.0))
    with pytest.raises(ValueError, match="entries"):
        gen.generate_batch(["a", "b"], waypoints=[ROUTE, None, None], num_frames=10)
    with pytest.raises(ValueError, match="starts"):
        gen.generate_batch(["a", "b"], num_frames=10, starts=np.zeros((3, 3)))
    with pytest.raises(TypeError):
        gen.generate_batch("a person walks", num_frames=10)
    stream = gen.stream(["a person walks"], seed=0)
    with pytest.raises(IndexError):
        stream.set_text("a person runs", index=3)
    with pytest.raises(ValueError, match="empty"):
        stream.reset(0, "")
    with pytest.raises(ValueError, match="increasing"):
        stream.set_waypoints([[0, 1, 9], [0, 2, 3]])
    with pytest.raises(ValueError, match="temperature"):
        SamplingConfig(temperature=0.0)


def test_weights_round_trip(gen: MotionGenerator, tmp_path) -> None:
    gen.sampling = SamplingConfig(temperature=0.9, top_p=0.95)
    try:
        folder = gen.save(tmp_path / "weights")
        assert sorted(p.name for p in folder.iterdir()) == sorted([*WEIGHT_FILES.values(), "sampling.json"])
        loaded = MotionGenerator.from_pretrained(folder, text_encoder=gen.text_encoder)
        assert loaded.untrained and loaded.sampling == gen.sampling
        a = gen.generate("a person walks", ROUTE, num_frames=20, seed=7)
        b = loaded.generate("a person walks", ROUTE, num_frames=20, seed=7)
        np.testing.assert_array_equal(a.joints, b.joints)
        half = MotionGenerator.from_pretrained(
            gen.save(tmp_path / "half", half=True), text_encoder=gen.text_encoder
        )
        c = half.generate("a person walks", ROUTE, num_frames=20, seed=7)
        assert c.joints.shape == a.joints.shape and np.isfinite(c.joints).all()
    finally:
        gen.sampling = SamplingConfig()


def test_from_pretrained_names_what_is_missing(tmp_path) -> None:
    with pytest.raises(FileNotFoundError, match="no generator weights"):
        MotionGenerator.from_pretrained(tmp_path / "nowhere")
    (tmp_path / "vqvae.pt").write_bytes(b"")
    with pytest.raises(FileNotFoundError, match="gpt.pt"):
        MotionGenerator.from_pretrained(tmp_path)


def test_shipped_model_follows_a_route(pretrained_generator: MotionGenerator) -> None:
    gen = pretrained_generator
    assert not gen.untrained
    route = [[0.0, 2.5, 50], [2.0, 4.5, 110]]
    m = gen.generate("a person walks forward and turns right", waypoints=route, num_frames=120, seed=0)
    pelvis = _pelvis_xz(m.joints)
    np.testing.assert_allclose(pelvis[[50, 110]], np.array(route)[:, :2], atol=0.02)
    # A walk: the pelvis keeps a plausible height and the feet touch the floor.
    assert 0.7 < np.median(m.joints[:, 0, 1]) < 1.1
    assert np.percentile(m.joints[:, [7, 8, 10, 11], 1].min(axis=1), 50) < 0.1


def test_the_stream_passes_untimed_waypoints_behind_the_character(
    pretrained_generator: MotionGenerator,
) -> None:
    # A walker 3 m out is given a waypoint behind and to its right, then one ahead: it turns
    # back through the first (the studio's browser test did this, and the smoothed look-ahead
    # cut the turn 0.53 m short of it, so the route never counted it reached).
    stream = pretrained_generator.stream(["a person walks forward"], seed=0)
    for _ in range(60):
        stream.step()
    stream.set_text("a person jogs", index=0)
    route = np.array([[1.5, 2.5, np.nan], [-1.0, 5.5, np.nan]], np.float32)
    stream.set_waypoints(route, index=0)
    pelvis = np.stack([np.asarray(stream.step())[0, 0, [0, 2]] for _ in range(140)])
    closest = [np.linalg.norm(pelvis - w[:2], axis=1).min() for w in route]
    np.testing.assert_allclose(closest, 0.0, atol=0.02)


def _standing(frames: int, step: float) -> np.ndarray:
    """A rest-pose body that glides along +X by `step` metres per frame, feet included."""
    from motion_env.motion.kinematics import bone_offsets, forward_kinematics

    rots = np.zeros((frames, NUM_JOINTS, 4))
    rots[..., 0] = 1.0
    height = -float(bone_offsets()[[2, 5, 8], 1].sum())
    pos = np.stack([np.arange(frames) * step, np.full(frames, height), np.zeros(frames)], axis=1)
    return forward_kinematics(pos, rots).astype(np.float32)


def test_foot_pinner_holds_feet_in_contact_and_lets_go_smoothly() -> None:
    from motion_env.generation.feet import FOOT_BLEND, FOOT_CREEP, FOOT_MAX_OFFSET, FootPinner

    joints = _standing(20, 0.01)  # the feet skate 1 cm per frame
    contacts = np.zeros((20, 4))
    contacts[:10, 0] = 1.0  # the left ankle is in contact for the first 10 frames
    pinner = FootPinner(1)
    # Two calls (as the stream makes them, a token at a time) equal one.
    out = np.concatenate(
        [pinner.apply(0, joints[:8], contacts[:8]), pinner.apply(0, joints[8:], contacts[8:])]
    )
    # Held, creeping FOOT_CREEP a frame at most (as real planted feet slide), where it slid 9 cm
    # (within millimetres: the straight rest-pose leg cannot quite reach).
    crept = np.repeat(joints[:1, 7, [0, 2]], 10, axis=0)
    crept[:, 0] += FOOT_CREEP * np.arange(10)
    np.testing.assert_allclose(out[:10, 7, [0, 2]], crept, atol=2e-3)
    np.testing.assert_allclose(out[10 + FOOT_BLEND :], joints[10 + FOOT_BLEND :], atol=1e-6)  # released
    np.testing.assert_allclose(
        out[:, [0, 2, 5, 8, 11]], joints[:, [0, 2, 5, 8, 11]]
    )  # the right leg untouched
    # A foot dragged faster than the pin may hold slides along at FOOT_MAX_OFFSET: no pop later.
    fast = _standing(40, 0.05)
    held = FootPinner(1).apply(0, fast, np.tile([1.0, 0.0, 0.0, 0.0], (40, 1)))
    gap = np.linalg.norm(held[:, 7, [0, 2]] - fast[:, 7, [0, 2]], axis=1)
    assert (
        gap.max() <= FOOT_MAX_OFFSET + 1e-6 and gap[-1] > 0.8 * FOOT_MAX_OFFSET
    )  # (a straight leg reaches less)
    assert np.abs(np.diff(gap[10:])).max() < 1e-4  # steady: it slides along


def test_saving_keeps_what_the_model_knows_about_captions(gen: MotionGenerator, tmp_path) -> None:
    from motion_env.text.vocabulary import load_vocabulary

    shipped = load_vocabulary()
    if shipped is None:
        pytest.skip("the shipped vocabulary (motion_env/weights/vocabulary.*) is not installed")
    previous, gen.pipeline.vocabulary = gen.pipeline.vocabulary, shipped
    try:
        folder = gen.save(tmp_path / "weights")
        again = load_vocabulary(folder)
        assert again is not None and again.texts == shipped.texts and again.actions == shipped.actions
        np.testing.assert_allclose(again.embeddings, shipped.embeddings, atol=2e-3)
    finally:
        gen.pipeline.vocabulary = previous
