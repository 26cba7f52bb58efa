"""Naturalness of generated motion, per action, next to the real held-out takes (``motion-env eval natural``).

Each action of the split with at least ``min_takes`` takes (mirrors included; the label of the
dataset's ``index.csv``) gives up to ``per_action`` of its takes (seeded choice), each made again:

- stage ``generated``: by the generator from the take's own first caption (the caption
  templates' wording of its labels), from the take's start, along its root path continued one
  second past its end (:func:`extended_path`: the takes are cuts of longer motion), with timed
  waypoints every second where the take travels (:func:`travel_waypoints`), cut to its length;
- stage ``streamed``: the same request (caption, start, timed waypoints) made frame by frame by
  the stream (:meth:`~motion_env.generation.generator.MotionGenerator.stream`), as the
  environments emit it: the causal stages (the decoder's history, the streamed foot pin and
  physics, the path's residuals spread as it goes) instead of the whole clip's;
- stage ``vqvae``: the take's features encoded and decoded by the VQ-VAE alone, the decoded body
  placed on the take's real root path and its feet pinned as the generator does (stages 4-6 of
  :mod:`motion_env.generation.pipeline`, without the physics stage): what the tokenizer alone
  changes;
- stage ``real-path``: the generator's own tokens, sampled from the take's caption along the
  take's real root path instead of the path controller's, then decoded, balanced, placed on that
  path, its feet pinned and its physics applied as in a whole clip: with ``vqvae`` and
  ``generated`` on either side, it splits what the tokenizer, the GPT and the path each add.

Per action (and over all of them), the clips against the same real takes (definitions in
``docs/metrics.md``, "Naturalness"):

- ``plausible``: the share judged plausible by the MuJoCo replay (:func:`motion_env.replay.evaluate`);
- ``accel_ratio``, ``jerk_ratio``: the 99th percentile of every joint's acceleration (second
  difference x fps^2) and jerk (third difference x fps^3) over all frames, divided by the real
  takes' (:func:`~motion_env.evaluation.metrics.joint_acceleration`, ``joint_jerk``);
- ``pops``: the share of clips whose largest joint acceleration exceeds 1.5 x the 99.9th
  percentile of all the action's real takes in the split;
- ``skating_ratio``: foot skating (:func:`~motion_env.evaluation.metrics.foot_skating_ratio`)
  divided by the real takes';
- ``fd``, ``diversity``: Fréchet distance to all the action's real takes and the mean distance
  between clips, on the features of the shipped classifier of real takes
  (:func:`motion_env.models.classifier.clip_embeddings`), next to ``fd_real_vs_real`` (the real
  takes split in two random halves, the first cut to as many takes as clips were made: two real
  samples of the clips' size) and the real takes' own diversity.

The row over all actions compares like with like: each action's real takes weigh, in the
reference's mean and covariance and in its diversity, what the action's clips weigh among the
clips (:func:`mix_weights`). Unweighted, a rare action (4 takes of 490, but 4 of 94 clips) counted
5 times less in the reference than in the clips, and the real takes chosen for the clips
themselves scored a distance of 144 against all real takes (test split, 2026-11-26).
"""

from __future__ import annotations

import time
from collections import Counter, defaultdict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from motion_env.evaluation.metrics import (
    check_settings,
    diversity,
    foot_skating_ratio,
    frechet_distance,
    joint_acceleration,
    joint_jerk,
)
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import root_path_from_joints

__all__ = [
    "STAGES",
    "NaturalnessResult",
    "NaturalnessRow",
    "NaturalnessSettings",
    "NaturalTake",
    "evaluate_naturalness",
    "naturalness_takes",
    "extended_path",
    "make_again",
    "mix_weights",
    "travel_waypoints",
]

STAGES = ("generated", "streamed", "vqvae", "real-path")
TRAVEL_SPEED = 0.25  # m/s: a second in which the root moves slower than this gets no waypoint
POP_FACTOR = 1.5  # a clip pops when its largest joint acceleration exceeds this x the real p99.9
MIN_FRAMES = 20  # 1 s: the shortest clip the replay judges


