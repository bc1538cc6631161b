"""Retargeting a source skeleton's motion onto the canonical skeleton.

Joints are matched by name (built-in naming schemes, or a user map in YAML). Rotations are
transferred with rest-pose alignment, so that a source whose rest pose differs from the canonical
T-pose (arms down, splayed legs, extra zero-length joints) drives the canonical bones in the same
directions as its own:

* a canonical joint with one child bone: ``G_c = Q(t) G_s(t) A_c`` where ``A_c`` rotates the
  canonical rest bone onto the source's rest bone (rest-pose alignment) and ``Q(t)`` is the
  smallest rotation that corrects the bone direction to where the source's mapped child actually is
  (exact even when the source has extra joints in between);
* the pelvis and the upper spine (a centre child and a left/right pair): a frame built from the
  "up" bone and the left-right axis, so the forward offset of the source's hip joints does not tilt
  the pelvis;
* leaves (head, wrists, toes): the source joint's rotation with the parent's alignment.

Root translation is scaled by the ratio of leg lengths (so strides fit the canonical legs and feet
do not skate) and, by default, shifted vertically so the feet stand on y = 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import MotionError, SkeletonMappingError
from .motion import Motion
from .rotations import axis_angle_to_matrix, normalize, rotation_between
from .skeleton import CANONICAL, JOINT_INDEX, JOINT_NAMES, PARENTS, global_to_local

# Canonical joints that may be missing from a source; they then follow their parent rigidly.
OPTIONAL_JOINTS = frozenset({"spine2", "l_collar", "r_collar", "l_foot", "r_foot"})


def _lr(template: dict[str, list[str]]) -> dict[str, list[str]]:
    """Expand '{s}'/'{S}' placeholders into left and right entries of a naming scheme."""
    out: dict[str, list[str]] = {}
    for key, names in template.items():
        if "{side}" in key:
            for side, s, S, full in (("l", "l", "L", "Left"), ("r", "r", "R", "Right")):
                out[key.replace("{side}", side)] = [n.format(s=s, S=S, Side=full) for n in names]
        else:
            out[key] = names
    return out


# Canonical joint -> accepted source names (matched case-insensitively, namespace prefix stripped).
NAMING_SCHEMES: dict[str, dict[str, list[str]]] = {
    "smpl": _lr({
        "pelvis": ["pelvis", "m_avg_pelvis"], "spine1": ["spine1", "m_avg_spine1"], "spine2": ["spine2", "m_avg_spine2"],
        "spine3": ["spine3", "m_avg_spine3"], "neck": ["neck", "m_avg_neck"], "head": ["head", "m_avg_head"],
        "{side}_hip": ["{s}_hip", "{S}_Hip", "{Side}_hip", "m_avg_{S}_hip"], "{side}_knee": ["{s}_knee", "{Side}_knee", "m_avg_{S}_knee"],
        "{side}_ankle": ["{s}_ankle", "{Side}_ankle", "m_avg_{S}_ankle"], "{side}_foot": ["{s}_foot", "{Side}_foot", "m_avg_{S}_foot"],
        "{side}_collar": ["{s}_collar", "{Side}_collar", "m_avg_{S}_collar"], "{side}_shoulder": ["{s}_shoulder", "{Side}_shoulder", "m_avg_{S}_shoulder"],
        "{side}_elbow": ["{s}_elbow", "{Side}_elbow", "m_avg_{S}_elbow"], "{side}_wrist": ["{s}_wrist", "{Side}_wrist", "m_avg_{S}_wrist"],
    }),
    # CMU as converted to BVH by most public sets (e.g. 02_01): LeftUpLeg / LowerBack / LeftArm ...
    "cmu": _lr({
        "pelvis": ["Hips"], "spine1": ["LowerBack"], "spine2": ["Spine"], "spine3": ["Spine1"], "neck": ["Neck"], "head": ["Head"],
        "{side}_hip": ["{Side}UpLeg"], "{side}_knee": ["{Side}Leg"], "{side}_ankle": ["{Side}Foot"], "{side}_foot": ["{Side}ToeBase"],
        "{side}_collar": ["{Side}Shoulder"], "{side}_shoulder": ["{Side}Arm"], "{side}_elbow": ["{Side}ForeArm"], "{side}_wrist": ["{Side}Hand"],
    }),
    # CMU's "3dsMax-friendly" naming (e.g. 131_01): LeftHip / lowerback / Chest / LeftCollar ...
    "cmu_max": _lr({
        "pelvis": ["Hips"], "spine1": ["lowerback"], "spine2": ["Chest"], "spine3": ["Chest2"], "neck": ["lowerneck", "Neck"], "head": ["Head"],
        "{side}_hip": ["{Side}Hip"], "{side}_knee": ["{Side}Knee"], "{side}_ankle": ["{Side}Ankle"], "{side}_foot": ["{Side}Toe"],
        "{side}_collar": ["{Side}Collar"], "{side}_shoulder": ["{Side}Shoulder"], "{side}_elbow": ["{Side}Elbow"], "{side}_wrist": ["{Side}Wrist"],
    }),
    # Bandai-Namco research motion sets: Hips, Spine, Chest, UpperLeg_L ... (one spine joint fewer).
    "bandai_namco": _lr({
        "pelvis": ["Hips"], "spine1": ["Spine"], "spine3": ["Chest"], "neck": ["Neck"], "head": ["Head"],
        "{side}_hip": ["UpperLeg_{S}"], "{side}_knee": ["LowerLeg_{S}"], "{side}_ankle": ["Foot_{S}"], "{side}_foot": ["Toes_{S}", "Toe_{S}"],
        "{side}_collar": ["Shoulder_{S}"], "{side}_shoulder": ["UpperArm_{S}"], "{side}_elbow": ["LowerArm_{S}"], "{side}_wrist": ["Hand_{S}"],
    }),
    # Mixamo (names carry a "mixamorig:" prefix, stripped before matching).
    "mixamo": _lr({
        "pelvis": ["Hips"], "spine1": ["Spine"], "spine2": ["Spine1"], "spine3": ["Spine2"], "neck": ["Neck"], "head": ["Head"],
        "{side}_hip": ["{Side}UpLeg"], "{side}_knee": ["{Side}Leg"], "{side}_ankle": ["{Side}Foot"], "{side}_foot": ["{Side}ToeBase"],
        "{side}_collar": ["{Side}Shoulder"], "{side}_shoulder": ["{Side}Arm"], "{side}_elbow": ["{Side}ForeArm"], "{side}_wrist": ["{Side}Hand"],
    }),
    "canonical": {n: [n] for n in JOINT_NAMES},
}


def _key(name: str) -> str:
    return name.split(":")[-1].strip().lower()


@dataclass
class SourceMotion:
    """A motion on some source skeleton, in metres, Y up, as world-space joint transforms."""

    names: list[str]
    parents: list[int]
    rest_positions: np.ndarray  # (J, 3) rest pose, metres
    global_rotations: np.ndarray  # (T, J, 3, 3)
    global_positions: np.ndarray  # (T, J, 3) metres
    fps: float
    path: str


def resolve_joint_map(names: list[str], path: str, custom_map: dict[str, str] | None = None) -> tuple[str, dict[str, int]]:
    """Pick a naming scheme (or apply ``custom_map``): returns (scheme name, canonical -> source index)."""
    lookup: dict[str, int] = {}
    for i, n in enumerate(names):
        lookup.setdefault(_key(n), i)
    if custom_map is not None:
        unknown = sorted(set(custom_map) - set(JOINT_NAMES))
        if unknown:
            raise SkeletonMappingError(path, f"joint map names unknown canonical joints {unknown}; canonical joints are {list(JOINT_NAMES)}")
        missing_src = sorted(src for src in custom_map.values() if _key(src) not in lookup)
        if missing_src:
            raise SkeletonMappingError(path, f"joint map refers to joints {missing_src} that the file does not have")
        mapping = {c: lookup[_key(s)] for c, s in custom_map.items()}
        _check_required(mapping, path, "custom")
        return "custom", mapping
    best: tuple[int, str, dict[str, int]] | None = None
    for scheme, table in NAMING_SCHEMES.items():
        mapping = {}
        for canon, candidates in table.items():
            idx = next((lookup[_key(c)] for c in candidates if _key(c) in lookup), None)
            if idx is not None:
                mapping[canon] = idx
        required_ok = all(j in mapping for j in JOINT_NAMES if j not in OPTIONAL_JOINTS)
        score = len(mapping) + (100 if required_ok else 0)
        if best is None or score > best[0]:
            best = (score, scheme, mapping)
    assert best is not None
    _check_required(best[2], path, best[1])
    return best[1], best[2]


def _check_required(mapping: dict[str, int], path: str, scheme: str) -> None:
    missing = [j for j in JOINT_NAMES if j not in mapping and j not in OPTIONAL_JOINTS]
    if missing:
        raise SkeletonMappingError(
            path,
            f"unknown skeleton: could not map canonical joints {missing} (closest naming scheme: {scheme}). "
            "Pass a joint map YAML ('canonical_name: source_joint_name' per line) with --joint-map.",
        )


def load_joint_map(path: str | Path) -> dict[str, str]:
    import yaml

    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise MotionError(path, f"cannot read joint map: {exc}") from None
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise MotionError(path, "joint map must be a mapping 'canonical_joint: source_joint'")
    return data


def leg_length(rest_positions: np.ndarray, hip: int, knee: int, ankle: int) -> float:
    return float(np.linalg.norm(rest_positions[knee] - rest_positions[hip]) + np.linalg.norm(rest_positions[ankle] - rest_positions[knee]))


def _canonical_leg_length() -> float:
    return mean_leg_length(CANONICAL.rest_positions(), JOINT_INDEX)


def mean_leg_length(rest_positions: np.ndarray, mapping: dict[str, int]) -> float:
    """Hip-knee-ankle length averaged over both legs; ``mapping`` is canonical name -> index."""
    return 0.5 * sum(leg_length(rest_positions, mapping[f"{s}_hip"], mapping[f"{s}_knee"], mapping[f"{s}_ankle"]) for s in "lr")


def standing_height_from_legs(rest_positions: np.ndarray, mapping: dict[str, int]) -> float:
    """Standing height estimated from the leg bones (rigs differ far more in torso than in legs)."""
    return mean_leg_length(rest_positions, mapping) * CANONICAL_HEIGHT / _canonical_leg_length()


CANONICAL_HEIGHT = 1.70


def _frame(up: np.ndarray, lateral: np.ndarray) -> np.ndarray:
    """Orthonormal frame (columns x=lateral, y=up, z=forward) from an up and a left-right vector."""
    y = normalize(up)
    x = normalize(lateral - (lateral * y).sum(-1, keepdims=True) * y)
    z = np.cross(x, y)
    return np.stack([x, y, z], -1)


def _reference(c: int, mapping: dict[int, int], src_rest: np.ndarray, child: int, min_len: float) -> int | None:
    """First mapped canonical descendant along ``child``'s chain at a non-zero source distance from c."""
    k: int | None = child
    while k is not None:
        if k in mapping and np.linalg.norm(src_rest[mapping[k]] - src_rest[mapping[c]]) > min_len:
            return k
        kids = [i for i, p in enumerate(PARENTS) if p == k]
        k = kids[0] if kids else None
    return None


