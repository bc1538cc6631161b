"""Retargeting a source skeleton's motion onto the canonical skeleton.

Joints are matched by name (:mod:`.joint_maps`: built-in naming schemes, or a user map in YAML). Rotations are
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

import numpy as np

from ..errors import MotionError
from .motion import Motion
from .resample import frame_chunks
from .rotations import axis_angle_to_matrix, normalize, rotation_between
from .skeleton import CANONICAL, JOINT_INDEX, JOINT_NAMES, PARENTS, global_to_local


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


def leg_length(rest_positions: np.ndarray, hip: int, knee: int, ankle: int) -> float:
    """Hip to knee plus knee to ankle, in the rest pose."""
    return float(
        np.linalg.norm(rest_positions[knee] - rest_positions[hip])
        + np.linalg.norm(rest_positions[ankle] - rest_positions[knee])
    )


def _canonical_leg_length() -> float:
    return mean_leg_length(CANONICAL.rest_positions(), JOINT_INDEX)


def mean_leg_length(rest_positions: np.ndarray, mapping: dict[str, int]) -> float:
    """Hip-knee-ankle length averaged over both legs; ``mapping`` is canonical name -> index."""
    return 0.5 * sum(
        leg_length(rest_positions, mapping[f"{s}_hip"], mapping[f"{s}_knee"], mapping[f"{s}_ankle"])
        for s in "lr"
    )


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


def _reference(
    c: int, mapping: dict[int, int], src_rest: np.ndarray, child: int, min_len: float
) -> int | None:
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


def remove_rig_roll(
    glob: np.ndarray,
    g_src: np.ndarray,
    mapping: dict[int, int],
    bones: dict[int, np.ndarray],
    leaves: list[int],
    roll: dict | None = None,
) -> dict:
    """Take each joint's constant twist offset (the rig's roll) out of ``glob`` in place; returns
    the offsets it took out (``roll``: take out these instead of measuring them on this clip).

    A bone joint's rotation keeps its direction (exact from the positions) and its twist about the
    bone relative to the canonical parent varies as in the source, but the clip-mean twist is
    removed; a leaf keeps its rotation relative to its parent less the clip-mean of it. Joints run
    parents first, so each is measured against its already corrected parent.
    """
    used: dict = {}
    for c in range(1, len(JOINT_NAMES)):
        parent = PARENTS[c]
        if c in bones:
            v = normalize(bones[c])
            if roll is None:
                d = glob[:, c] @ v  # the bone direction in the world, exact
                swing = rotation_between(glob[:, parent] @ v, d) @ glob[:, parent]  # twist of the parent
                twist = np.swapaxes(swing, -1, -2) @ glob[:, c]  # a rotation about v
                angle = np.arctan2(
                    twist[:, [2, 0, 1], [1, 2, 0]] @ v - twist[:, [1, 2, 0], [2, 0, 1]] @ v,
                    np.trace(twist, axis1=1, axis2=2) - 1.0,
                )
                used[c] = float(np.arctan2(np.sin(angle).mean(), np.cos(angle).mean()))
            else:
                used[c] = roll[c]
            glob[:, c] = glob[:, c] @ axis_angle_to_matrix(-used[c] * v)
        elif c in leaves:
            s, p = mapping[c], mapping.get(parent)
            if p is None:
                continue
            relative = np.swapaxes(g_src[:, p], -1, -2) @ g_src[:, s]  # in the source parent's axes
            if roll is None:
                used[c] = (
                    _mean_rotation(np.swapaxes(g_src[:, p], -1, -2) @ glob[:, parent]),
                    _mean_rotation(relative),
                )
            else:
                used[c] = roll[c]
            to_canon, neutral = used[c]
            glob[:, c] = glob[:, parent] @ to_canon.T @ relative @ neutral.T @ to_canon
        elif c not in mapping:  # follows its corrected parent rigidly
            glob[:, c] = glob[:, parent]
    return used


@dataclass(frozen=True)
class RetargetCalibration:
    """What retargeting measures on a whole clip, fixed for a stream of single poses: each joint's
    rig roll (None for a rig whose rest pose stands: nothing to measure) and the floor, the height
    of the feet's sole points that the root is lowered by (:func:`clip_floor`)."""

    roll: dict | None
    floor: float


