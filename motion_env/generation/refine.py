"""Test-time refinement: joint targets and objectives met by the generated body (TLControl / MaskControl).

One clip (one character) at a time, after its tokens are sampled (:func:`refine_clip`):

1. **root**: the root path is bent so the pelvis passes its targets and the other targeted joints
   line up horizontally, then around :class:`~motion_env.objectives.KeepOut` cylinders and inside
   :class:`~motion_env.objectives.StayInside` polygons (:mod:`motion_env.generation.closed_form`);
2. **optimise** (:func:`optimise_body`): gradient steps on what the generator produced, with the
   path held fixed, through the VQ-VAE decoder and a differentiable copy of the recompose
   (:mod:`motion_env.generation.torch_body`). ``RefineConfig.space`` picks the variables:

   - ``"latent"`` (TLControl): the decoder's input latents, one per token, starting at the
     sampled codes and pulled back towards them;
   - ``"logits"`` (MaskControl): per-token logits over the codebook, starting at the body GPT's
     own (caption- and path-conditioned) logits with the sampled token on top; the decoder reads
     the expectation of the codebook under their softmax, and a KL term to the GPT's distribution
     keeps the body one the caption makes likely;

   the cost: squared distance of the targeted joints from their targets (the pelvis and the head
   excepted: the finish meets them alone), the objectives, foot contacts kept still, each joint's
   acceleration kept as sampled, and the prior term; without leg targets or objectives to
   optimise, the legs' features and the foot contacts are held as sampled (LEG_CHANNELS);
3. **finish**: the optimised features are composed on the path exactly as without targets, the
   feet are pinned (:class:`~motion_env.generation.feet.FootPinner`), and closed-form IK on the
   limb chains (:func:`~motion_env.generation.closed_form.solve_limbs`) puts each targeted joint on its
   target; KeepOut and StayInside are checked and the detour widened if a joint still crosses.

What the finish could not meet (a target out of the body's reach, two targets further apart than
the body allows, an objective that still fails) comes back in a report and as a UserWarning.
The choice between the two spaces (and the defaults below) was made by measurement: see
``docs/metrics.md`` ("Joint control") and the model card.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Protocol

import numpy as np
import torch
from scipy.ndimage import gaussian_filter1d

from motion_env.generation.closed_form import MISS_TOLERANCE, describe_misses, solve_limbs, target_errors
from motion_env.generation.recompose import align_heading_to_travel
from motion_env.generation.root_bending import bend_root, detour
from motion_env.generation.torch_body import frame_yaw, local_pose_torch, place_on_path_torch
from motion_env.models.normalizer import Normalizer
from motion_env.models.vqvae import VQVAE
from motion_env.motion.kinematics import pelvis_shape
from motion_env.motion.skeleton import FOOT_CONTACT, FOOT_JOINTS, LOCAL_VEL, RIC, ROT6D
from motion_env.motion.validation import CheckedConfig, NonNegativeFloat, PositiveInt
from motion_env.objectives import HeightLimit, KeepOut, StayInside

__all__ = [
    "SPACES",
    "RefineConfig",
    "Refined",
    "optimise_body",
    "refine_clip",
]

SPACES = ("latent", "logits", "none")
LEG_JOINTS = (1, 2, 4, 5, 7, 8, 10, 11)  # hips, knees, ankles, toes
FINISHED = (0, 15)  # pelvis, head: targets the closed-form finish meets alone
LEG_CHANNELS = np.array(
    [
        c
        for j in LEG_JOINTS
        for c in (
            *range(RIC.start + 3 * (j - 1), RIC.start + 3 * j),
            *range(ROT6D.start + 6 * (j - 1), ROT6D.start + 6 * j),
            *range(LOCAL_VEL.start + 3 * j, LOCAL_VEL.start + 3 * j + 3),
        )
    ]
    + list(range(FOOT_CONTACT.start, FOOT_CONTACT.stop))
)
"""The features of the legs (positions, rotations, velocities) and the foot contacts."""
TARGET_SCALE = 0.05
"""Metres: a target this far off costs 1 (the other terms are weighed against it)."""
VELOCITY_SCALE = 0.01
"""Metres per frame: a joint whose frame-to-frame step changes by this much costs 1."""
ACCEL_SCALE = 0.005
"""Metres per frame squared (2 m/s^2): a joint's acceleration changed by this much costs 1."""


