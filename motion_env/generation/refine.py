"""Test-time refinement: joint targets and objectives met by the generated body (TLControl / MaskControl).

One clip (one character) at a time, after its tokens are sampled (:func:`refine_clip`):

1. **root**: the root path is bent so the pelvis passes its targets and the other targeted joints
   line up horizontally, then around :class:`~motion_env.objectives.KeepOut` cylinders and inside
   :class:`~motion_env.objectives.StayInside` polygons (:mod:`motion_env.generation.targets`);
2. **optimise** (:func:`optimise_body`): gradient steps on what the generator produced, with the
   path held fixed, through the VQ-VAE decoder and a differentiable copy of the recompose
   (:mod:`motion_env.generation.torch_body`). ``RefineConfig.space`` picks the variables:

   - ``"latent"`` (TLControl): the decoder's input latents, one per token, starting at the
     sampled codes and pulled back towards them;
   - ``"logits"`` (MaskControl): per-token logits over the codebook, starting at the body GPT's
     own (caption- and path-conditioned) logits with the sampled token on top; the decoder reads
     the expectation of the codebook under their softmax, and a KL term to the GPT's distribution
     keeps the body one the caption makes likely;

   the cost: squared distance of the targeted joints from their targets, the objectives,
   foot contacts kept still, and the prior term;
3. **finish**: the optimised features are composed on the path exactly as without targets, the
   feet are pinned (:class:`~motion_env.generation.feet.FootPinner`), and closed-form IK on the
   limb chains (:func:`~motion_env.generation.targets.finish`) puts each targeted joint on its
   target; KeepOut and StayInside are checked and the detour widened if a joint still crosses.

What the finish could not meet (a target out of the body's reach, two targets further apart than
the body allows, an objective that still fails) comes back in a report and as a UserWarning.
The choice between the two spaces (and the defaults below) was made by measurement: see
``docs/metrics.md`` ("Joint control") and the model card.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from motion_env.generation.feet import FootPinner
from motion_env.generation.recompose import align_heading_to_travel
from motion_env.generation.targets import (
    MISS_TOLERANCE,
    bend_root,
    describe_misses,
    detour,
    finish,
    target_errors,
)
from motion_env.generation.torch_body import frame_yaw, local_pose_torch, place_on_path_torch
from motion_env.motion.checks import check_positive_ints
from motion_env.motion.skeleton import FOOT_CONTACT, FOOT_JOINTS
from motion_env.objectives import HeightLimit, KeepOut, StayInside

__all__ = [
    "SPACES",
    "RefineConfig",
    "Refined",
    "check_objective_values",
    "controlled_clips",
    "optimise_body",
    "refine_clip",
]

SPACES = ("latent", "logits", "none")
TARGET_SCALE = 0.05
"""Metres: a target this far off costs 1 (the other terms are weighed against it)."""
VELOCITY_SCALE = 0.01
"""Metres per frame: a joint whose frame-to-frame step changes by this much costs 1."""


@dataclass(frozen=True)
class RefineConfig:
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
        objective_weight: weight of the objectives' costs.
        tolerance: metres; the optimiser stops once every target is this close (the closed-form
            finish does the rest).
    """

    space: str = "latent"
    steps: int = 24
    lr: float = 0.15
    prior_weight: float = 0.02
    contact_weight: float = 3.0
    smooth_weight: float = 0.0
    objective_weight: float = 4.0
    tolerance: float = 0.03

    def __post_init__(self) -> None:
        if self.space not in SPACES:
            raise ValueError(f"RefineConfig.space must be one of {SPACES}, got {self.space!r}")
        check_positive_ints(self, "steps")
        for name in (
            "lr",
            "prior_weight",
            "contact_weight",
            "smooth_weight",
            "objective_weight",
            "tolerance",
        ):
            if not getattr(self, name) >= 0:
                raise ValueError(f"RefineConfig.{name} must be >= 0, got {getattr(self, name)!r}")


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


