"""Your character: a skinned glTF / GLB's mesh in its bind pose and its 22 canonical joints, in the
project's frame, ready for :func:`~.fit.fit_body`.

    character = read_character("hero.glb")          # the first skin's meshes (or skin=N)
    character.vertices, character.faces, character.joints
    fitted = fit_body(character.vertices, character.joints)

What is read: every mesh primitive of triangles (TRIANGLES, strips and fans) on a node skinned to the
skin, concatenated; its POSITION and indices. The skin's joints are mapped onto the canonical 22 by
name (:mod:`hrr_garment.motion.joint_maps`: Mixamo, SMPL, CMU, ... or a user's joint map).

Where it is placed: by the glTF rule for skinned meshes, the mesh node's own transform is ignored and
a vertex ``v`` is drawn at ``W_j @ IBM_j @ v`` for each of its joints ``j`` (``W_j`` the joint's
world matrix through the node tree, ``IBM_j`` its inverse bind matrix). In a file whose joints stand
in the bind pose, ``B = W_j @ IBM_j`` is the same matrix for every joint (the skin's space to the
world: an armature's centimetre scale, a Z-up root's turn) and the mesh is ``B @ v``. Where some
joints' nodes are posed away from the bind pose, ``B`` is the matrix most joints agree on, and the
mesh and all joints are read in the bind pose (the joints at ``B @ inverse(IBM_j)``); the joints
found posed are reported. World units are metres by glTF's rule; a file whose legs say otherwise
(centimetres without a scaling node) is scaled as motion files are. glTF is Y up and faces +Z, as the
project does; a character authored on other axes without a root turn is turned onto them by the
nearest quarter turns (its head above its pelvis, its left at +X). Finally the soles are put on
y = 0 and the pelvis over the origin.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..motion.bvh_motion import PLAUSIBLE_HEIGHT_M
from ..motion.gltf import world_unit_scale
from ..motion.gltf_file import open_gltf, rest_world_matrices
from ..motion.joint_maps import resolve_joint_map
from ..motion.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS, REST_OFFSETS
from .body_file import BodyRecord
from .fit import PRIMARY_CHILD, fit_body
from .mesh_record import MAX_MESH_FACES, MAX_MESH_VERTICES, BodyMesh
from .skinned_mesh import bind_matrices, canonical_weights, read_mesh, skinned_meshes

_BIND_TOLERANCE = 1e-4  # relative: joints whose W @ IBM differ by more are posed away from the bind pose
STATURE_RANGE_M = (0.3, 3.0)  # what body.json accepts


@dataclass(frozen=True)
class Character:
    """A character's rest mesh and canonical joints in the project's frame (see the module docstring)."""

    vertices: np.ndarray  # (V, 3) float64 metres, Y up, facing +Z, soles on y = 0, pelvis over the origin
    faces: np.ndarray  # (F, 3) int64
    joints: np.ndarray  # (22, 3) the canonical joints in the same frame
    skin: int  # the skin read
    scheme: str  # the joint naming scheme matched (mixamo, smpl, ..., custom)
    unit_scale: float  # metres per world unit of the file (1: metres, as glTF says)
    posed_joints: tuple[str, ...] = ()  # skin joints whose nodes stood away from the bind pose
    turned: bool = False  # True when quarter turns were needed to stand it Y up, facing +Z
    filled_joints: tuple[str, ...] = ()  # optional canonical joints the skin lacks, placed between others
    # (V, 22) float32 each vertex's skin weights gathered onto the canonical joints (a joint the
    # canonical skeleton lacks, a finger or a twist bone, gives its weight to its nearest canonical
    # ancestor); None where the mesh carries no weights
    weights: np.ndarray | None = None


def _skin_to_world(world: np.ndarray, ibm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The skin's space to the world: the ``W_j @ IBM_j`` most joints agree on, and which joints
    disagree (stand posed away from the bind pose)."""
    b = world @ ibm
    size = max(float(np.abs(b[:, :3, :3]).max()), 1e-12)
    reach = max(float(np.abs(world[:, :3, 3]).max()), size)
    gap = (
        np.abs(b[:, None, :3, :3] - b[None, :, :3, :3]).max((-1, -2)) / size
        + np.abs(b[:, None, :3, 3] - b[None, :, :3, 3]).max(-1) / reach
    )
    agree = gap <= _BIND_TOLERANCE
    best = int(np.argmax(agree.sum(1)))
    return b[best], ~agree[best]