class Pipeline(Protocol):
    """What this stage reads of the :class:`~motion_env.generation.pipeline.Pipeline` that runs it."""

    vqvae: VQVAE
    normalizer: Normalizer
    device: torch.device

    def compose(
        self, features: np.ndarray, root_path: np.ndarray, num_frames: int
    ) -> tuple[np.ndarray, np.ndarray]: ...

    def place_clip(
        self, features: np.ndarray, root_path: np.ndarray, num_frames: int
    ) -> tuple[np.ndarray, np.ndarray]: ...


@dataclass(frozen=True)
class RefineConfig(CheckedConfig):
    """Settings of the test-time refinement.

    Attributes:
        space: what the optimiser changes: "latent" (the decoder's latents, TLControl), "logits"
            (token logits through the codebook expectation, MaskControl) or "none" (the
            closed-form stages alone).
        steps: gradient steps at most (it stops early when every target is within `tolerance`).
        lr: Adam's step size (latents: in units of the codebook's RMS; logits: in nats).
        prior_weight: weight of the prior term (latent: squared distance from the sampled
            codes over the codebook's mean square; logits: KL to the GPT's distribution).
        contact_weight: weight of keeping planted feet (the decoder's contacts) from sliding.
        smooth_weight: weight of keeping each joint's frame-to-frame motion as sampled (a change
            of VELOCITY_SCALE per frame costs as much as a target TARGET_SCALE off): the
            optimiser may move the body, not make it jitter.
        accel_weight: weight of keeping each joint's acceleration (second difference) as sampled
            (a change of ACCEL_SCALE per frame squared costs as much as a target TARGET_SCALE
            off). Measured on 48 controlled clips of val takes: weight 1 took the optimiser's
            own share of the largest acceleration (the optimised clip's over the unoptimised
            one's) from 1.28x to 1.14x at the 90th percentile, at most 4.6x to 3.0x (weight 10:
            1.09x, 1.30x, but then the closed-form finish has more to do: the whole clip's p90
            rose from 1.81x to 1.91x), the mean target error from 0.26 to 0.23 cm.
        objective_weight: weight of the objectives' costs.
        tolerance: metres; the optimiser stops once every target is this close (the closed-form
            finish does the rest).
        spread: frames; the optimiser's change to the decoded features is spread in time by a
            Gaussian of this width (0: as optimised). Each token's latent moves on its own, so
            unspread the change can jump at token boundaries. Measured on 24 controlled clips of
            held-out takes (``scripts/measure_refine_smoothness.py``), 4 frames took the largest
            acceleration of a controlled clip, against the same seed without targets, from at
            most 4.3x to 2.5x (90th percentile 2.5x -> 1.75x), the mean target error from 0.17
            to 0.25 cm.
        pop_guard: the optimiser's change is kept whole only if the placed body's (composed,
            feet pinned, physics) largest joint acceleration stays within this many times the
            sampled clip's on the same path; else a half, a quarter or none of it
            (:func:`_without_new_pops`; 0: off). The optimiser's differentiable body does not
            re-solve the arms as the composition does, nor pin the feet, and a change it saw as
            smooth could compose to an elbow flipping sides or a foot jumping to a new pin.
            Measured on 48 controlled val clips: the largest ratio 5.49 -> 3.13, within reach
            1.20 -> 1.09, the mean target error 0.26 cm either way (on the composed body; on the
            placed one, 96 val clips within reach: largest 3.15 -> 1.54).
    """

    space: Annotated[str, SPACES] = "latent"
    steps: PositiveInt = 24
    lr: NonNegativeFloat = 0.15
    prior_weight: NonNegativeFloat = 0.02
    contact_weight: NonNegativeFloat = 3.0
    smooth_weight: NonNegativeFloat = 0.0
    accel_weight: NonNegativeFloat = 1.0
    objective_weight: NonNegativeFloat = 4.0
    tolerance: NonNegativeFloat = 0.03
    spread: NonNegativeFloat = 4.0
    pop_guard: NonNegativeFloat = 1.2