def rest_is_standing(src_rest: np.ndarray, mapping: dict[int, int]) -> bool:
    """Whether the source's zero pose stands: the spine points away from the legs.

    Rigs exported with their joint orientations baked into the channels (Bandai-Namco: every bone
    along +x in the zero pose, the legs folded onto the spine) have no usable rest pose; their
    twist about each bone is then taken from the clip itself (:func:`remove_rig_roll`).
    """
    pelvis = src_rest[mapping[JOINT_INDEX["pelvis"]]]
    up = normalize(src_rest[mapping[JOINT_INDEX["neck"]]] - pelvis)
    legs = normalize(src_rest[[mapping[JOINT_INDEX["l_ankle"]], mapping[JOINT_INDEX["r_ankle"]]]] - pelvis)
    return bool((legs @ up < -0.5).all())  # each leg more than 120 degrees from the spine


def _mean_rotation(rotations: np.ndarray) -> np.ndarray:
    """The rotation nearest the element-wise mean of (T, 3, 3) rotations (chordal L2 mean)."""
    u, _, vt = np.linalg.svd(rotations.mean(0))
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def remove_rig_roll(glob: np.ndarray, g_src: np.ndarray, mapping: dict[int, int], bones: dict[int, np.ndarray],
                    leaves: list[int]) -> None:
    """Take each joint's constant twist offset (the rig's roll) out of ``glob`` in place.

    A bone joint's rotation keeps its direction (exact from the positions) and its twist about the
    bone relative to the canonical parent varies as in the source, but the clip-mean twist is
    removed; a leaf keeps its rotation relative to its parent less the clip-mean of it. Joints run
    parents first, so each is measured against its already corrected parent.
    """
    for c in range(1, len(JOINT_NAMES)):
        parent = PARENTS[c]
        if c in bones:
            v = normalize(bones[c])
            d = glob[:, c] @ v  # the bone direction in the world, exact
            swing = rotation_between(glob[:, parent] @ v, d) @ glob[:, parent]  # twist of the parent
            twist = np.swapaxes(swing, -1, -2) @ glob[:, c]  # a rotation about v
            angle = np.arctan2(twist[:, [2, 0, 1], [1, 2, 0]] @ v - twist[:, [1, 2, 0], [2, 0, 1]] @ v,
                               np.trace(twist, axis1=1, axis2=2) - 1.0)
            offset = np.arctan2(np.sin(angle).mean(), np.cos(angle).mean())
            glob[:, c] = glob[:, c] @ axis_angle_to_matrix(-offset * v)
        elif c in leaves:
            s, p = mapping[c], mapping.get(parent)
            if p is None:
                continue
            relative = np.swapaxes(g_src[:, p], -1, -2) @ g_src[:, s]  # in the source parent's axes
            to_canon = _mean_rotation(np.swapaxes(g_src[:, p], -1, -2) @ glob[:, parent])
            neutral = _mean_rotation(relative)
            glob[:, c] = glob[:, parent] @ to_canon.T @ relative @ neutral.T @ to_canon
        else:
            glob[:, c] = glob[:, parent] if c not in mapping else glob[:, c]