@dataclass
class NaturalnessSettings:
    """What :func:`evaluate_naturalness` measures.

    Attributes:
        data: a dataset built by ``motion-env data build`` (``index.csv`` and the splits).
        split: the held-out split: "test" to report, "val" to choose between models.
        per_action: clips per action (the action's takes, seeded choice, when it has more).
        seed: the choice of takes, the real-vs-real halves and the generator's seed.
        stage: "generated" (the whole generator), "streamed" (the same, frame by frame), "vqvae"
            (the real takes through the VQ-VAE) or "real-path" (the generator's tokens along the
            takes' real root paths).
        min_takes: an action is reported when the split has at least this many takes of it.
        classifier: the classifier checkpoint whose features the distances use (None: shipped).
        actions: only these actions (None: every action with min_takes takes); each one's row is
            the one a run over every action gives (the same takes, seed and real halves), the
            "all" row is over these.
    """

    data: str | Path
    split: str = "test"
    per_action: int = 7
    seed: int = 0
    stage: str = "generated"
    min_takes: int = 3
    classifier: str | Path | None = None
    actions: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        check_settings(self, per_action=2, seed=0, min_takes=3)
        if self.stage not in STAGES:
            raise ValueError(f"NaturalnessSettings.stage must be one of {STAGES}, got {self.stage!r}")
        if self.actions is not None:
            self.actions = tuple(self.actions)
            if not self.actions or not all(isinstance(a, str) and a.strip() for a in self.actions):
                raise ValueError(
                    f"NaturalnessSettings.actions must be None or action names, got {self.actions!r}"
                )


@dataclass
class NaturalTake:
    """A held-out take: its name, action, first caption, (T, 22, 3) joints, (T, 263) features."""

    name: str
    action: str
    text: str
    joints: np.ndarray
    features: np.ndarray


def naturalness_takes(data_dir: str | Path, split: str, min_takes: int = 3) -> dict[str, list[NaturalTake]]:
    """The split's takes of at least 1 s by action, for the actions with at least `min_takes` (sorted)."""
    from motion_env.data.dataset import read_split
    from motion_env.evaluation.route_following import read_index

    data_dir = Path(data_dir)
    index = read_index(data_dir)
    if not index:
        raise FileNotFoundError(f"no index.csv in {data_dir} (build it with motion-env data build)")
    by_action: dict[str, list[NaturalTake]] = defaultdict(list)
    for clip in read_split(data_dir, split):
        row = index.get(clip.name)
        if row is None or not row["label"] or clip.num_frames < MIN_FRAMES or ":" in clip.name:
            continue
        joints = np.asarray(clip.joints, np.float32)
        by_action[row["label"]].append(
            NaturalTake(
                clip.name, row["label"], clip.captions[0], joints, np.asarray(clip.features, np.float32)
            )
        )
    return {a: takes for a, takes in sorted(by_action.items()) if len(takes) >= min_takes}


def travel_waypoints(path: np.ndarray, every: int = FPS) -> np.ndarray | None:
    """Timed waypoints along a root path, every `every` frames where it travels.

    Args:
        path: (T, 3) x, z, heading.
        every: frames between waypoints (20: one a second).
    Returns:
        (K, 3) x, z, frame: the path's position at frames `every`, 2 `every`, ... (and the last
        frame when it is at least half a step on), each kept when the root moved faster than
        TRAVEL_SPEED since the previous candidate; None when none is (a take in place: the
        caption alone decides where to stand).
    """
    t_len = len(path)
    frames = list(range(every, t_len, every))
    if t_len - 1 - (frames[-1] if frames else 0) >= every // 2:
        frames.append(t_len - 1)
    kept, previous = [], 0
    for f in frames:
        moved = float(np.linalg.norm(path[f, :2] - path[previous, :2]))
        if moved > TRAVEL_SPEED * (f - previous) / FPS:
            kept.append([path[f, 0], path[f, 1], f])
        previous = f
    return np.array(kept, np.float32) if kept else None


