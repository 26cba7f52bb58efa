"""Joint targets and objectives of a request, checked once at the boundary.

Joint targets come as a :class:`~motion_env.joint_targets.JointTargets` or a dense (T, 22, 3) array
with NaN where a joint is free (both give a JointTargets); objectives as a list of
:mod:`motion_env.objectives` or callables ``f(joints) -> scalar``, each evaluated once on a still clip
so that a broken one fails here, naming it, and not deep inside the refinement.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from motion_env.joint_targets import JointTargets
from motion_env.motion.skeleton import BONE_LENGTHS, JOINT_NAMES, NUM_JOINTS, PARENTS
from motion_env.motion.trajectory import MAX_COORDINATE
from motion_env.objectives import HeightLimit, KeepOut, StayInside

__all__ = [
    "check_joint_targets",
    "check_objective_values",
    "check_objectives",
    "per_row_controls",
    "reach_heights",
    "warn_unreachable",
]


def check_joint_targets(
    targets: Any, num_frames: int | None, what: str = "joint_targets", first_frame: int = 0
) -> JointTargets | None:
    """None, a :class:`~motion_env.joint_targets.JointTargets`, or a dense (T, 22, 3) array of world
    targets (metres, NaN = the joint is free at that frame).

    Args:
        targets: the targets; a dense array has T = `num_frames` rows (None: any T >= 1, the
            stream's targets), row k being frame ``first_frame + k``; a JointTargets names its
            frames itself (clip frames, or the stream's episode frames).
        num_frames: the clip's length (None: the stream, any frame).
        what: the argument's name in messages.
        first_frame: the frame of a dense array's row 0.

    Returns:
        The targets as a JointTargets, or None when there are none (None, or every entry NaN).
        Raises ValueError naming the frame and joint of the first bad entry: a wrong shape (a
        target outside the clip's frames), an infinite value, a joint given only some of its
        coordinates, a coordinate beyond MAX_COORDINATE.
    """
    if targets is None:
        return None
    if isinstance(targets, JointTargets):
        return _check_sparse_targets(targets, num_frames, what)
    try:
        arr = np.asarray(targets, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(
            f"{what} must be a JointTargets or a numeric array of shape (T, {NUM_JOINTS}, 3), NaN where "
            "a joint is free"
        ) from None
    if arr.ndim != 3 or arr.shape[1:] != (NUM_JOINTS, 3):
        raise ValueError(
            f"{what} must have shape (num_frames, {NUM_JOINTS}, 3) (world x, y, z per frame and joint, NaN "
            f"where free), got {arr.shape}"
        )
    if num_frames is not None and arr.shape[0] != num_frames:
        outside = " (targets outside the clip)" if arr.shape[0] > num_frames else ""
        raise ValueError(
            f"{what} has {arr.shape[0]} frames, the clip has num_frames={num_frames}{outside}: give one row "
            f"per frame of the clip, NaN where a joint is free"
        )
    if arr.shape[0] < 1:
        raise ValueError(f"{what} has no frames")

    def name(frame: int, joint: int) -> str:
        return f"frame {frame + first_frame}, joint {joint} ({JOINT_NAMES[joint]})"

    bad = np.argwhere(np.isinf(arr).any(axis=-1))
    if len(bad):
        f, j = bad[0]
        raise ValueError(f"{what} has an infinite value at {name(f, j)}: {arr[f, j].tolist()}")
    nan = np.isnan(arr)
    partial = np.argwhere(nan.any(axis=-1) & ~nan.all(axis=-1))
    if len(partial):
        f, j = partial[0]
        raise ValueError(
            f"{what} gives only some coordinates at {name(f, j)}: {arr[f, j].tolist()}; give x, y and z, "
            f"or NaN for all three (a height alone: motion_env.objectives.HeightLimit)"
        )
    _check_coordinates(np.nan_to_num(arr).reshape(-1, 3), lambda k: name(*divmod(k, NUM_JOINTS)), what)
    if nan.all():
        return None
    out = JointTargets.from_dense(arr.astype(np.float32), first_frame)
    warn_unreachable(out, what)
    return out


def reach_heights() -> np.ndarray:
    """(22,) metres: the highest each joint can be, standing on the toes of one leg with the chain
    from the pelvis to the joint stretched straight up (an arm raised, the other leg kicked high)."""
    lengths = np.asarray(BONE_LENGTHS, np.float64)
    toe_to_pelvis = lengths[[10, 7, 4, 1]].sum()  # toe -> ankle -> knee -> hip -> pelvis
    up = np.full(NUM_JOINTS, toe_to_pelvis)
    for j in range(1, NUM_JOINTS):
        up[j] = up[PARENTS[j]] + lengths[j]
    return up


def warn_unreachable(targets: JointTargets | None, what: str = "joint_targets") -> None:
    """Warn, naming the frames, about targets no body can meet: above what the joint reaches on
    tiptoe with the arms up (:func:`reach_heights`), or below the floor. The clip is still made
    (the finish gets as close as the bones allow), but it will miss them."""
    if targets is None:
        return
    high = targets.positions[:, 1] > reach_heights()[targets.joints] + 0.01
    low = targets.positions[:, 1] < -0.01
    for bad, words in ((high, "above what that joint can reach"), (low, "below the floor")):
        if bad.any():
            k = np.flatnonzero(bad)
            names = ", ".join(
                f"{JOINT_NAMES[int(targets.joints[i])]} at frame {int(targets.frames[i])} "
                f"(y = {targets.positions[i, 1]:.2f} m)"
                for i in k[:5]
            )
            more = f" and {len(k) - 5} more" if len(k) > 5 else ""
            warnings.warn(
                f"{what}: {names}{more} {'is' if len(k) == 1 else 'are'} {words}; the motion will miss "
                f"{'it' if len(k) == 1 else 'them'}",
                UserWarning,
                stacklevel=5,
            )


def _check_coordinates(positions: np.ndarray, name: Any, what: str) -> None:
    far = np.flatnonzero(np.abs(positions).max(axis=-1) > MAX_COORDINATE)
    if len(far):
        raise ValueError(
            f"{what} at {name(int(far[0]))} is {positions[far[0]].tolist()}: coordinates must lie within "
            f"{MAX_COORDINATE:g} m of the origin"
        )


def _check_sparse_targets(targets: JointTargets, num_frames: int | None, what: str) -> JointTargets | None:
    def name(k: int) -> str:
        j = int(targets.joints[k])
        return f"frame {int(targets.frames[k])}, joint {j} ({JOINT_NAMES[j]})"

    if num_frames is not None and len(targets) and targets.frames[-1] >= num_frames:
        raise ValueError(
            f"{what} has a target at {name(len(targets) - 1)}, outside the clip's num_frames={num_frames} "
            "frames (0 .. num_frames - 1)"
        )
    _check_coordinates(targets.positions, name, what)
    warn_unreachable(targets, what)
    return targets if len(targets) else None


def check_objectives(
    objectives: Any, what: str = "objectives", num_frames: int | None = None
) -> tuple[Any, ...]:
    """None or a list of objectives (:mod:`motion_env.objectives`, or callables ``f(joints) -> scalar``)
    -> a tuple; TypeError naming the first entry that is not callable. With `num_frames` (a whole
    clip), each callable is also evaluated once (:func:`check_objective_values`)."""
    if objectives is None:
        return ()
    if callable(objectives) or isinstance(objectives, str | bytes) or not isinstance(objectives, Sequence):
        raise TypeError(
            f"{what} must be a list of objectives (e.g. [motion_env.objectives.KeepOut(...)]), "
            f"got {type(objectives).__name__}"
        )
    for k, obj in enumerate(objectives):
        if not callable(obj):
            raise TypeError(
                f"{what}[{k}] is a {type(obj).__name__}, not an objective: give a motion_env.objectives "
                f"object or a callable f(joints) -> scalar (joints: torch.Tensor (T, 22, 3))"
            )
    if num_frames is not None:
        check_objective_values(tuple(objectives), num_frames, what)
    return tuple(objectives)


def check_objective_values(objectives: tuple, num_frames: int, what: str = "objectives") -> None:
    """Evaluate each callable objective once on a still clip: it must return a finite 0-d (or
    one-element) torch tensor that depends on the joints. ValueError / TypeError naming it otherwise."""
    import torch  # here: checking a request must not load torch for callers that never pass one

    for k, obj in enumerate(objectives):
        if isinstance(obj, KeepOut | StayInside | HeightLimit):
            continue
        probe = torch.zeros(num_frames, 22, 3, requires_grad=True)
        try:
            with torch.enable_grad():
                value = obj(probe)
        except Exception as exc:  # the user's code: say which objective failed, keep the cause
            raise ValueError(
                f"{what}[{k}] ({obj!r}) raised {type(exc).__name__} on a (T, 22, 3) tensor: {exc}"
            ) from exc
        if not isinstance(value, torch.Tensor):
            raise TypeError(
                f"{what}[{k}] returned a {type(value).__name__}; it must return a scalar torch.Tensor "
                "computed "
                "from the joints (so the refinement can follow its gradient)"
            )
        if value.numel() != 1:
            raise ValueError(
                f"{what}[{k}] returned a tensor of shape {tuple(value.shape)}; it must return a scalar"
            )
        if not torch.isfinite(value).all():
            raise ValueError(
                f"{what}[{k}] returned {float(value)} on a still clip; it must return a finite cost"
            )
        if not value.requires_grad:
            raise ValueError(
                f"{what}[{k}] returned a value that does not depend on the joints (no gradient): the "
                "refinement could not lower it"
            )


def _per_row(values: Any, batch: int, is_one: Any, what: str) -> list[Any]:
    """None, one value for every row, or B entries -> B entries."""
    if values is None:
        return [None] * batch
    if is_one(values):
        return [values] * batch
    if not isinstance(values, Sequence | np.ndarray) or len(values) != batch:
        raise ValueError(f"{what} must be None, one value for every character, or a list of {batch} entries")
    return list(values)


def per_row_controls(
    joint_targets: Any, objectives: Any, batch: int, num_frames: int
) -> tuple[list[JointTargets | None], list[tuple[Any, ...]]]:
    """The joint targets and objectives of each character of a batch (None, one for all, or B entries)."""

    def one_array(v: Any) -> bool:
        if isinstance(v, JointTargets):
            return True
        return np.asarray(v, dtype=object).ndim == 3 if not isinstance(v, np.ndarray) else v.ndim == 3

    def one_list(v: Any) -> bool:
        return (
            not isinstance(v, Sequence) or not all(o is None or isinstance(o, Sequence) for o in v) or not v
        )

    targets = _per_row(joint_targets, batch, one_array, "joint_targets")
    objs = _per_row(objectives, batch, one_list, "objectives")
    name = (lambda w, i: w) if batch == 1 else (lambda w, i: f"{w} of character {i}")
    return (
        [check_joint_targets(t, num_frames, name("joint_targets", i)) for i, t in enumerate(targets)],
        [check_objectives(o, name("objectives", i), num_frames) for i, o in enumerate(objs)],
    )