def optimise_body(
    pipe: object,
    codes: torch.Tensor,
    gpt_logits: torch.Tensor | None,
    features: np.ndarray,
    path: np.ndarray,
    targets: np.ndarray,
    objectives: list,
    config: RefineConfig,
) -> tuple[np.ndarray, int]:
    """Gradient steps on one clip's latents or token logits (see the module docstring).

    Args:
        pipe: the :class:`~motion_env.generation.pipeline.Pipeline`.
        codes: (N,) the sampled tokens; gpt_logits: (N, V) their logits (needed for "logits").
        features: (N * rate, 263) the decoded features of `codes`.
        path: (N * rate, 3) the root path, heading already turned to the travel.
        targets: (T, 22, 3), T <= N * rate, NaN = free.
        objectives: costs of the world joints (T, 22, 3) -> 0-d tensor.

    Returns:
        (N * rate, 263) float32 features of the optimised clip, and the steps taken.
    """
    vq = pipe.vqvae
    dev = pipe.device
    t_len = targets.shape[0]
    codebook = vq.quantizer.codebook.detach()
    mean = torch.as_tensor(pipe.normalizer.mean, device=dev)
    std = torch.as_tensor(pipe.normalizer.std, device=dev)
    yaw = torch.as_tensor(frame_yaw(features), device=dev)
    path_t = torch.as_tensor(path, dtype=torch.float32, device=dev)
    known = torch.as_tensor(~np.isnan(targets[..., 0]), device=dev)
    goal = torch.as_tensor(np.nan_to_num(targets), dtype=torch.float32, device=dev)
    flags = features[:t_len, FOOT_CONTACT] > 0.5
    still = torch.as_tensor(flags[1:] & flags[:-1], device=dev)  # (T-1, 4) planted on both frames
    codes = codes.to(dev)

    if config.space == "logits":
        if gpt_logits is None:
            raise ValueError("RefineConfig.space='logits' needs the GPT's logits")
        prior = torch.log_softmax(gpt_logits.to(dev).float(), dim=-1)
        # The sampled token on top (95 % of the mass), so the clip starts as it was sampled.
        others = torch.logsumexp(prior.scatter(1, codes[:, None], -torch.inf), dim=1)
        lift = (np.log(0.95 / 0.05) + others - prior.gather(1, codes[:, None])[:, 0]).clamp_min(0.0)
        start = prior.clone()
        start[torch.arange(len(codes)), codes] += lift
        param = start.clone().requires_grad_(True)
        scale = 1.0
    else:
        start = codebook[codes]
        param = start.clone().requires_grad_(True)
        scale = float(codebook.pow(2).mean().sqrt())

    def latent() -> torch.Tensor:
        if config.space == "logits":
            return torch.softmax(param, dim=-1) @ codebook
        return param

    def prior_cost() -> torch.Tensor:
        if config.space == "logits":
            q = torch.softmax(param, dim=-1)
            return (q * (torch.log_softmax(param, dim=-1) - prior)).sum(-1).mean()
        return (param - start).pow(2).sum(-1).mean() / codebook.pow(2).sum(-1).mean()

    opt = torch.optim.Adam([param], lr=config.lr * scale)
    steps = 0
    with torch.no_grad():
        first = place_on_path_torch(
            local_pose_torch(vq._decode_latent(latent()[None])[0] * std + mean, yaw), path_t
        )
        first = first[:t_len]
        step0 = first[1:] - first[:-1]
    with torch.enable_grad():
        for step in range(1, config.steps + 1):
            steps = step
            feats = vq._decode_latent(latent()[None])[0] * std + mean
            world = place_on_path_torch(local_pose_torch(feats, yaw), path_t)[:t_len]
            dist2 = (world - goal).pow(2).sum(-1)[known]
            cost = dist2.mean() / TARGET_SCALE**2 if len(dist2) else world.new_zeros(())
            if len(dist2) and not objectives and float(dist2.detach().max().sqrt()) < config.tolerance:
                break
            for objective in objectives:
                cost = cost + config.objective_weight * objective(world) / TARGET_SCALE**2
            feet = world[:, list(FOOT_JOINTS)]
            slide = (feet[1:] - feet[:-1])[..., [0, 2]].pow(2).sum(-1)[still]
            if len(slide):  # planted feet do not slide
                cost = cost + config.contact_weight * slide.mean() / TARGET_SCALE**2
            if config.smooth_weight > 0 and len(world) > 1:
                jitter = ((world[1:] - world[:-1]) - step0).pow(2).sum(-1)
                cost = cost + config.smooth_weight * jitter.mean() / VELOCITY_SCALE**2
            cost = cost + config.prior_weight * prior_cost()
            opt.zero_grad()
            cost.backward()
            opt.step()
    with torch.no_grad():
        out = pipe.normalizer.denormalize(vq._decode_latent(latent()[None])[0])
    return out.astype(np.float32), steps


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
    pipe: object,
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
    path = bend_root(root_path, joints0, targets, route)
    if areas:
        joints1, _ = pipe.compose(features, path, n)
        path = detour(path, joints1, areas)
    steps = 0
    # HeightLimit is left to the closed-form crouch (the feet stay planted): given to the
    # optimiser, it lowers the whole body, feet through the floor included.
    costs = [o for o in objectives if not isinstance(o, HeightLimit)]
    if config.space != "none" and (not np.isnan(targets).all() or costs):
        aligned = align_heading_to_travel(path)[:n]
        features, steps = optimise_body(pipe, codes, gpt_logits, features, aligned, targets, costs, config)
    contacts = features[:t_len, FOOT_CONTACT] > 0.5
    planted = contacts.reshape(t_len, 2, 2).any(axis=2)
    margin = 0.0
    for _ in range(4):
        joints, _ = pipe.compose(features, path, n)
        pinned = FootPinner(1).apply(0, joints, features[:, FOOT_CONTACT])[:t_len]
        final = finish(pinned, targets, limits, planted)
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