def extended_path(path: np.ndarray, frames: int = FPS) -> np.ndarray:
    """(T, 3) root path continued `frames` past its end at its last second's mean velocity.

    The takes are cuts of longer motion: a run goes on running at the take's last frame. Asked to
    be at the last frame's spot then, the path controller would stop there (a route's last
    waypoint is where the character stays); along the continued path it passes through, and the
    clip is cut back to the take's length.
    """
    back = min(FPS, len(path) - 1)
    velocity = (path[-1] - path[-1 - back]) / max(back, 1)
    velocity[2] = 0.0  # the heading stays: a turning take is judged on the turn it made
    return np.concatenate([path, path[-1] + velocity * np.arange(1, frames + 1)[:, None]])


def _generated(gen: Any, take: NaturalTake, seed: int) -> np.ndarray:
    t_len = len(take.joints)
    path = extended_path(root_path_from_joints(take.joints))
    waypoints = travel_waypoints(path)
    motion = gen.generate(take.text, waypoints, len(path), seed=seed, start=path[0], infeasible="warn")
    return motion.joints[:t_len]


def _streamed(gen: Any, take: NaturalTake, seed: int) -> np.ndarray:
    """The request of :func:`_generated`, made frame by frame by one streamed character."""
    t_len = len(take.joints)
    path = extended_path(root_path_from_joints(take.joints))
    stream = gen.stream([take.text], [travel_waypoints(path)], starts=path[:1], seed=seed, infeasible="warn")
    return np.stack([stream.step()[0] for _ in range(t_len)])


def _vqvae(gen: Any, take: NaturalTake) -> np.ndarray:
    """The take through the VQ-VAE, placed on its real root path with the generator's stages 5-6."""
    import torch

    from motion_env.generation.feet import FootPinner
    from motion_env.motion.skeleton import FOOT_CONTACT

    p = gen.pipeline
    n = len(take.features) // p.rate * p.rate
    x = torch.from_numpy(p.normalizer.normalize(take.features[:n]))[None].to(p.device)  # (1, n, 263)
    with torch.no_grad():
        body = p.decode(p.vqvae.encode(x))[0]  # (n, 263)
    path = root_path_from_joints(take.joints)  # the compose holds the last pose over frames past n
    joints, _ = p.compose(body, path, len(take.joints))
    contacts = np.concatenate([body[:, FOOT_CONTACT], np.repeat(body[-1:, FOOT_CONTACT], len(path) - n, 0)])
    return FootPinner(1).apply(0, joints, contacts)