def _fill_optional(joints: dict[str, np.ndarray], path: Path) -> tuple[np.ndarray, tuple[str, ...]]:
    """(22, 3) canonical joints; an optional joint the skin lacks (spine2, a collar, a toe) is put
    along its parent-to-child bone at the canonical fraction, or a toe ahead of its ankle."""
    filled = []
    for name in JOINT_NAMES:
        if name in joints:
            continue
        j = JOINT_INDEX[name]
        parent = joints[JOINT_NAMES[PARENTS[j]]]
        child = PRIMARY_CHILD.get(name)
        if child is not None and child in joints:
            own, onward = np.linalg.norm(REST_OFFSETS[j]), np.linalg.norm(REST_OFFSETS[JOINT_INDEX[child]])
            joints[name] = parent + (joints[child] - parent) * own / (own + onward)
        else:
            grand = joints[JOINT_NAMES[PARENTS[PARENTS[j]]]]
            scale = np.linalg.norm(parent - grand) / np.linalg.norm(REST_OFFSETS[PARENTS[j]])
            joints[name] = parent + REST_OFFSETS[j] * scale
        filled.append(name)
    out = np.stack([joints[n] for n in JOINT_NAMES])
    if not np.isfinite(out).all():
        raise InputError(path, "the skin's joint transforms are not finite")
    return out, tuple(filled)


BIPED_MIN_COS = 0.5  # legs within 60 degrees of straight down the spine's line: a human standing at rest


def _check_biped(joints: np.ndarray, path: Path) -> None:
    """Refuse a skeleton whose legs do not hang opposite its spine (a four-legged animal's: spine
    level, legs down), which no turn stands up as a human; its fit would be meaningless."""
    up = joints[JOINT_INDEX["head"]] - joints[JOINT_INDEX["pelvis"]]
    down = joints[[JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"]]].mean(0) - joints[
        [JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]]
    ].mean(0)
    cos = float(-(up @ down) / max(np.linalg.norm(up) * np.linalg.norm(down), 1e-12))
    if cos < BIPED_MIN_COS:
        angle = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        raise InputError(
            path,
            f"not a human skeleton: its legs run {angle:.0f} degrees off the line of its spine "
            "(a human's hang straight on from it; a four-legged animal's stand across it), so no "
            "body can be fitted; only a two-legged human rig can be read as a character",
        )


def _upright(joints: np.ndarray) -> np.ndarray:
    """The quarter-turn rotation (one of 24) that best stands ``joints`` up: head above pelvis
    along +Y, its left (left hip and shoulder minus right) along +X."""
    up = joints[JOINT_INDEX["head"]] - joints[JOINT_INDEX["pelvis"]]
    left = sum(joints[JOINT_INDEX[f"l_{j}"]] - joints[JOINT_INDEX[f"r_{j}"]] for j in ("hip", "shoulder"))
    best, score = np.eye(3), -np.inf
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            r = np.zeros((3, 3))
            r[range(3), perm] = signs
            if np.linalg.det(r) > 0:
                s = (r @ up)[1] / (np.linalg.norm(up) + 1e-12) + (r @ left)[0] / (
                    np.linalg.norm(left) + 1e-12
                )
                if s > score + 1e-9:
                    best, score = r, s
    return best