def check_objective_values(objectives: tuple, num_frames: int, what: str = "objectives") -> None:
    """Evaluate each callable objective once on a still clip: it must return a finite 0-d (or
    one-element) torch tensor that depends on the joints. ValueError / TypeError naming it otherwise."""
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


def controlled_clips(
    pipe: object, req: object, config: RefineConfig
) -> list[tuple[np.ndarray, Refined | None]]:
    """Whole clips of a request with joint targets or objectives (rows without them are generated
    exactly as without the refinement): per row, the (T, 22, 3) joints and the report (or None)."""
    import math
    from dataclasses import replace

    from motion_env.generation.recompose import snap_route
    from motion_env.generation.route import plan_route
    from motion_env.generation.targets import implied_route

    t_len = req.num_frames
    for i, objs in enumerate(req.objectives):
        check_objective_values(
            objs, t_len, "objectives" if len(req.texts) == 1 else f"objectives of character {i}"
        )
    rate = pipe.rate
    n_tok = math.ceil(t_len / rate)
    emb = pipe.encode_text(req.texts)
    controlled = [t is not None or bool(o) for t, o in zip(req.targets, req.objectives, strict=True)]
    # The path controller walks to where the targets are when the caller gave no route.
    ctrl_routes = [
        implied_route(t) if r is None and t is not None else r
        for r, t in zip(req.routes, req.targets, strict=True)
    ]
    raw = pipe.clip_paths(emb, replace(req, routes=ctrl_routes), snap=False)
    routes = [plan_route(r, s[:2]) for r, s in zip(req.routes, req.starts, strict=True)]
    paths = np.stack([snap_route(p, r) for p, r in zip(raw, routes, strict=True)])
    logits: list[torch.Tensor] = []
    want_logits = config.space == "logits" and any(controlled)
    tokens = pipe.sample_tokens(emb, paths, n_tok, req.seed, logits if want_logits else None)
    body = pipe.decode(tokens)
    out: list[tuple[np.ndarray, Refined | None]] = []
    for i in range(len(req.texts)):
        if not controlled[i]:
            joints, _ = pipe.compose(body[i], paths[i], n_tok * rate)
            out.append((FootPinner(1).apply(0, joints, body[i][:, FOOT_CONTACT])[:t_len], None))
            continue
        targets = (
            req.targets[i] if req.targets[i] is not None else np.full((t_len, 22, 3), np.nan, np.float32)
        )
        row_logits = torch.stack([step[i] for step in logits]) if want_logits else None
        refined = refine_clip(
            pipe,
            config,
            body[i],
            tokens[i],
            row_logits,
            paths[i],
            routes[i],
            targets,
            list(req.objectives[i]),
        )
        out.append((refined.joints, refined))
    return out