def _on_real_path(gen: Any, take: NaturalTake, seed: int) -> np.ndarray:
    """The take made again by the generator's stages 1 and 3-6 along its real root path (continued
    as in :func:`_generated`): the GPT reads that path's gait-free features (as in its training)
    instead of the path controller's path, and the body is placed on it."""
    import torch

    from motion_env.motion.trajectory import gait_free_path

    p = gen.pipeline
    t_len = len(take.joints)
    path = extended_path(root_path_from_joints(take.joints))
    n_tok = -(-t_len // p.rate)
    with torch.no_grad():
        tokens = p.sample_tokens(p.encode_text([take.text]), gait_free_path(path)[None], n_tok, seed)
        body = p.decode(tokens)[0]
    frames = n_tok * p.rate
    path = p.balance(body, path, None, frames)
    return p.place_clip(body, path, frames)[1][:t_len]


_MAKERS = {"generated": _generated, "streamed": _streamed, "real-path": _on_real_path}


def make_again(gen: Any, take: NaturalTake, seed: int, stage: str = "generated") -> np.ndarray:
    """`take` made again by `gen` as the evaluation's `stage` makes it ("generated", "streamed" or
    "real-path"; seed: the generator's): (T, 22, 3) joints."""
    if stage not in _MAKERS:
        raise ValueError(f"stage must be one of {sorted(_MAKERS)}, got {stage!r}")
    return _MAKERS[stage](gen, take, seed)


@dataclass
class _Clips:
    """Per-clip measurements of a set of clips (generated or real)."""

    accel: list[np.ndarray] = field(default_factory=list)
    jerk: list[np.ndarray] = field(default_factory=list)
    skating: list[float] = field(default_factory=list)
    plausible: list[bool] = field(default_factory=list)
    failed: list[list[str]] = field(default_factory=list)  # the replay's failed checks per judged clip
    joints: list[np.ndarray] = field(default_factory=list)

    def add(self, joints: np.ndarray) -> None:
        from motion_env.motion.types import Motion
        from motion_env.replay import evaluate

        self.accel.append(joint_acceleration(joints))
        self.jerk.append(joint_jerk(joints))
        self.skating.append(foot_skating_ratio(joints))
        replay = evaluate(Motion(joints=joints, fps=FPS))
        if replay["plausible"] is not None:
            self.plausible.append(bool(replay["plausible"]))
            self.failed.append(list(replay["failed"]))
        self.joints.append(joints)

    def extend(self, other: _Clips) -> None:
        for name in ("accel", "jerk", "skating", "plausible", "failed", "joints"):
            getattr(self, name).extend(getattr(other, name))


@dataclass
class NaturalnessRow:
    """The numbers of one action (or of all), clips against the same real takes; None: undefined."""

    takes: int  # real takes of the action(s) in the split
    clips: int  # clips made and measured
    plausible: float | None  # share judged plausible by the replay
    real_plausible: float | None
    replay_failures: dict[str, int]  # replay check -> clips that failed it (a clip may fail several)
    accel_p99: float  # m/s^2
    real_accel_p99: float
    accel_ratio: float
    jerk_p99: float  # m/s^3
    real_jerk_p99: float
    jerk_ratio: float
    pops: float  # share of clips over POP_FACTOR x the real takes' p99.9 acceleration
    real_pops: float
    skating: float
    real_skating: float
    skating_ratio: float | None
    fd: float | None
    fd_real_vs_real: float | None
    diversity: float | None
    real_diversity: float | None


def _share(values: list[bool]) -> float | None:
    return float(np.mean(values)) if values else None


def _ratio(a: float, b: float) -> float | None:
    return a / b if b > 0 else None


def _fd(a: np.ndarray, b: np.ndarray, b_weights: np.ndarray | None = None) -> float | None:
    return frechet_distance(a, b, b_weights) if min(len(a), len(b)) >= 2 else None


def _diversity(x: np.ndarray, weights: np.ndarray | None = None) -> float | None:
    return diversity(x, weights) if len(x) >= 2 else None


def mix_weights(clips: list[int], takes: list[int]) -> np.ndarray:
    """Weights of the real takes that give each action the share its clips have among the clips.

    Args:
        clips: per action, the clips made of it.
        takes: per action, its real takes (rows of the reference, in the same order, >= 1 each).
    Returns:
        (sum(takes),) weights: an action's takes each weigh clips[a] / takes[a], so its takes
        together weigh what its clips do.
    """
    if len(clips) != len(takes) or min(takes, default=1) < 1:
        raise ValueError(f"need a clip count and >= 1 take per action, got {clips} and {takes}")
    return np.concatenate([np.full(t, c / t) for c, t in zip(clips, takes)])


def _p99(values: list[np.ndarray]) -> float:
    return float(np.percentile(np.concatenate([v.ravel() for v in values]), 99))


def _row(
    made: _Clips, real: _Clips, thresholds: list[float], takes: int, emb: dict[str, np.ndarray]
) -> NaturalnessRow:
    """One row: `made` against `real` (the same takes); per-clip pop `thresholds`; `emb`: the
    classifier features of the made clips, of all the real takes and of the two real halves, and
    the weights of the real takes and of the second half (keys ``real_w``, ``half_b_w``; absent:
    equal)."""
    accel, real_accel = _p99(made.accel), _p99(real.accel)
    jerk, real_jerk = _p99(made.jerk), _p99(real.jerk)
    skate, real_skate = float(np.mean(made.skating)), float(np.mean(real.skating))
    return NaturalnessRow(
        takes=takes,
        clips=len(made.joints),
        plausible=_share(made.plausible),
        real_plausible=_share(real.plausible),
        replay_failures=dict(sorted(Counter(c for checks in made.failed for c in checks).items())),
        accel_p99=accel,
        real_accel_p99=real_accel,
        accel_ratio=accel / real_accel,
        jerk_p99=jerk,
        real_jerk_p99=real_jerk,
        jerk_ratio=jerk / real_jerk,
        pops=float(np.mean([a.max() > t for a, t in zip(made.accel, thresholds)])),
        real_pops=float(np.mean([a.max() > t for a, t in zip(real.accel, thresholds)])),
        skating=skate,
        real_skating=real_skate,
        skating_ratio=_ratio(skate, real_skate),
        fd=_fd(emb["made"], emb["real"], emb.get("real_w")),
        fd_real_vs_real=_fd(emb["half_a"], emb["half_b"], emb.get("half_b_w")),
        diversity=_diversity(emb["made"]),
        real_diversity=_diversity(emb["real"], emb.get("real_w")),
    )


@dataclass
class NaturalnessResult:
    """What :func:`evaluate_naturalness` measured: a row per action and one over all of them.

    Attributes:
        stage: one of :data:`STAGES`.
        split: the split the takes come from.
        actions: action -> its :class:`NaturalnessRow`.
        overall: all the actions' clips together (pops against each clip's own action).
        takes: action -> the names of the takes made again.
        seconds: wall time of the evaluation.
    """

    stage: str
    split: str
    actions: dict[str, NaturalnessRow]
    overall: NaturalnessRow
    takes: dict[str, list[str]]
    seconds: float

    def to_dict(self) -> dict[str, Any]:
        """The result as plain JSON-ready data."""
        return asdict(self)

    def format(self) -> str:
        """A plain-text table: a line per action, then "all"."""
        head = (
            f"{'action':<22}{'takes':>6}{'clips':>6}{'plausible':>10}{'real':>6}{'accel x':>8}{'jerk x':>8}"
            f"{'pops':>6}{'real':>6}{'skate x':>8}{'FD':>8}{'real/real':>10}{'div':>7}{'real':>7}"
        )
        lines = [f"naturalness, stage {self.stage}, split {self.split} ({self.seconds:.0f} s)", head]
        for name, r in (*self.actions.items(), ("all", self.overall)):
            lines.append(
                f"{name:<22}{r.takes:>6}{r.clips:>6}{_fmt(r.plausible, 10, 2)}{_fmt(r.real_plausible, 6, 2)}"
                f"{r.accel_ratio:>8.2f}{r.jerk_ratio:>8.2f}{r.pops:>6.2f}{r.real_pops:>6.2f}"
                f"{_fmt(r.skating_ratio, 8, 2)}{_fmt(r.fd, 8, 1)}{_fmt(r.fd_real_vs_real, 10, 1)}"
                f"{_fmt(r.diversity, 7, 2)}{_fmt(r.real_diversity, 7, 2)}"
            )
        failing = [
            f"{name} ({', '.join(f'{c} {n}' for c, n in r.replay_failures.items())})"
            for name, r in self.actions.items()
            if r.replay_failures
        ]
        if failing:
            lines.append("replay checks failed, clips per check: " + "; ".join(failing))
        return "\n".join(lines)


def _fmt(value: float | None, width: int, digits: int) -> str:
    return f"{'-':>{width}}" if value is None else f"{value:>{width}.{digits}f}"


def _embeddings(model: Any, made: _Clips, takes: list[NaturalTake], rng: np.random.Generator) -> dict:
    """Classifier features of the made clips, all real takes and two random halves of them, the
    first cut to the number of made clips (the distance of two real samples of the clips' size:
    the bias of a few samples in 192 dimensions is in both)."""
    from motion_env.models.classifier import clip_embeddings

    real = clip_embeddings(model, [t.joints for t in takes])
    order = rng.permutation(len(takes))
    half = len(takes) // 2
    return {
        "made": clip_embeddings(model, made.joints),
        "real": real,
        "half_a": real[order[: min(half, len(made.joints))]],
        "half_b": real[order[half:]],
    }


def _pooled_embeddings(per_action: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The actions' features joined, the real takes weighted to the made clips' mix of actions and
    the second halves to the first halves' (:func:`mix_weights`)."""
    out = {k: np.concatenate([e[k] for e in per_action]) for k in ("made", "real", "half_a", "half_b")}
    count = {k: [len(e[k]) for e in per_action] for k in out}
    out["real_w"] = mix_weights(count["made"], count["real"])
    out["half_b_w"] = mix_weights(count["half_a"], count["half_b"])
    return out


def evaluate_naturalness(gen: Any, settings: NaturalnessSettings, progress: bool = True) -> NaturalnessResult:
    """Make the chosen held-out takes again and measure them against the real ones (module docstring).

    Args:
        gen: a :class:`~motion_env.generation.generator.MotionGenerator` (stage "vqvae" uses its
            VQ-VAE, normaliser and placement only).
        settings: the data, split, clips per action, seed, stage and classifier.
        progress: show a tqdm progress bar (one step per clip).
    Returns:
        a :class:`NaturalnessResult`.
    """
    from tqdm.auto import tqdm

    from motion_env.models.classifier import load_classifier

    t0 = time.perf_counter()
    classifier, _ = load_classifier(settings.classifier)
    takes = naturalness_takes(settings.data, settings.split, settings.min_takes)
    if not takes:
        raise ValueError(
            f"{settings.data}: no action has {settings.min_takes} takes of at least 1 s "
            f"in split {settings.split!r}"
        )
    unknown = sorted(set(settings.actions or ()) - set(takes))
    if unknown:
        raise ValueError(
            f"actions {unknown}: no such action with {settings.min_takes} takes of at least 1 s in "
            f"split {settings.split!r} (there are: {', '.join(takes)})"
        )
    rng = np.random.default_rng(settings.seed)
    chosen = {
        a: [ts[i] for i in sorted(rng.choice(len(ts), min(settings.per_action, len(ts)), replace=False))]
        for a, ts in takes.items()
    }
    if settings.actions is not None:  # the choice above is made for every action all the same
        chosen = {a: c for a, c in chosen.items() if a in settings.actions}
    bar = tqdm(
        total=sum(map(len, chosen.values())), desc=f"naturalness ({settings.stage})", disable=not progress
    )
    rows: dict[str, NaturalnessRow] = {}
    pooled_made, pooled_real, thresholds = _Clips(), _Clips(), []
    pooled_emb: list[dict[str, np.ndarray]] = []
    for action, ts in takes.items():
        if action not in chosen:
            rng.permutation(len(ts))  # its real halves (_embeddings): the others' stay as in a full run
            continue
        made, real = _Clips(), _Clips()
        for take in chosen[action]:
            bar.set_postfix_str(action, refresh=False)
            if settings.stage == "vqvae":
                made.add(_vqvae(gen, take))
            else:
                made.add(_MAKERS[settings.stage](gen, take, settings.seed))
            real.add(take.joints)
            bar.update(1)
        real_accel = np.concatenate([joint_acceleration(t.joints).ravel() for t in ts])
        pop = POP_FACTOR * float(np.percentile(real_accel, 99.9))
        emb = _embeddings(classifier, made, ts, rng)
        rows[action] = _row(made, real, [pop] * len(made.joints), len(ts), emb)
        pooled_made.extend(made)
        pooled_real.extend(real)
        thresholds += [pop] * len(made.joints)
        pooled_emb.append(emb)
    bar.close()
    overall = _row(
        pooled_made,
        pooled_real,
        thresholds,
        sum(len(takes[a]) for a in chosen),
        _pooled_embeddings(pooled_emb),
    )
    return NaturalnessResult(
        stage=settings.stage,
        split=settings.split,
        actions=rows,
        overall=overall,
        takes={a: [t.name for t in c] for a, c in chosen.items()},
        seconds=round(time.perf_counter() - t0, 1),
    )