@dataclass
class Refined:
    """One refined clip: the joints, and how well the targets and objectives were met.

    Attributes:
        joints: (T, 22, 3) float32 world joints.
        errors: (N,) metres, each target's distance from its joint; `where`: (N, 2) frame, joint.
        violations: per objective, the largest violation (m; built-in objectives) or the final
            cost (a callable).
        steps: gradient steps taken.
        message: what was missed ('' when nothing).
    """

    joints: np.ndarray
    errors: np.ndarray
    where: np.ndarray
    violations: list[float]
    steps: int
    message: str

    def summary(self) -> str:
        """One line for ``Motion.meta["control"]``: the targets' errors, the objectives, the steps."""
        parts = []
        if len(self.errors):
            parts.append(
                f"{len(self.errors)} joint targets: mean error {self.errors.mean() * 100:.2f} cm, "
                f"largest {self.errors.max() * 100:.2f} cm"
            )
        if self.violations:
            parts.append("objectives: " + ", ".join(f"{v:.4g}" for v in self.violations))
        parts.append(f"{self.steps} refinement steps")
        return "; ".join(parts)


class _Variables:
    """What the optimiser changes: the decoder's latents ("latent") or token logits ("logits"),
    the latent they give, and the prior term that keeps them near what was sampled."""

    def __init__(
        self,
        config: RefineConfig,
        codebook: torch.Tensor,
        codes: torch.Tensor,
        gpt_logits: torch.Tensor | None,
    ) -> None:
        self.space = config.space
        self.codebook = codebook
        if self.space == "logits":
            if gpt_logits is None:
                raise ValueError("RefineConfig.space='logits' needs the GPT's logits")
            self.prior = torch.log_softmax(gpt_logits.to(codebook.device).float(), dim=-1)
            # The sampled token on top (95 % of the mass), so the clip starts as it was sampled.
            others = torch.logsumexp(self.prior.scatter(1, codes[:, None], -torch.inf), dim=1)
            lift = (np.log(0.95 / 0.05) + others - self.prior.gather(1, codes[:, None])[:, 0]).clamp_min(0.0)
            self.start = self.prior.clone()
            self.start[torch.arange(len(codes)), codes] += lift
            self.scale = 1.0
        else:
            self.start = codebook[codes]
            self.scale = float(codebook.pow(2).mean().sqrt())
        self.param = self.start.clone().requires_grad_(True)

    def latent(self) -> torch.Tensor:
        """(N, code_dim) the decoder's input."""
        if self.space == "logits":
            return torch.softmax(self.param, dim=-1) @ self.codebook
        return self.param

    def prior_cost(self) -> torch.Tensor:
        if self.space == "logits":
            q = torch.softmax(self.param, dim=-1)
            return (q * (torch.log_softmax(self.param, dim=-1) - self.prior)).sum(-1).mean()
        return (self.param - self.start).pow(2).sum(-1).mean() / self.codebook.pow(2).sum(-1).mean()