def read_character(
    path: str | Path, skin: int | None = None, joint_map: dict | None = None, unit_scale: float | None = None
) -> Character:
    """A skinned glTF / GLB's mesh in its bind pose and its canonical joints, in the project's frame
    (the module docstring says how). ``skin``: which skin (default: the one with the most skinned
    vertices); ``joint_map``: canonical joint -> the file's joint name; ``unit_scale``: metres per
    world unit (default 1, detected from the legs when that gives no plausible human height)."""
    doc = open_gltf(path)
    path = doc.path
    if "KHR_draco_mesh_compression" in (doc.doc.extensionsUsed or []):
        raise doc.fail(
            "its meshes are Draco-compressed (KHR_draco_mesh_compression), which pygltflib does not "
            "decode; export it without mesh compression"
        )
    skin, meshes = skinned_meshes(doc, skin)
    joint_nodes = list(doc.doc.skins[skin].joints or [])
    if not joint_nodes or not all(isinstance(j, int) and 0 <= j < len(doc.doc.nodes) for j in joint_nodes):
        raise doc.fail(f"skin {skin} has no joints or names nodes that are missing")
    names = [doc.doc.nodes[j].name or f"node_{j}" for j in joint_nodes]
    scheme, mapping = resolve_joint_map(names, str(path), joint_map)
    ibm = bind_matrices(doc, skin, joint_nodes)
    world = rest_world_matrices(doc)[joint_nodes]
    if not (np.isfinite(world).all() and np.isfinite(ibm).all()):
        raise doc.fail("the node transforms or inverse bind matrices are not finite")
    bind, posed = _skin_to_world(world, ibm)
    if abs(np.linalg.det(bind[:3, :3])) < 1e-12:
        raise doc.fail(
            f"skin {skin}'s bind pose is degenerate (its joints times their inverse bind matrices are "
            "singular)"
        )
    vertices, faces, skinning = read_mesh(doc, meshes)
    vertices = vertices @ bind[:3, :3].T + bind[:3, 3]
    try:
        bind_joints = np.stack([bind @ np.linalg.inv(m) for m in ibm])[:, :3, 3]
    except np.linalg.LinAlgError:
        raise doc.fail(f"skin {skin} has an inverse bind matrix that cannot be inverted") from None
    # a short character (a child's body) is still in metres down to half the shortest adult
    scale = world_unit_scale(
        path, bind_joints, mapping, unit_scale=unit_scale, shortest_m=PLAUSIBLE_HEIGHT_M[0] / 2
    )
    joints, filled = _fill_optional({c: bind_joints[i] * scale for c, i in mapping.items()}, path)
    _check_biped(joints, path)
    turn = _upright(joints)
    vertices, joints = vertices * scale @ turn.T, joints @ turn.T
    shift = np.array([joints[0, 0], vertices[:, 1].min(), joints[0, 2]])
    if not np.isfinite(vertices).all():
        raise doc.fail("the skinned mesh's vertices are not finite in the world")
    weights = None if skinning is None else canonical_weights(doc, skinning, joint_nodes, mapping=mapping)
    return Character(
        vertices - shift,
        faces,
        joints - shift,
        skin,
        scheme,
        scale,
        posed_joints=tuple(names[i] for i in np.flatnonzero(posed)),
        turned=not np.allclose(turn, np.eye(3)),
        filled_joints=filled,
        weights=weights,
    )


def character_body(
    path: str | Path, skin: int | None = None, joint_map: dict | None = None, unit_scale: float | None = None
) -> tuple[BodyRecord, Character]:
    """The body of a skinned character file (``hrr-body fit`` writes it; ``hrr-animate --body``
    reads it in place): :func:`read_character`, then the skeleton and capsules fitted to its mesh
    (:func:`~.fit.fit_body`), and the mesh itself with its skin weights where it can be kept
    (:func:`own_mesh`: the body the viewer sees). An :class:`~hrr_garment.errors.InputError` naming
    the file where the mesh cannot be fitted or the character is not of a human's height."""
    character = read_character(path, skin=skin, joint_map=joint_map, unit_scale=unit_scale)
    try:
        fitted = fit_body(character.vertices, character.joints)
    except ValueError as exc:
        raise InputError(path, f"cannot fit a body to its mesh: {exc}") from None
    lo, hi = STATURE_RANGE_M
    if not lo <= fitted.stature <= hi:
        raise InputError(
            path,
            f"the character is {fitted.stature:.3g} m tall, not within [{lo}, {hi}] m; "
            "if the file is not in metres, pass --unit-scale (metres per file unit)",
        )
    return BodyRecord(
        fitted.skeleton,
        fitted.body,
        pelvis_height=fitted.pelvis_height,
        stature=fitted.stature,
        report=fitted.report,
        mesh=own_mesh(character),
    ), character


def own_mesh(character: Character) -> BodyMesh | None:
    """The character's skinned mesh as its body record keeps it, or None where its file carries no
    skin weights or the mesh is larger than body.json keeps (:data:`~.mesh_record.MAX_MESH_VERTICES`):
    such a body is then drawn and collided as its capsules."""
    if character.weights is None or not (
        len(character.vertices) <= MAX_MESH_VERTICES and len(character.faces) <= MAX_MESH_FACES
    ):
        return None
    return BodyMesh.of_character(character)