def retarget(
    src: SourceMotion,
    mapping_by_name: dict[str, int],
    ground: bool = True,
    calibration: RetargetCalibration | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Return canonical (local rotations (T,22,3,3), root translation (T,3)). The rig roll and the
    floor are measured on this clip, or taken from ``calibration`` (a stream's poses one by one)."""
    local, root, _ = _retarget(src, mapping_by_name, None if calibration is None else calibration.roll)
    if ground:
        root = root.copy()
        root[:, 1] -= clip_floor(local, root, src.path or "") if calibration is None else calibration.floor
    return local, root


def calibrate_retarget(src: SourceMotion, mapping_by_name: dict[str, int]) -> RetargetCalibration:
    """The rig roll and floor of a whole clip, for :func:`retarget` of other poses on the same rig."""
    local, root, roll = _retarget(src, mapping_by_name, None)
    return RetargetCalibration(roll, clip_floor(local, root))


def _retarget(
    src: SourceMotion, mapping_by_name: dict[str, int], roll: dict | None
) -> tuple[np.ndarray, np.ndarray, dict | None]:
    """Canonical local rotations, the root before grounding, and the rig roll taken out (None: none)."""
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
        refs = [
            r for r in (_reference(c, mapping, src_rest, k, min_len) for k in children[c]) if r is not None
        ]
        if len(children[c]) == 3 and len(refs) == 3:
            # pelvis / upper spine: up = centre child, lateral = left child minus right child.
            lefts = [r for r in refs if JOINT_NAMES[r].startswith("l_")]
            rights = [r for r in refs if JOINT_NAMES[r].startswith("r_")]
            centre = next(r for r in refs if r not in lefts + rights)
            v_frame = _frame(canon_rest[centre] - canon_rest[c], canon_rest[lefts[0]] - canon_rest[rights[0]])
            u_frame = _frame(
                p_src[:, mapping[centre]] - p_src[:, s],
                p_src[:, mapping[lefts[0]]] - p_src[:, mapping[rights[0]]],
            )
            rest_frame = _frame(
                src_rest[mapping[centre]] - src_rest[s],
                src_rest[mapping[lefts[0]]] - src_rest[mapping[rights[0]]],
            )
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
    used = (
        None
        if rest_is_standing(src_rest, mapping)
        else remove_rig_roll(glob, g_src, mapping, bones, leaves, roll)
    )
    local = global_to_local(glob, PARENTS)
    pelvis = mapping[JOINT_INDEX["pelvis"]]
    root = p_src[:, pelvis] * (_canonical_leg_length() / mean_leg_length(src_rest, mapping_by_name))
    return local, root, used


def clip_floor(local: np.ndarray, root: np.ndarray, source: str = "") -> float:
    """The height of the floor under a clip: the 10th percentile over its frames of the lowest sole
    point. That point is ~0 whenever a foot is planted, and the percentile is robust to jumps and
    hops (airborne frames are higher). ``source`` names the clip in errors."""
    heights = [
        Motion(local[a:b], root[a:b], source=source).lowest_foot_height() for a, b in frame_chunks(len(local))
    ]
    return float(np.percentile(np.concatenate(heights), 10))


def ground_align(local: np.ndarray, root: np.ndarray) -> np.ndarray:
    """Shift the root vertically so the feet's sole points stand on y = 0 (:func:`clip_floor`)."""
    out = root.astype(np.float64).copy()
    out[:, 1] -= clip_floor(local, root)
    return out


def check_source(src: SourceMotion) -> None:
    """Refuse a source motion with non-finite values after forward kinematics."""
    if not (np.isfinite(src.global_positions).all() and np.isfinite(src.global_rotations).all()):
        raise MotionError(src.path, "non-finite values after forward kinematics")