def optimise_body(
    pipe: Pipeline,
    codes: torch.Tensor,
    gpt_logits: torch.Tensor | None,
    features: np.ndarray,
    path: np.ndarray,
    targets: np.ndarray,
    objectives: list,
    config: RefineConfig,
    keep: np.ndarray | None = None,
    pelvis: float | None = None,
) -> tuple[np.ndarray, int]:
    """Gradient steps on one clip's latents or token logits (see the module docstring).

    Args:
        pipe: the :class:`~motion_env.generation.pipeline.Pipeline`.
        codes: (N,) the sampled tokens; gpt_logits: (N, V) their logits (needed for "logits").
        features: (N * rate, 263) the decoded features of `codes`.
        path: (N * rate, 3) the root path, heading already turned to the travel.
        targets: (T, 22, 3), T <= N * rate, NaN = free.
        objectives: costs of the world joints (T, 22, 3) -> 0-d tensor.
        keep: feature channels held as in `features` (the optimiser sees them fixed, and they
            come back unchanged), or None.
        pelvis: the pelvis shape the composition holds (m; see
            :meth:`~motion_env.generation.pipeline.Pipeline.compose`), or None for each body's own.

    Returns:
        (N * rate, 263) float32 features of the optimised clip, and the steps taken.
    """
    vq, dev, t_len = pipe.vqvae, pipe.device, targets.shape[0]
    yaw = torch.as_tensor(frame_yaw(features), device=dev)
    path_t = torch.as_tensor(path, dtype=torch.float32, device=dev)
    known = torch.as_tensor(~np.isnan(targets[..., 0]), device=dev)
    goal = torch.as_tensor(np.nan_to_num(targets), dtype=torch.float32, device=dev)
    flags = features[:t_len, FOOT_CONTACT] > 0.5
    still = torch.as_tensor(flags[1:] & flags[:-1], device=dev)  # (T-1, 4) planted on both frames
    var = _Variables(config, vq.quantizer.codebook.detach(), codes.to(dev), gpt_logits)
    held = torch.zeros(features.shape[1], dtype=torch.bool, device=dev)
    if keep is not None:
        held[torch.as_tensor(keep, device=dev)] = True
    sampled = torch.as_tensor(features, dtype=torch.float32, device=dev)

    def decoded() -> torch.Tensor:  # (n, 263) the features the variables give, `keep` held
        feats = pipe.normalizer.denormalize_torch(vq.decode_latent(var.latent()[None])[0])
        return torch.where(held, sampled[: len(feats)], feats)

    def world() -> torch.Tensor:  # (T, 22, 3) the body the variables give, on the fixed path
        return place_on_path_torch(local_pose_torch(decoded(), yaw), path_t, pelvis)[:t_len]

    opt = torch.optim.Adam([var.param], lr=config.lr * var.scale)
    steps = 0
    with torch.no_grad():
        first = world()
        step0 = first[1:] - first[:-1]
        acc0 = first[2:] - 2 * first[1:-1] + first[:-2]
    with torch.enable_grad():
        for step in range(1, config.steps + 1):
            steps = step
            joints = world()
            dist2 = (joints - goal).pow(2).sum(-1)[known]
            if len(dist2) and not objectives and float(dist2.detach().max().sqrt()) < config.tolerance:
                break
            cost = _cost(joints, dist2, step0, still, objectives, config)
            if config.accel_weight > 0 and len(joints) > 2:  # accelerations kept as sampled
                acc = joints[2:] - 2 * joints[1:-1] + joints[:-2] - acc0
                cost = cost + config.accel_weight * acc.pow(2).sum(-1).mean() / ACCEL_SCALE**2
            cost = cost + config.prior_weight * var.prior_cost()
            opt.zero_grad()
            cost.backward()
            opt.step()
    with torch.no_grad():
        out = decoded().cpu().numpy()
    return out.astype(np.float32), steps


