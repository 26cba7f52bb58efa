"""`motion_env/Waypoints-v0`: walk a generated human along a route of waypoints."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from motion_env.envs.arena import circles
from motion_env.envs.config import EnvConfig, check_actions, validate_start
from motion_env.envs.core import build_characters
from motion_env.envs.episodes import sample_route, sample_start
from motion_env.envs.spaces import action_space, caption_size, observation_space
from motion_env.generation.request import check_text
from motion_env.joint_targets import JointTargets
from motion_env.motion.skeleton import FPS
from motion_env.motion.trajectory import validate_waypoints

RENDER_STYLES = ("stick", "humanoid")


class WaypointsEnv(gym.Env[dict[str, np.ndarray], np.ndarray]):
    """A generated human walks a route of waypoints; the agent says where to go next.

    ## Description
    Every step the streaming motion generator (:class:`motion_env.MotionGenerator`) emits the next
    body pose (or ``frames_per_step`` poses, 20 per second) of a character that moves as the caption
    says ("a person jogs", ...) towards the point it was told to go to. Poses stay continuous when
    the caption (:meth:`set_text`) or the target (an action) changes mid-episode.

    The *route* is the list of waypoints given at reset (``options["waypoints"]``, or a random one).
    The *route target* R[k] is the next waypoint of the route the character has not passed; it is
    what the observation's ``"target"`` and the reward refer to. R[k] is passed when the pelvis comes
    within ``arrive_radius`` of it (or, while the character follows the route, when R[k] is timed
    and its frame has been reached, as the generator's path controller does). The last waypoint is
    never passed: reaching it is the end of the route.

    Between steps, :meth:`set_text` changes the caption, :meth:`set_route` replaces the route (the
    character follows the new one from its first waypoint), :meth:`set_joint_targets` and
    :meth:`set_objectives` ask for joint positions and height limits at later frames (a target set at
    least 10 frames ahead is met exactly; frames already emitted never change), and
    :meth:`control_summary` says how well the targets were met so far.

    ## Action Space
    | ``action_mode`` | space | an action is |
    |---|---|---|
    | ``"normalized"`` (default, for learning) | ``Box(-1, 1, (3,), float32)`` | (lateral, forward, follow) |
    | ``"normalized"``, ``follow_action=False`` | ``Box(-1, 1, (2,), float32)`` | (lateral, forward) |
    | ``"absolute"`` | ``Box(-arena_size, arena_size, (2,), float32)`` | (x, z) in world metres |
    | ``"relative"`` | ``Box(-3 arena_size, 3 arena_size, (2,), float32)`` | (dx, dz) metres, heading frame |

    In the normalized mode the first two numbers times ``reach`` metres (3 m) are the point, in the
    character's heading frame from its pelvis (lateral + = its left), that it walks to next; a
    positive ``follow`` instead means "follow the route" (it commands the route target, below), so a
    learned policy can choose the exact route. What a commanded point does to the route:

    - a point within ``snap_radius`` (5 cm) of a route waypoint R[j] with j >= k means "follow the
      route from R[j]": the character walks the rest of the route, R[j:], with its timing; k jumps to
      j (skipped waypoints earn no bonus). **To keep following the route, issue the route target**:
      ``follow > 0`` (normalized mode), ``info["route_target"]`` (absolute) or ``obs["target"]``
      (relative). A fresh episode starts out following the route from R[0]; re-issuing the current
      command changes nothing.
    - any other point is a detour: the character walks to that point and stays there. The route is
      kept (its waypoints are still passed if the character happens to come near them) and is
      resumed by issuing one of its waypoints again.
    - bad actions: finite values outside the Box are clipped into it (``info["action_clipped"]``);
      NaN or infinite values raise a ``ValueError`` before anything changes, so the episode can
      continue with the next finite action (``invalid_action="hold"`` instead keeps the previous
      target and sets ``info["action_invalid"]``); a wrong shape or a dtype that is not real
      numbers always raises.

    ## Observation Space
    A ``Dict`` of float32 Boxes with finite bounds (``FlattenObservation`` turns it into 84 + D
    numbers, D = 64 for the shipped model), all of the last frame emitted, with heading θ from the
    generator's root (θ = 0 faces +Z; facing (sin θ, cos θ)):

    | key | shape | meaning |
    |---|---|---|
    | ``"root"`` | (4,) | pelvis world x, z, cos θ, sin θ |
    | ``"target"`` | (2,) | the route target relative to the pelvis, heading frame (lateral, forward) |
    | ``"route_ahead"`` | (6,) | the next three waypoints after it, the same way |
    | ``"route_state"`` | (3,) | following the route; the target is the last waypoint; waypoints left |
    | ``"velocity"`` | (3,) | pelvis velocity in the heading frame (m/s), turn rate dθ/dt (rad/s) |
    | ``"pose"`` | (66,) | the 22 joints (HumanML3D order) in the heading frame, flattened |
    | ``"caption"`` | (D,) | the caption as the path controller reads it |

    - ``"route_ahead"``: the last waypoint repeated past the end of the route.
    - ``"route_state"``: following the route (1) or on a detour (0); the target is the last
      waypoint (1/0); waypoints left after the target / 3 (at most 1).
    - ``"velocity"``: lateral and forward m/s, then the turn rate.
    - ``"pose"``: x lateral and z forward relative to the pelvis, y the height above the floor.
    - ``"caption"``: the path controller's projection of the sentence embedding: what sets walking
      versus jogging pace.

    ## Rewards
    Summed over the frames of a step, each term in ``info`` as ``reward_*``:

    - ``reward_progress``: ``progress_weight`` x the metres the pelvis got closer to the route target;
    - ``reward_arrival``: ``arrival_bonus`` for every route waypoint passed by arrival (the last one
      included, once);
    - ``reward_collision``: ``-collision_penalty`` per frame with the pelvis inside an obstacle;
    - ``reward_time``: ``-time_penalty`` per second (0.1), so circling a waypoint costs.

    After the episode terminated, further steps (without ``reset``) warn and pay nothing.

    ## Starting State
    The character starts at ``options["start"]`` (x, z, heading), else at the origin facing +Z (or,
    with ``random_start=True``, at a random free spot and heading in the arena), and follows the route
    from R[0]. Missing reset options (``"text"``, ``"waypoints"``, ``"start"``) are drawn from
    ``self.np_random``: the caption from ``text_pool``, a route of 2-4 untimed waypoints (legs of
    1.5-3.5 m, turns up to 90 degrees, clear of obstacles). ``options["waypoints"]`` is (K, 2) or
    (K, 3): x, z in world metres and optionally the frame (20 fps) of each waypoint (NaN: untimed).
    ``reset`` emits the first frame. The same seed and options give the same poses.

    ## Episode End
    ### Termination
    When the pelvis is within ``arrive_radius`` of the last waypoint after the others were passed or
    skipped (``terminate_on_arrival=False`` keeps the episode running).

    ### Truncation
    By the ``TimeLimit`` of the registration: 150 steps of four frames (30 s).

    ## Arguments
    ```python
    gym.make("motion_env/Waypoints-v0", action_mode="absolute", frames_per_step=1, ...)
    ```

    | Parameter | Type | Default | Description |
    |---|---|---|---|
    | ``generator`` | MotionGenerator or None | ``None`` | the generator (None: load ``model_path``) |
    | ``model_path`` | str or None | ``None`` | weights folder to load (None: the shipped model) |
    | ``text_pool`` | Sequence[str] or None | ``None`` | captions a reset without a text draws from |
    | ``action_mode`` | str | ``"normalized"`` | ``"normalized"``, ``"absolute"`` or ``"relative"`` |
    | ``frames_per_step`` | int | ``4`` | frames (1/20 s each) per step |
    | ``arrive_radius`` | float | ``0.5`` | metres from a waypoint that count as reaching it |
    | ``terminate_on_arrival`` | bool | ``True`` | terminate when the last waypoint is reached |
    | ``render_mode`` | str or None | ``None`` | ``"rgb_array"``: :meth:`render` returns a picture |
    | ``obstacles`` | array or Sequence or None | ``None`` | circles ``(x, z, radius)`` and/or polygons |
    | ``arena_size`` | float | ``10.0`` | half-width of the square arena (m) |
    | ``snap_radius`` | float | ``0.05`` | a command this close to a waypoint follows the route |
    | ``progress_weight`` | float | ``1.0`` | weight of ``reward_progress`` (per metre) |
    | ``arrival_bonus`` | float | ``1.0`` | ``reward_arrival`` per waypoint reached |
    | ``collision_penalty`` | float | ``1.0`` | ``reward_collision`` per frame inside an obstacle |
    | ``time_penalty`` | float | ``0.1`` | ``reward_time`` per second |
    | ``reach`` | float | ``3.0`` | metres that a normalized action of 1 reaches |
    | ``follow_action`` | bool | ``True`` | the normalized action's "follow the route" switch |
    | ``invalid_action`` | str | ``"raise"`` | NaN/inf actions: ``"raise"`` or ``"hold"`` |
    | ``random_start`` | bool | ``False`` | start at a random free spot and heading |
    | ``device`` | str | ``"cpu"`` | torch device of the generator that is loaded |
    | ``render_size`` | tuple[int, int] | ``(480, 360)`` | (width, height) of a picture, pixels |
    | ``render_style`` | str | ``"stick"`` | ``"stick"`` or ``"humanoid"`` |
    | ``robot`` | str or None | ``None`` | ``"unitree_g1"``, ``"booster_t1"`` or a humanoid MJCF path |
    | ``lookahead`` | str | ``"auto"`` | ``"head"``, ``"exact"`` or ``"auto"`` (the head when there is one) |

    - ``frames_per_step``: the default 4 is one generator token, so a new target every step costs no
      more than one every token.
    - ``generator``: a :class:`motion_env.MotionGenerator` (None loads the shipped model, or
      ``model_path``, on ``device``).
    - ``text_pool``: None gives six walking and jogging captions.
    - ``action_mode``, ``reach``, ``follow_action``, ``snap_radius``, ``invalid_action``: see
      Action Space; ``arena_size`` also bounds random starts, routes and goals.
    - ``obstacles``: circles ``(x, z, radius)`` and/or polygons ``[(x, z), ...]`` in metres
      (:mod:`motion_env.envs.arena`, shared with the A* planner); circles are drawn; all are
      avoided by random routes and penalised by ``reward_collision`` (the generator itself does
      not see them).
    - ``render_mode="rgb_array"``: a picture of the character with its trail, route, current
      command (target) and obstacles; ``render_style="stick"`` (a stick figure, matplotlib) or
      ``"humanoid"`` (the MuJoCo humanoid of :mod:`motion_env.replay`, needs offscreen OpenGL:
      ``MUJOCO_GL=egl`` or ``osmesa``); ``render_size`` = (width, height) in pixels. The render
      rate (``metadata["render_fps"]``) is 20 / ``frames_per_step``.
    - ``lookahead``: how the generator's one-second look-ahead is made after a new command
      (:attr:`motion_env.generation.streaming.MotionStream.lookahead`): ``"head"`` predicts it
      in one pass (the frames emitted stay the path controller's), ``"exact"`` rolls the
      controller out again (21 steps, the behaviour before the head).
    - ``robot``: every frame emitted is also retargeted onto that robot (``info["robot_qpos"]``,
      below) by :class:`motion_env.retarget.StreamRetargeter`: causal, IK warm-started from the
      previous frame, joint ranges respected, root height from the lowest foot geom; it adds about
      2-3 ms per frame with the G1 on one CPU core (a step at ``frames_per_step=1``: median 0.2 ms
      -> 2.9 ms); needs ``pip install "motion-env[robots]"``.

    ## ``info`` keys
    Returned by ``reset`` and ``step``, with the same keys and shapes (the ``reward_*`` terms: ``step``
    only), so vector envs can stack them:

    | key | shape | meaning |
    |---|---|---|
    | ``joints`` | (22, 3) float32 | world positions of the last frame emitted |
    | ``step_joints`` | (F, 22, 3) float32 | the F = ``frames_per_step`` frames the step emitted |
    | ``text`` | str | the caption |
    | ``caption_warning`` | str | the warning the caption got ('' for none) |
    | ``frame`` | int | frames emitted so far |
    | ``route_length`` | int | K, the waypoints of the route (the route itself: :attr:`route`) |
    | ``route_index`` | int | k, the index of the route target |
    | ``route_target`` | (2,) float32 | the route target R[k], world x, z |
    | ``command`` | (2,) float32 | the point the character is walking to, world x, z |
    | ``following_route`` | bool | following the route (True) or on a detour (False) |
    | ``distance`` | float | pelvis to the route target (m) |
    | ``is_success`` | bool | the last waypoint reached |
    | ``action_clipped`` | bool | the action was outside the Box and was clipped |
    | ``action_invalid`` | bool | the action had NaN/inf and was not applied (``"hold"``) |
    | ``reward_progress``, ... | float | the reward terms (Rewards) |
    | ``robot_qpos`` | (nq,) float32 | with ``robot=``: the last frame emitted on the robot |

    - ``step_joints`` after a reset holds the first frame F times.
    - ``caption_warning`` is given once as a ``UserWarning`` too, when the caption was not English,
      too long or far from every caption the model knows.
    - ``route``: (K, 3) with times (frame index or NaN).
    - ``robot_qpos``: MuJoCo qpos (root x, y, z in MuJoCo's Z-up axes, quaternion w, x, y, z, then
      the joints), the same shape after reset and every step.

    ## Version History
    * v0: Initial version.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": FPS}
    reset_options: tuple[str, ...] = ("text", "waypoints", "start")

    def __init__(
        self,
        generator: Any | None = None,
        model_path: str | None = None,
        text_pool: Sequence[str] | None = None,
        action_mode: str = "normalized",
        frames_per_step: int = 4,
        arrive_radius: float = 0.5,
        terminate_on_arrival: bool = True,
        render_mode: str | None = None,
        obstacles: np.ndarray | Sequence | None = None,
        arena_size: float = 10.0,
        snap_radius: float = 0.05,
        progress_weight: float = 1.0,
        arrival_bonus: float = 1.0,
        collision_penalty: float = 1.0,
        time_penalty: float = 0.1,
        reach: float = 3.0,
        follow_action: bool = True,
        invalid_action: str = "raise",
        random_start: bool = False,
        device: str = "cpu",
        render_size: tuple[int, int] = (480, 360),
        render_style: str = "stick",
        robot: str | None = None,
        lookahead: str = "auto",
    ) -> None:
        self.config = EnvConfig(
            action_mode=action_mode,
            frames_per_step=frames_per_step,
            arrive_radius=arrive_radius,
            terminate_on_arrival=terminate_on_arrival,
            arena_size=arena_size,
            snap_radius=snap_radius,
            progress_weight=progress_weight,
            arrival_bonus=arrival_bonus,
            collision_penalty=collision_penalty,
            time_penalty=time_penalty,
            reach=reach,
            follow_action=follow_action,
            invalid_action=invalid_action,
            random_start=random_start,
            lookahead=lookahead,
        )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}"
            )
        if render_style not in RENDER_STYLES:
            raise ValueError(f"render_style must be one of {RENDER_STYLES}, got {render_style!r}")
        self.render_mode = render_mode
        self.render_style = render_style
        self.render_size = (int(render_size[0]), int(render_size[1]))
        self._view: Any = None
        self.metadata = {**self.metadata, "render_fps": FPS / self.config.frames_per_step}
        self.text_pool, self.obstacles, self.generator, self._batch = build_characters(
            self.config, text_pool, obstacles, generator, model_path, device
        )
        self._batch.use_robot(robot, 1)
        self.action_space = action_space(self.config)
        self.observation_space = observation_space(caption_size(self.generator))
        self._flags = (False, False)
        self._terminated = False

    # -- Gymnasium API -------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        text, route, start = self._episode(options or {})
        stream_seed = int(self.np_random.integers(2**31 - 1))
        self._batch.start(self.generator, [text], [route], start[None], seed=stream_seed)
        self._flags = (False, False)
        self._terminated = False
        return self._observation(), self._info()

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        if self._batch.stream is None:
            raise RuntimeError("call reset() before step()")
        cfg = self.config
        actions, valid, clipped = check_actions(
            action, 1, cfg.action_bound, cfg.invalid_action, cfg.action_size
        )
        if self._terminated:
            gym.logger.warn(
                "step() called after the episode terminated; call reset() to start a new one "
                "(the character moves on, but no reward is given until then)"
            )
        batch = self._batch
        batch.begin_step()
        batch.command(actions, valid)
        for _ in range(cfg.frames_per_step):
            batch.emit_frame()
        self._flags = (bool(clipped[0]), not bool(valid[0]))
        scale = 0.0 if self._terminated else 1.0
        terms = {name: scale * float(v[0]) for name, v in self._reward_terms().items()}
        reward = float(sum(terms.values()))
        self._terminated |= bool(cfg.terminate_on_arrival and batch.reached[0])
        return self._observation(), reward, self._terminated, False, {**self._info(), **terms}

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode; make the env with render_mode='rgb_array'"
            )
            return None
        if self._batch.stream is None:
            raise RuntimeError("call reset() before render()")
        batch = self._batch
        obstacles = circles(self.obstacles) if len(self.obstacles) else None
        if self.render_style == "humanoid":
            if self._view is None:
                from motion_env.render.humanoid import HumanoidView

                self._view = HumanoidView(*self.render_size)
            trail = np.array(batch.trails[0])
            return self._view.draw(batch.joints[0], trail, batch.command_xz[0], batch.routes[0], obstacles)
        from motion_env.render import render_frame

        return render_frame(
            batch.joints[0],
            path=np.array(batch.trails[0]),
            target=batch.command_xz[0],
            waypoints=batch.routes[0],
            obstacles=obstacles,
            title=batch.texts[0],
            label=f"t = {(int(batch.stream.frame_index[0]) - 1) / FPS:.2f} s",
            width=self.render_size[0],
            height=self.render_size[1],
        )

    def close(self) -> None:
        self._batch.stream = None
        if self._view is not None:
            self._view.close()
            self._view = None

    # -- editing mid-episode -------------------------------------------------------------------

    def set_text(self, text: str) -> None:
        """Change the caption mid-episode; the motion blends into the new one without a pop."""
        self._require_episode()
        self._batch.set_text(text, index=0)  # the stream checks the caption

    def set_route(self, waypoints: np.ndarray | Sequence) -> None:
        """Replace the route mid-episode ((K, 2) or (K, 3), times = absolute frame indices).

        The route index restarts at 0 and the character follows the new route from R[0].
        """
        self._require_episode()
        self._batch.set_route(0, validate_waypoints(waypoints))

    def set_joint_targets(
        self, targets: JointTargets | np.ndarray | None, first_frame: int | None = None
    ) -> None:
        """Joint targets from now on (replacing earlier ones): a :class:`motion_env.JointTargets`
        in episode frames, or (F, 22, 3) world metres, NaN where a joint is free, row k = episode
        frame ``first_frame + k`` (default: the next frame).

        The stream's rules (:meth:`motion_env.generation.streaming.MotionStream.set_joint_targets`):
        a target set at least 10 frames (0.5 s) before its frame is met there exactly; frames
        already emitted never change. :meth:`control_summary` says how well they were met so far.
        """
        self._require_episode()
        self._batch.stream.set_joint_targets(targets, index=0, first_frame=first_frame)

    def set_objectives(self, objectives: Sequence[Any] | None) -> None:
        """Height limits from now on (:class:`motion_env.objectives.HeightLimit`, episode frames);
        KeepOut / StayInside need a whole clip, or a planner (``policies.AStarPolicy``)."""
        self._require_episode()
        self._batch.stream.set_objectives(objectives, index=0)

    def control_summary(self) -> str:
        """How well the joint targets emitted so far were met (one line)."""
        self._require_episode()
        return self._batch.stream.control_summary(0)

    @property
    def text(self) -> str:
        self._require_episode()
        return self._batch.texts[0]

    @property
    def route(self) -> np.ndarray:
        """(K, 3) the current route (x, z, frame index or NaN)."""
        self._require_episode()
        return self._batch.routes[0].copy()

    # -- internals -----------------------------------------------------------------------------

    def _require_episode(self) -> None:
        if self._batch.stream is None:
            raise RuntimeError("call reset() first")

    def _episode(self, options: dict[str, Any]) -> tuple[str, np.ndarray, np.ndarray]:
        """Caption, route (K, 3) and start (3,) of a new episode from options and self.np_random."""
        unknown = sorted(set(options) - set(self.reset_options))
        if unknown:
            raise ValueError(f"unknown reset options {unknown}; known: {list(self.reset_options)}")
        rng = self.np_random
        text = options.get("text")
        text = self.text_pool[int(rng.integers(len(self.text_pool)))] if text is None else check_text(text)
        start = options.get("start")
        start = sample_start(rng, self.config, self.obstacles) if start is None else validate_start(start)
        route = self._route(options, start)
        return text, route, start

    def _route(self, options: dict[str, Any], start: np.ndarray) -> np.ndarray:
        waypoints = options.get("waypoints")
        if waypoints is None:
            return sample_route(self.np_random, start, self.config, self.obstacles)
        return validate_waypoints(waypoints)

    def _reward_terms(self) -> dict[str, np.ndarray]:
        return self._batch.rewards()

    def _observation(self) -> dict[str, np.ndarray]:
        return {name: value[0] for name, value in self._batch.observations().items()}

    def _info(self) -> dict[str, Any]:
        batch = self._batch
        route_target = batch.route_target[0]
        return {
            "joints": batch.joints[0].copy(),
            "step_joints": batch.step_joints()[0],
            "text": batch.texts[0],
            "caption_warning": self.generator.caption_warning(batch.texts[0]),
            "frame": int(batch.stream.frame_index[0]),
            "route_length": len(batch.routes[0]),
            "route_index": int(batch.k[0]),
            "route_target": route_target.astype(np.float32),
            "command": batch.command_xz[0].astype(np.float32),
            "following_route": bool(batch.following[0]),
            "distance": float(np.linalg.norm(batch.pos[0] - route_target)),
            "is_success": bool(batch.reached[0]),
            "action_clipped": self._flags[0],
            "action_invalid": self._flags[1],
            **({"robot_qpos": batch.robot_qpos[0].copy()} if batch.retargeter is not None else {}),
        }