def retarget(src: SourceMotion, mapping_by_name: dict[str, int], ground: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Return canonical (local rotations (T,22,3,3), root translation (T,3))."""
    mapping = {JOINT_INDEX[c]: s for c, s in mapping_by_name.items()}
    n_frames = src.global_rotations.shape[0]
    canon_rest = CANONICAL.rest_positions()
    src_rest = src.rest_positions
    min_len = 1e-3 * max(1e-6, float(np.ptp(src_rest[:, 1])))
    g_src, p_src = src.global_rotations, src.global_positions
    glob = np.zeros((n_frames, len(JOINT_NAMES), 3, 3))
    align = {}  # rest alignment per canonical joint, used by leaves
    bones: dict[int, np.ndarray] = {}  # single-bone joints: the canonical rest bone they follow
    leaves: list[int] = []
    children = {j: [i for i, p in enumerate(PARENTS) if p == j] for j in range(len(JOINT_NAMES))}
    for c in range(len(JOINT_NAMES)):
        parent = PARENTS[c]
        if c not in mapping:
            glob[:, c] = glob[:, parent]
            align[c] = align.get(parent, np.eye(3))
            continue
        s = mapping[c]
        refs = [r for r in (_reference(c, mapping, src_rest, k, min_len) for k in children[c]) if r is not None]
        if len(children[c]) == 3 and len(refs) == 3:
            # pelvis / upper spine: up = centre child, lateral = left child minus right child.
            lefts = [r for r in refs if JOINT_NAMES[r].startswith("l_")]
            rights = [r for r in refs if JOINT_NAMES[r].startswith("r_")]
            centre = next(r for r in refs if r not in lefts + rights)
            v_frame = _frame(canon_rest[centre] - canon_rest[c], canon_rest[lefts[0]] - canon_rest[rights[0]])
            u_frame = _frame(p_src[:, mapping[centre]] - p_src[:, s], p_src[:, mapping[lefts[0]]] - p_src[:, mapping[rights[0]]])
            rest_frame = _frame(src_rest[mapping[centre]] - src_rest[s], src_rest[mapping[lefts[0]]] - src_rest[mapping[rights[0]]])
            glob[:, c] = u_frame @ v_frame.T
            align[c] = rest_frame @ v_frame.T
        elif refs:
            r = refs[0]
            v = canon_rest[r] - canon_rest[c]
            # Rest alignment by the smallest turn from where the parent's alignment already puts the
            # bone: the twist about the bone stays the parent's rest twist.
            parent_align = align.get(parent, np.eye(3))
            a = rotation_between(parent_align @ v, src_rest[mapping[r]] - src_rest[s]) @ parent_align
            r0 = g_src[:, s] @ a
            q = rotation_between(r0 @ v, p_src[:, mapping[r]] - p_src[:, s])
            glob[:, c] = q @ r0
            align[c] = a
            bones[c] = v
        else:
            a = align.get(parent, np.eye(3))
            glob[:, c] = g_src[:, s] @ a
            align[c] = a
            leaves.append(c)
    if not rest_is_standing(src_rest, mapping):
        remove_rig_roll(glob, g_src, mapping, bones, leaves)
    local = global_to_local(glob, PARENTS)
    pelvis = mapping[JOINT_INDEX["pelvis"]]
    root = p_src[:, pelvis] * (_canonical_leg_length() / mean_leg_length(src_rest, mapping_by_name))
    if ground:
        root = ground_align(local, root)
    return local, root


def ground_align(local: np.ndarray, root: np.ndarray) -> np.ndarray:
    """Shift the root vertically so the feet's sole points stand on y = 0.

    The lowest sole point per frame is ~0 whenever a foot is planted; its 10th percentile over the
    clip is taken as the floor, which is robust to jumps and hops (airborne frames are higher).
    """
    motion = Motion(local, root)
    floor = float(np.percentile(motion.lowest_foot_height(), 10))
    out = root.astype(np.float64).copy()
    out[:, 1] -= floor
    return out


def check_source(src: SourceMotion) -> None:
    if not (np.isfinite(src.global_positions).all() and np.isfinite(src.global_rotations).all()):
        raise MotionError(src.path, "non-finite values after forward kinematics")