def _cost(
    world: torch.Tensor,
    dist2: torch.Tensor,
    step0: torch.Tensor,
    still: torch.Tensor,
    objectives: list,
    config: RefineConfig,
) -> torch.Tensor:
    """The refinement's cost without the prior: targets, objectives, planted feet, smoothness."""
    cost = dist2.mean() / TARGET_SCALE**2 if len(dist2) else world.new_zeros(())
    for objective in objectives:
        cost = cost + config.objective_weight * objective(world) / TARGET_SCALE**2
    feet = world[:, list(FOOT_JOINTS)]
    slide = (feet[1:] - feet[:-1])[..., [0, 2]].pow(2).sum(-1)[still]
    if len(slide):  # planted feet do not slide
        cost = cost + config.contact_weight * slide.mean() / TARGET_SCALE**2
    if config.smooth_weight > 0 and len(world) > 1:
        jitter = ((world[1:] - world[:-1]) - step0).pow(2).sum(-1)
        cost = cost + config.smooth_weight * jitter.mean() / VELOCITY_SCALE**2
    return cost


def _smoothed_change(before: np.ndarray, after: np.ndarray, sigma: float) -> np.ndarray:
    """`before` plus the optimiser's change to it, spread in time by a Gaussian of `sigma` frames.

    The optimiser moves each token's latent on its own, so its change to the features can jump
    at token boundaries: a pop the sampled clip did not have. Spread, the change keeps its size
    over the frames around it (the closed-form finish meets the targets exactly either way).
    """
    if sigma <= 0:
        return after
    change = gaussian_filter1d(after.astype(np.float64) - before, sigma, axis=0, mode="nearest")
    return (before + change).astype(np.float32)


def _largest_acceleration(joints: np.ndarray) -> float:
    """The largest |second difference| of any joint (m per frame squared): (T, 22, 3) -> float."""
    return float(np.linalg.norm(np.diff(joints, 2, axis=0), axis=-1).max(initial=0.0))


def _without_new_pops(
    pipe: Pipeline, sampled: np.ndarray, optimised: np.ndarray, path: np.ndarray, n: int, guard: float
) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """`optimised` features, or less of their change from `sampled` (a half, a quarter, none),
    whichever first places (composed, feet pinned, physics: :meth:`Pipeline.place_clip`) a body
    whose largest joint acceleration is at most `guard` times the sampled features' on the same
    path (0: `optimised` as it is), and that placement (None with the guard off), which the
    finish starts from.

    The optimiser sees the body through a differentiable copy of the composition
    (:mod:`~motion_env.generation.torch_body`) that does not re-solve the arms as
    :func:`~motion_env.generation.recompose.on_bone_lengths` does: latents it moved to bring a
    wrist closer could shorten a decoded arm, whose elbow the composition then swings from one
    side to the other in a frame (200 m/s^2 where the copy it optimised showed 30). Nor does it
    pin the feet: changed legs' contacts are pinned anew, and a foot could jump to its new pin
    (val, all six joints at 2 keyframes of a CMU take: a toe at 63 m/s^2, 3.2x the clip without
    targets, where the composed body showed none). The closed-form finish meets the targets either
    way; the optimiser only brings the body closer.
    """
    if guard <= 0:
        return optimised, None
    base = pipe.place_clip(sampled, path, n)
    limit = guard * _largest_acceleration(base[1])
    change = optimised - sampled
    for share in (1.0, 0.5, 0.25):
        candidate = optimised if share == 1.0 else (sampled + share * change).astype(np.float32)
        placed = pipe.place_clip(candidate, path, n)
        if _largest_acceleration(placed[1]) <= limit:
            return candidate, placed
    return sampled, base


def _violations(objectives: list, joints: np.ndarray) -> list[float]:
    out = []
    for obj in objectives:
        if isinstance(obj, KeepOut | StayInside | HeightLimit):
            out.append(float(obj.violation(joints).max(initial=0.0)))
        else:
            with torch.no_grad():
                out.append(float(obj(torch.as_tensor(joints, dtype=torch.float32))))
    return out


