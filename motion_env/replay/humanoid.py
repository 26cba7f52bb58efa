"""The replay humanoid's body, generated from the canonical skeleton: :func:`humanoid_xml`.

The body is built from :mod:`motion_env.motion.skeleton`: one body per non-leaf joint, placed at
that joint in a relaxed standing rest pose, with a 3-DoF ball joint (a free joint at the pelvis),
capsule limbs sized from :data:`skeleton.BONE_LENGTHS`, and segment masses, centres of mass and
inertias from standard body-segment proportions. As in MuJoCo Menagerie, the body XML holds the
body only; the scene (floor, light, camera) is ``motion_env/replay/model/scene.xml``, which
includes it as ``humanoid.xml`` (see ``motion_env/replay/model/README.md``). The body is made at
load time (:func:`motion_env.replay.mjcf.load_model`) because the mass and the rest pose are
parameters; ``model/humanoid.xml`` is the default body (70 kg, :data:`REST_DIRECTIONS`) written
out by :func:`motion_env.replay.mjcf.write_body_xml`.

Frames: motions are Y up and face +Z (docs/conventions.md); MuJoCo models are Z up and humanoids
face +X. :func:`to_mujoco` maps a motion point (x, y, z) to (z, x, y), a proper rotation, so the
character's forward is MuJoCo +X, its left +Y and up +Z. Every body frame is aligned with the
world in the rest pose, so a ball joint's quaternion is the body's rotation relative to its
parent, both measured from that pose.

Sources:
- segment masses, centre-of-mass positions and radii of gyration: P. de Leva, "Adjustments to
  Zatsiorsky-Seluyanov's segment inertia parameters", J. Biomechanics 29(9), 1996 (male table);
  the trunk is split into its lower, middle and upper parts, the hand is merged into the forearm;
- joint ranges: typical adult active ranges of motion (e.g. the AAOS tables), widened by about
  10 degrees, as limits on the components of each joint's rotation vector;
- the rest pose: median bone directions over the first frames of Bandai Namco walk and
  raise-hands takes loaded by :func:`motion_env.load_bvh`, symmetrised, with straight limbs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion_env.motion.skeleton import BONE_LENGTHS, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, PARENTS

DEFAULT_MASS = 70.0  # kg

# The one table mapping canonical joint names to MuJoCo body names. A non-leaf joint is the
# origin of its body and holds that body's ball joint (named after the canonical joint); a leaf
# joint (toes, head, wrists) is a site on the body that carries it. Every canonical joint also
# has a site with its own name, so forward kinematics reads all 22 positions from `site_xpos`.
JOINT_TO_BODY: dict[str, str] = {
    "pelvis": "pelvis",
    "left_hip": "left_thigh",
    "right_hip": "right_thigh",
    "spine1": "abdomen",
    "left_knee": "left_shin",
    "right_knee": "right_shin",
    "spine2": "thorax",
    "left_ankle": "left_foot",
    "right_ankle": "right_foot",
    "spine3": "chest",
    "left_foot": "left_foot",
    "right_foot": "right_foot",
    "neck": "head",
    "left_collar": "left_clavicle",
    "right_collar": "right_clavicle",
    "head": "head",
    "left_shoulder": "left_upper_arm",
    "right_shoulder": "right_upper_arm",
    "left_elbow": "left_forearm",
    "right_elbow": "right_forearm",
    "left_wrist": "left_forearm",
    "right_wrist": "right_forearm",
}
assert tuple(JOINT_TO_BODY) == JOINT_NAMES

CHILDREN: tuple[tuple[int, ...], ...] = tuple(
    tuple(c for c in range(NUM_JOINTS) if PARENTS[c] == j) for j in range(NUM_JOINTS)
)
LEAF_JOINTS: tuple[int, ...] = tuple(j for j in range(NUM_JOINTS) if not CHILDREN[j])
BODY_JOINTS: tuple[int, ...] = tuple(j for j in range(NUM_JOINTS) if CHILDREN[j])  # 17, tree order
BALL_JOINTS: tuple[int, ...] = BODY_JOINTS[1:]  # every body but the pelvis has a ball joint

# Rest-pose bone directions in the motion frame (x = left, y = up, z = forward) for the left
# side and the midline; right-side bones are mirrored (x -> -x). Limbs are straight (arms
# hang 15 degrees out from the body, as in the data); the ankle->toe bone points 40 degrees down,
# as it does in a flat standing foot of the loaded mocap.
_REST_LEFT: dict[str, tuple[float, float, float]] = {
    "left_hip": (0.95, -0.31, 0.0),
    "spine1": (0.0, 1.0, 0.0),
    "left_knee": (0.0, -1.0, 0.0),
    "spine2": (0.0, 1.0, 0.0),
    "left_ankle": (0.0, -1.0, 0.0),
    "spine3": (0.0, 1.0, 0.04),
    "left_foot": (0.0, -0.64, 0.77),
    "neck": (0.0, 0.995, 0.1),
    "left_collar": (0.35, 0.935, 0.05),
    "head": (0.0, 0.99, 0.15),
    "left_shoulder": (0.957, -0.04, -0.28),
    "left_elbow": (0.26, -0.966, 0.0),
    "left_wrist": (0.26, -0.966, 0.0),
}


def _rest_direction(name: str) -> np.ndarray:
    if name in _REST_LEFT:
        d = np.array(_REST_LEFT[name])
    else:
        d = np.array(_REST_LEFT[name.replace("right_", "left_")]) * np.array([-1.0, 1.0, 1.0])
    return d / np.linalg.norm(d)


REST_DIRECTIONS = np.stack(
    [np.zeros(3)] + [_rest_direction(n) for n in JOINT_NAMES[1:]]
)  # (22, 3), motion frame

# Per-axis joint ranges (degrees) of the rotation vector of each ball joint, in MuJoCo's frame
# (x = forward, y = left, z = up) for the left side and the midline; mirrored for the right
# side. Signs: about +y, positive bends the hip backward (extension), the knee backward
# (flexion), the ankle toes-down, the spine forward; about +x, positive lifts a left limb
# sideways (abduction); about +z, positive turns a left limb outward and the midline to the left.
JOINT_RANGES_DEG: dict[str, tuple[tuple[float, float], tuple[float, float], tuple[float, float]]] = {
    "left_hip": ((-40.0, 60.0), (-140.0, 40.0), (-55.0, 55.0)),
    "spine1": ((-40.0, 40.0), (-40.0, 60.0), (-45.0, 45.0)),
    "left_knee": ((-25.0, 25.0), (-15.0, 160.0), (-45.0, 45.0)),
    "spine2": ((-40.0, 40.0), (-40.0, 60.0), (-45.0, 45.0)),
    "left_ankle": ((-45.0, 45.0), (-45.0, 65.0), (-45.0, 45.0)),
    "spine3": ((-40.0, 40.0), (-40.0, 60.0), (-45.0, 45.0)),
    "neck": ((-55.0, 55.0), (-65.0, 80.0), (-90.0, 90.0)),
    "left_collar": ((-40.0, 40.0), (-40.0, 40.0), (-40.0, 40.0)),
    "left_shoulder": ((-70.0, 180.0), (-180.0, 90.0), (-110.0, 110.0)),
    "left_elbow": ((-45.0, 45.0), (-165.0, 20.0), (-45.0, 45.0)),
}


def joint_ranges_rad() -> np.ndarray:
    """Per-axis ranges of every ball joint, (len(BALL_JOINTS), 3, 2) radians, in BALL_JOINTS order."""
    out = np.zeros((len(BALL_JOINTS), 3, 2))
    for k, j in enumerate(BALL_JOINTS):
        name = JOINT_NAMES[j]
        if name in JOINT_RANGES_DEG:
            ranges = np.array(JOINT_RANGES_DEG[name])
        else:  # mirror y -> -y: a rotation vector (rx, ry, rz) becomes (-rx, ry, -rz)
            ranges = np.array(JOINT_RANGES_DEG[name.replace("right_", "left_")])
            ranges[0] = -ranges[0, ::-1]
            ranges[2] = -ranges[2, ::-1]
        out[k] = np.deg2rad(ranges)
    return out


# Capsule radii (m) of the limbs and trunk.
_RADIUS = {
    "pelvis": 0.08,
    "lower_back": 0.09,
    "abdomen": 0.09,
    "thorax": 0.1,
    "chest": 0.11,
    "shoulders": 0.06,
    "neck": 0.05,
    "head": 0.1,
    "clavicle": 0.045,
    "upper_arm": 0.042,
    "forearm": 0.035,
    "hand": 0.03,
    "thigh": 0.065,
    "shin": 0.048,
    "foot": 0.02,
}
_HAND_LENGTH = 0.1  # wrist to the end of the hand capsule's axis
_FOOT_HALF_WIDTH = 0.025  # lateral offset of the two sole capsules
_HEEL_BACK = 0.05  # heel capsule end behind the ankle
_TOE_FRONT = 0.02  # toe capsule end in front of the toe (ball of foot) joint


@dataclass(frozen=True)
class _Segment:
    """A de Leva segment: mass fraction, CoM fraction from `proximal`, radii of gyration / length."""

    mass: float
    proximal: np.ndarray  # rest position, motion frame
    distal: np.ndarray
    com: float
    r_sagittal: float  # about the medio-lateral axis
    r_transverse: float  # about the antero-posterior axis
    r_long: float


def to_mujoco(points: np.ndarray) -> np.ndarray:
    """Motion frame (x left, y up, z forward) -> MuJoCo frame (x forward, y left, z up), (..., 3)."""
    return np.asarray(points)[..., [2, 0, 1]]


def from_mujoco(points: np.ndarray) -> np.ndarray:
    """Inverse of :func:`to_mujoco`, (..., 3)."""
    return np.asarray(points)[..., [1, 2, 0]]


def rest_positions(rest_directions: np.ndarray | None = None) -> np.ndarray:
    """Rest-pose joint positions (22, 3) in the motion frame, the sole bottoms at y = 0.

    rest_directions: (22, 3) unit bone directions (default :data:`REST_DIRECTIONS`); bones have
    the canonical :data:`skeleton.BONE_LENGTHS`.
    """
    dirs = REST_DIRECTIONS if rest_directions is None else check_directions(rest_directions)
    pos = np.zeros((NUM_JOINTS, 3))
    for j in range(1, NUM_JOINTS):
        pos[j] = pos[PARENTS[j]] + dirs[j] * BONE_LENGTHS[j]
    # The sole capsules' bottoms are level with the toe joints (see _foot_geoms).
    pos[:, 1] -= min(pos[JOINT_INDEX["left_foot"], 1], pos[JOINT_INDEX["right_foot"], 1])
    return pos


def check_directions(rest_directions: np.ndarray) -> np.ndarray:
    """`rest_directions` as a (22, 3) float array of unit vectors, or ValueError."""
    dirs = np.asarray(rest_directions, dtype=np.float64)
    if dirs.shape != (NUM_JOINTS, 3) or not np.isfinite(dirs).all():
        raise ValueError(f"rest_directions must be a finite ({NUM_JOINTS}, 3) array, got shape {dirs.shape}")
    norms = np.linalg.norm(dirs[1:], axis=-1)
    if np.abs(norms - 1.0).max() > 1e-6:
        raise ValueError(f"rest_directions must be unit vectors (norms {norms.min():.3g}..{norms.max():.3g})")
    return dirs


def _segments(pos: np.ndarray) -> dict[str, list[_Segment]]:
    """de Leva segments carried by each body (rest positions in the motion frame)."""
    j = JOINT_INDEX
    hips_mid = 0.5 * (pos[j["left_hip"]] + pos[j["right_hip"]])
    head_dir = pos[j["head"]] - pos[j["neck"]]
    vertex = pos[j["head"]] + 0.13 * head_dir / np.linalg.norm(head_dir)
    segs: dict[str, list[_Segment]] = {
        # lower trunk: omphalion (~spine1) to the hip-joint midpoint
        "pelvis": [_Segment(0.1117, pos[j["spine1"]], hips_mid, 0.6115, 0.615, 0.551, 0.587)],
        # middle trunk (xiphoid to omphalion), split over the two lumbar/thoracic bodies
        "abdomen": [_Segment(0.1000, pos[j["spine2"]], pos[j["spine1"]], 0.4502, 0.482, 0.383, 0.468)],
        "thorax": [_Segment(0.0633, pos[j["spine3"]], pos[j["spine2"]], 0.4502, 0.482, 0.383, 0.468)],
        # upper trunk (suprasternale to xiphoid) less the two clavicles
        "chest": [_Segment(0.1396, pos[j["neck"]], pos[j["spine3"]], 0.2999, 0.716, 0.454, 0.659)],
        "head": [_Segment(0.0694, vertex, pos[j["neck"]], 0.5976, 0.362, 0.376, 0.312)],
    }
    for side in ("left", "right"):
        ankle, toe = pos[j[f"{side}_ankle"]], pos[j[f"{side}_foot"]]
        fwd = np.array([0.0, 0.0, 1.0])
        heel = np.array([ankle[0], toe[1], ankle[2]]) - _HEEL_BACK * fwd
        wrist = pos[j[f"{side}_wrist"]]
        fore = wrist - pos[j[f"{side}_elbow"]]
        hand_end = wrist + 0.09 * fore / np.linalg.norm(fore)  # wrist to the third knuckle
        segs[f"{side}_thigh"] = [
            _Segment(0.1416, pos[j[f"{side}_hip"]], pos[j[f"{side}_knee"]], 0.4095, 0.329, 0.329, 0.149)
        ]
        segs[f"{side}_shin"] = [_Segment(0.0433, pos[j[f"{side}_knee"]], ankle, 0.4459, 0.255, 0.249, 0.103)]
        segs[f"{side}_foot"] = [_Segment(0.0137, heel, toe + _TOE_FRONT * fwd, 0.4415, 0.257, 0.245, 0.124)]
        segs[f"{side}_clavicle"] = [
            _Segment(0.0100, pos[j[f"{side}_collar"]], pos[j[f"{side}_shoulder"]], 0.5, 0.3, 0.3, 0.1)
        ]
        segs[f"{side}_upper_arm"] = [
            _Segment(0.0271, pos[j[f"{side}_shoulder"]], pos[j[f"{side}_elbow"]], 0.5772, 0.285, 0.269, 0.158)
        ]
        segs[f"{side}_forearm"] = [
            _Segment(0.0162, pos[j[f"{side}_elbow"]], wrist, 0.4574, 0.276, 0.265, 0.121),
            _Segment(0.0061, wrist, hand_end, 0.7900, 0.628, 0.513, 0.401),
        ]
    total = sum(s.mass for body in segs.values() for s in body)
    assert abs(total - 1.0) < 1e-9, total
    return segs


def _segment_inertia(seg: _Segment, mass: float) -> tuple[np.ndarray, np.ndarray]:
    """(CoM (3,), inertia about the CoM (3, 3)), both in the MuJoCo frame."""
    p, d = to_mujoco(seg.proximal), to_mujoco(seg.distal)
    axis = d - p
    length = float(np.linalg.norm(axis))
    u = axis / length
    lateral = np.array([0.0, 1.0, 0.0]) - u[1] * u  # medio-lateral axis (MuJoCo +y) made normal to u
    if np.linalg.norm(lateral) < 1e-6:  # a segment along +y: pick the forward axis instead
        lateral = np.array([1.0, 0.0, 0.0]) - u[0] * u
    lateral /= np.linalg.norm(lateral)
    ap = np.cross(u, lateral)
    inertia = (
        (seg.r_sagittal * length) ** 2 * np.outer(lateral, lateral)
        + (seg.r_transverse * length) ** 2 * np.outer(ap, ap)
        + (seg.r_long * length) ** 2 * np.outer(u, u)
    ) * mass
    return p + seg.com * axis, inertia


def _body_inertial(segs: list[_Segment], total_mass: float, origin: np.ndarray) -> str:
    """An <inertial> element combining segments (parallel-axis theorem), relative to `origin`."""
    masses = [s.mass * total_mass for s in segs]
    parts = [_segment_inertia(s, m) for s, m in zip(segs, masses)]
    m_body = sum(masses)
    com = sum(m * c for m, (c, _) in zip(masses, parts)) / m_body
    inertia = np.zeros((3, 3))
    for m, (c, i_c) in zip(masses, parts):
        r = c - com
        inertia += i_c + m * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
    full = (inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1], inertia[0, 2], inertia[1, 2])
    return (
        f'<inertial pos="{_fmt(com - origin)}" mass="{m_body:.6g}" '
        f'fullinertia="{" ".join(f"{v:.6g}" for v in full)}"/>'
    )


def _fmt(v: np.ndarray) -> str:
    return " ".join(f"{x:.6g}" for x in np.asarray(v, dtype=float))


def _capsule(name: str, a: np.ndarray, b: np.ndarray, radius: float, origin: np.ndarray, cls: str) -> str:
    """A capsule between motion-frame points a and b, in the body frame at `origin` (MuJoCo)."""
    ends = np.concatenate([to_mujoco(a) - origin, to_mujoco(b) - origin])
    return f'<geom name="{name}" class="{cls}" fromto="{_fmt(ends)}" size="{radius:g}"/>'


# Limb bodies that are one capsule from one joint to the next: body part -> (start, end) joint
# (of the body's side).
_LIMB_SEGMENTS = {
    "clavicle": ("collar", "shoulder"),
    "upper_arm": ("shoulder", "elbow"),
    "thigh": ("hip", "knee"),
    "shin": ("knee", "ankle"),
}


def _geoms(body: str, pos: np.ndarray, origin: np.ndarray) -> list[str]:
    """Collision/visual geoms of one body (rest positions `pos` in the motion frame)."""
    j = JOINT_INDEX
    side, _, part = body.partition("_") if body.startswith(("left_", "right_")) else ("", "", body)
    cls = f"{side}_limb" if side else "trunk"
    r = _RADIUS
    if body == "pelvis":
        return [
            _capsule("pelvis", pos[j["left_hip"]], pos[j["right_hip"]], r["pelvis"], origin, cls),
            _capsule("lower_back", pos[j["pelvis"]], pos[j["spine1"]], r["lower_back"], origin, cls),
        ]
    if body == "abdomen":
        return [_capsule("abdomen", pos[j["spine1"]], pos[j["spine2"]], r["abdomen"], origin, cls)]
    if body == "thorax":
        return [_capsule("thorax", pos[j["spine2"]], pos[j["spine3"]], r["thorax"], origin, cls)]
    if body == "chest":
        return [
            _capsule("chest", pos[j["spine3"]], pos[j["neck"]], r["chest"], origin, cls),
            _capsule("shoulders", pos[j["left_collar"]], pos[j["right_collar"]], r["shoulders"], origin, cls),
        ]
    if body == "head":
        head_dir = pos[j["head"]] - pos[j["neck"]]
        centre = pos[j["head"]] + 0.07 * head_dir / np.linalg.norm(head_dir)
        return [
            _capsule("neck", pos[j["neck"]], pos[j["head"]], r["neck"], origin, cls),
            f'<geom name="head" class="{cls}" type="sphere" pos="{_fmt(to_mujoco(centre) - origin)}" '
            f'size="{r["head"]:g}"/>',
        ]
    if part in _LIMB_SEGMENTS:
        start, end = _LIMB_SEGMENTS[part]
        return [_capsule(body, pos[j[f"{side}_{start}"]], pos[j[f"{side}_{end}"]], r[part], origin, cls)]
    if part == "forearm":
        a, b = pos[j[f"{side}_elbow"]], pos[j[f"{side}_wrist"]]
        hand_end = b + _HAND_LENGTH * (b - a) / np.linalg.norm(b - a)
        return [
            _capsule(body, a, b, r["forearm"], origin, cls),
            _capsule(f"{side}_hand", b, hand_end, r["hand"], origin, cls),
        ]
    if part == "foot":
        return _foot_geoms(side, pos, origin, cls)
    raise ValueError(f"no geometry defined for body {body!r}")


def _foot_geoms(side: str, pos: np.ndarray, origin: np.ndarray, cls: str) -> list[str]:
    """Two parallel sole capsules (medial, lateral) whose bottoms are level with the toe joint."""
    j = JOINT_INDEX
    ankle, toe = pos[j[f"{side}_ankle"]], pos[j[f"{side}_foot"]]
    rf = _RADIUS["foot"]
    sole_y = toe[1] + rf
    geoms = []
    for k, sign in enumerate((-1.0, 1.0)):
        shift = np.array([sign * _FOOT_HALF_WIDTH, 0.0, 0.0])
        heel = np.array([ankle[0], sole_y, ankle[2] - _HEEL_BACK]) + shift
        front = np.array([toe[0], sole_y, toe[2] + _TOE_FRONT]) + shift
        geoms.append(_capsule(f"{side}_sole{k}", heel, front, rf, origin, cls))
    return geoms


def _tree_distance(a: int, b: int) -> int:
    def ancestors(j: int) -> list[int]:
        out = [j]
        while PARENTS[out[-1]] >= 0:
            out.append(PARENTS[out[-1]])
        return out

    pa, pb = ancestors(a), ancestors(b)
    common = next(x for x in pa if x in pb)
    return pa.index(common) + pb.index(common)


def _excluded_pairs() -> list[tuple[str, str]]:
    """Body pairs two steps apart in the tree (siblings, grandparents) whose capsules overlap in
    ordinary poses; MuJoCo already skips parent-child pairs. The upper arms against the chest
    and the two thighs stay in, as arms through the chest and crossed legs are what we look for.
    The hands against the pelvis go out: hands on the hips sink into its capsule in real takes."""
    keep = {frozenset(("chest", "left_upper_arm")), frozenset(("chest", "right_upper_arm")),
            frozenset(("left_thigh", "right_thigh"))}  # fmt: skip
    pairs = []
    for ia, a in enumerate(BODY_JOINTS):
        for b in BODY_JOINTS[ia + 1 :]:
            names = (JOINT_TO_BODY[JOINT_NAMES[a]], JOINT_TO_BODY[JOINT_NAMES[b]])
            if _tree_distance(a, b) == 2 and frozenset(names) not in keep:
                pairs.append(names)
    return pairs + [("pelvis", "left_forearm"), ("pelvis", "right_forearm")]


def humanoid_xml(mass: float = DEFAULT_MASS, rest_directions: np.ndarray | None = None) -> str:
    """The body-only MJCF of the humanoid with total mass `mass` (kg), as a string.

    Bodies follow :data:`JOINT_TO_BODY`; ball joints carry the canonical joint names and the
    per-joint maximum rotation angle of :data:`JOINT_RANGES_DEG` as their MuJoCo range.
    rest_directions: (22, 3) bone directions of the rest pose (default :data:`REST_DIRECTIONS`;
    :func:`motion_env.replay.fit.clip_rest_directions` adapts the pelvis and chest to a clip).
    """
    if not (np.isfinite(mass) and mass > 0):
        raise ValueError(f"humanoid mass must be a positive number of kg, got {mass!r}")
    pos = rest_positions(rest_directions)
    segs = _segments(pos)
    ranges = np.rad2deg(joint_ranges_rad())
    max_angle = {JOINT_NAMES[j]: float(np.abs(ranges[k]).max()) for k, j in enumerate(BALL_JOINTS)}

    def body_xml(j: int, parent_origin: np.ndarray, indent: str) -> list[str]:
        name = JOINT_NAMES[j]
        body = JOINT_TO_BODY[name]
        origin = to_mujoco(pos[j])
        lines = [f'{indent}<body name="{body}" pos="{_fmt(origin - parent_origin)}">']
        inner = indent + "  "
        if j == 0:
            lines.append(f'{inner}<freejoint name="root"/>')
        else:
            lines.append(f'{inner}<joint name="{name}" range="0 {max_angle[name]:g}"/>')
        lines.append(inner + _body_inertial(segs[body], mass, origin))
        lines += [inner + g for g in _geoms(body, pos, origin)]
        lines.append(f'{inner}<site name="{name}" class="joint_site" pos="0 0 0"/>')
        for c in CHILDREN[j]:
            if c in LEAF_JOINTS:
                site_pos = to_mujoco(pos[c]) - origin
                lines.append(
                    f'{inner}<site name="{JOINT_NAMES[c]}" class="joint_site" pos="{_fmt(site_pos)}"/>'
                )
            else:
                lines += body_xml(c, origin, inner)
        lines.append(f"{indent}</body>")
        return lines

    excludes = "\n".join(f'    <exclude body1="{a}" body2="{b}"/>' for a, b in _excluded_pairs())
    bodies = "\n".join(body_xml(0, np.zeros(3), "    "))
    return f"""<mujoco model="motion_env humanoid">
  <!-- Generated by motion_env.replay.humanoid.humanoid_xml(mass={mass:g}) from the canonical
       22-joint skeleton; see that module for the sources of the proportions. -->
  <compiler angle="degree"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <default>
    <joint type="ball" limited="true" armature="0.02" damping="1"/>
    <geom type="capsule" condim="3" friction="1 0.005 0.0001" density="0"/>
    <site size="0.01" group="3"/>
    <default class="trunk"><geom rgba="0.75 0.72 0.68 1"/></default>
    <default class="left_limb"><geom rgba="0.55 0.68 0.85 1"/></default>
    <default class="right_limb"><geom rgba="0.85 0.7 0.5 1"/></default>
    <default class="joint_site"><site rgba="0.1 0.1 0.1 1"/></default>
  </default>
  <worldbody>
{bodies}
  </worldbody>
  <contact>
{excludes}
  </contact>
</mujoco>
"""