def refine_clip(
    pipe: Pipeline,
    config: RefineConfig,
    features: np.ndarray,
    codes: torch.Tensor,
    gpt_logits: torch.Tensor | None,
    root_path: np.ndarray,
    route: np.ndarray | None,
    targets: np.ndarray,
    objectives: list,
) -> Refined:
    """One clip through the refinement (module docstring).

    Args:
        pipe: the :class:`~motion_env.generation.pipeline.Pipeline`.
        features: (n, 263) decoded features of the sampled `codes` (N,); gpt_logits (N, V) or None.
        root_path: (>= n, 3) the root path the tokens were sampled on (snapped, with look-ahead).
        route: the planned route it was snapped through (its anchors keep their frames), or None.
        targets: (T, 22, 3) checked joint targets (NaN = free), T <= n.
        objectives: checked objectives.
    """
    n = features.shape[0]
    t_len = targets.shape[0]
    limits = [o for o in objectives if isinstance(o, HeightLimit)]
    areas = [o for o in objectives if isinstance(o, KeepOut | StayInside)]
    joints0, _ = pipe.compose(features, root_path, n)
    # The optimiser's body holds the sampled clip's pelvis shape, as the composition will (its
    # own, within millimetres): where it did not, the composition's shift moved targeted wrists
    # after the optimiser had placed them (left_wrist / 1 frame of `eval control`: 0.97 -> 1.49 cm).
    pelvis = float(np.median(pelvis_shape(joints0)))
    path = bend_root(root_path, joints0, targets, route)
    if areas:
        joints1, _ = pipe.compose(features, path, n)
        path = detour(path, joints1, areas)
    steps = 0
    placed = None  # the body placed on `path`, when the pop guard has made it
    # HeightLimit is left to the closed-form crouch (the feet stay planted): given to the
    # optimiser, it lowers the whole body, feet through the floor included.
    costs = [o for o in objectives if not isinstance(o, HeightLimit)]
    # The pelvis and the head are met by the finish alone (the bent path, the pelvis height, a
    # lean): the optimiser reaches for the limbs. Given the pelvis and head too, it ran all its
    # steps on what the finish does exactly anyway, and moved the arms along (measured on 48 val
    # clips: the same smoothness and error, 15 % less time).
    reach = targets.copy()
    reach[:, list(FINISHED)] = np.nan
    if config.space != "none" and (not np.isnan(reach).all() or costs):
        aligned = align_heading_to_travel(path)[:n]
        # Without leg targets or costs the legs stay as sampled: moved only as a side effect of
        # the upper body's change, they were pinned anew and their knees popped (measured: up to
        # 3.8x the clip's largest joint acceleration without targets, against 1.5x held).
        legs = ~np.isnan(targets[:, list(LEG_JOINTS), 0]).all()
        keep = None if legs or costs else LEG_CHANNELS
        optimised, steps = optimise_body(
            pipe, codes, gpt_logits, features, aligned, reach, costs, config, keep, pelvis
        )
        smoothed = _smoothed_change(features, optimised, config.spread)
        features, placed = _without_new_pops(pipe, features, smoothed, path, n, config.pop_guard)
    contacts = features[:t_len, FOOT_CONTACT] > 0.5
    planted = contacts.reshape(t_len, 2, 2).any(axis=2)
    margin = 0.0
    for _ in range(4):
        joints, pinned = pipe.place_clip(features, path, n) if placed is None else placed
        placed = None  # a detour changes the path: placed again
        final = solve_limbs(pinned[:t_len], targets, limits, planted)
        worst = max([float(o.violation(final).max(initial=0.0)) for o in areas], default=0.0)
        if worst <= 1e-4:
            break
        margin += worst + 0.02
        path = detour(path, joints, areas, margin=0.02 + margin)
    errors, where = target_errors(final, targets)
    violations = _violations(objectives, final)
    message = describe_misses(errors, where, MISS_TOLERANCE)
    failed = [
        f"{type(o).__name__} still violated by {v * 100:.1f} cm"
        for o, v in zip(objectives, violations, strict=True)
        if isinstance(o, KeepOut | StayInside | HeightLimit) and v > 0.005
    ]
    if failed:
        message = "; ".join([m for m in [message, *failed] if m])
    return Refined(final, errors, where, violations, steps, message)
