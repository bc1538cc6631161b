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
from ..motion.gltf_file import node_parents, open_gltf, rest_world_matrices
from ..motion.joint_maps import resolve_joint_map
from ..motion.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS, REST_OFFSETS
from .body_file import BodyRecord
from .fit import PRIMARY_CHILD, fit_body

MAX_VERTICES = 2_000_000  # a game or film character has well under a million
_TRIANGLE_MODES = (4, 5, 6)  # TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN
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


def _skinned_meshes(doc, skin: int | None) -> tuple[int, list[int]]:
    """The skin to read and the meshes skinned to it (each once)."""
    gl = doc.doc
    skins = gl.skins or []
    if not skins:
        raise doc.fail("the file has no skin: a character is read from a mesh skinned to a skeleton")
    if skin is not None and not (isinstance(skin, int) and 0 <= skin < len(skins)):
        raise doc.fail(f"no skin {skin!r}: the file has {len(skins)} (0 to {len(skins) - 1})")
    meshes: dict[int, list[int]] = {}
    for node in gl.nodes:
        if node.mesh is not None and node.skin is not None and 0 <= node.skin < len(skins):
            if not (isinstance(node.mesh, int) and 0 <= node.mesh < len(gl.meshes or [])):
                raise doc.fail(f"a node names mesh {node.mesh}, which is missing")
            meshes.setdefault(node.skin, [])
            if node.mesh not in meshes[node.skin]:
                meshes[node.skin].append(node.mesh)
    if skin is None:
        if not meshes:
            raise doc.fail("no mesh is skinned: no node has both a mesh and a skin")
        skin = max(meshes, key=lambda s: (sum(_vertex_count(doc, m) for m in meshes[s]), -s))
    if not meshes.get(skin):
        raise doc.fail(f"no mesh is skinned to skin {skin}")
    return skin, meshes[skin]


def _vertex_count(doc, mesh: int) -> int:
    total = 0
    for prim in doc.doc.meshes[mesh].primitives or []:
        position = prim.attributes.POSITION if prim.attributes is not None else None
        if (prim.mode if prim.mode is not None else 4) in _TRIANGLE_MODES and position is not None:
            try:
                total += int(doc.doc.accessors[position].count)
            except (IndexError, TypeError):
                raise doc.fail(f"mesh {mesh} names POSITION accessor {position}, which is missing") from None
    return total


def _triangles(indices: np.ndarray, mode: int) -> np.ndarray:
    """(F, 3) triangles of a primitive's index list in its mode (strips and fans unrolled)."""
    if mode == 4:
        return indices[: len(indices) // 3 * 3].reshape(-1, 3)
    n = max(len(indices) - 2, 0)
    if mode == 5:  # strip: every other triangle turned back to keep the winding
        tri = np.stack([indices[:n], indices[1:n + 1], indices[2:n + 2]], 1)
        tri[1::2] = tri[1::2][:, [1, 0, 2]]
        return tri
    return np.stack([np.full(n, indices[0] if len(indices) else 0), indices[1:n + 1], indices[2:n + 2]], 1)


def _read_mesh(doc, meshes: list[int]) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """The meshes' triangle primitives as one (V, 3) vertex and (F, 3) face array, in the skin's
    space, and their skin joints and weights (V, 4) each (None unless every primitive has them)."""
    vertices, faces, skinning, offset = [], [], [], 0
    for m in meshes:
        for p, prim in enumerate(doc.doc.meshes[m].primitives or []):
            mode = prim.mode if prim.mode is not None else 4
            position = prim.attributes.POSITION if prim.attributes is not None else None
            if mode not in _TRIANGLE_MODES or position is None:
                continue  # points and lines are no surface
            v = doc.accessor(position, raw_integers=True)
            if v.shape[1] != 3:
                raise doc.fail(f"mesh {m} primitive {p}: POSITION must be VEC3")
            idx = (np.arange(len(v)) if prim.indices is None
                   else doc.accessor(prim.indices, raw_integers=True)[:, 0].astype(np.int64))
            if len(idx) and (idx.min() < 0 or idx.max() >= len(v)):
                raise doc.fail(f"mesh {m} primitive {p}: an index reaches past its {len(v)} vertices")
            vertices.append(v)
            faces.append(_triangles(idx, mode) + offset)
            skinning.append(_skin_weights(doc, prim.attributes, len(v)))
            offset += len(v)
            if offset > MAX_VERTICES:
                raise doc.fail(f"the skinned meshes hold over {MAX_VERTICES} vertices; decimate the character first")
    if not vertices:
        raise doc.fail(f"the meshes skinned to the skin ({meshes}) have no triangles")
    weights = None
    if all(w is not None for w in skinning):
        weights = (np.concatenate([j for j, _ in skinning]), np.concatenate([w for _, w in skinning]))
    return np.concatenate(vertices), np.concatenate(faces), weights


def _skin_weights(doc, attributes, count: int) -> tuple[np.ndarray, np.ndarray] | None:
    """A primitive's JOINTS_0 (indices into the skin's joints) and WEIGHTS_0, (V, 4) each, or None."""
    joints, weights = getattr(attributes, "JOINTS_0", None), getattr(attributes, "WEIGHTS_0", None)
    if joints is None or weights is None:
        return None
    j, w = doc.accessor(joints, raw_integers=True), doc.accessor(weights)
    if j.shape != (count, 4) or w.shape != (count, 4):
        raise doc.fail(f"JOINTS_0 and WEIGHTS_0 must be VEC4 for each of the {count} vertices")
    return j.astype(np.int64), w


def _canonical_weights(doc, skinning: tuple[np.ndarray, np.ndarray], joint_nodes: list[int],
                       mapping: dict[str, int]) -> np.ndarray:
    """(V, 22) each vertex's weights gathered onto the canonical joints: a skin joint that is not
    one of them gives its weight to its nearest mapped ancestor (the pelvis where it has none)."""
    joints, weights = skinning
    if joints.size and (joints.min() < 0 or joints.max() >= len(joint_nodes)):
        raise doc.fail(f"JOINTS_0 names a joint outside the skin's {len(joint_nodes)}")
    parents = node_parents(doc)
    canonical = {joint_nodes[i]: JOINT_INDEX[c] for c, i in mapping.items()}
    owner = np.zeros(len(joint_nodes), np.int64)
    for i, node in enumerate(joint_nodes):
        while node >= 0 and node not in canonical:
            node = parents[node]
        owner[i] = canonical.get(node, 0)
    out = np.zeros((len(joints), len(JOINT_NAMES)))
    np.add.at(out, (np.repeat(np.arange(len(joints)), joints.shape[1]), owner[joints].ravel()), weights.ravel())
    total = out.sum(1, keepdims=True)
    out[total[:, 0] <= 0, 0], total[total <= 0] = 1.0, 1.0  # a vertex weighted to nothing follows the pelvis
    return (out / total).astype(np.float32)


def _bind_matrices(doc, skin: int, joints: list[int]) -> np.ndarray:
    """(J, 4, 4) the skin's inverse bind matrices."""
    accessor = doc.doc.skins[skin].inverseBindMatrices
    if accessor is None:
        raise doc.fail(f"skin {skin} has no inverseBindMatrices, so its bind pose is unknown")
    ibm = doc.accessor(accessor)
    if ibm.shape != (len(joints), 16):
        raise doc.fail(f"skin {skin}'s inverseBindMatrices hold {ibm.shape[0]} MAT4 for {len(joints)} joints")
    return np.swapaxes(ibm.reshape(-1, 4, 4), 1, 2)  # glTF matrices are column-major


def _skin_to_world(world: np.ndarray, ibm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The skin's space to the world: the ``W_j @ IBM_j`` most joints agree on, and which joints
    disagree (stand posed away from the bind pose)."""
    b = world @ ibm
    size = max(float(np.abs(b[:, :3, :3]).max()), 1e-12)
    reach = max(float(np.abs(world[:, :3, 3]).max()), size)
    gap = (np.abs(b[:, None, :3, :3] - b[None, :, :3, :3]).max((-1, -2)) / size
           + np.abs(b[:, None, :3, 3] - b[None, :, :3, 3]).max(-1) / reach)
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
    down = (joints[[JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"]]].mean(0)
            - joints[[JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]]].mean(0))
    cos = float(-(up @ down) / max(np.linalg.norm(up) * np.linalg.norm(down), 1e-12))
    if cos < BIPED_MIN_COS:
        angle = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        raise InputError(path, f"not a human skeleton: its legs run {angle:.0f} degrees off the line of its spine "
                               "(a human's hang straight on from it; a four-legged animal's stand across it), so no "
                               "body can be fitted; only a two-legged human rig can be read as a character")


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
                s = (r @ up)[1] / (np.linalg.norm(up) + 1e-12) + (r @ left)[0] / (np.linalg.norm(left) + 1e-12)
                if s > score + 1e-9:
                    best, score = r, s
    return best


def read_character(path: str | Path, skin: int | None = None, joint_map: dict | None = None,
                   unit_scale: float | None = None) -> Character:
    """A skinned glTF / GLB's mesh in its bind pose and its canonical joints, in the project's frame
    (the module docstring says how). ``skin``: which skin (default: the one with the most skinned
    vertices); ``joint_map``: canonical joint -> the file's joint name; ``unit_scale``: metres per
    world unit (default 1, detected from the legs when that gives no plausible human height)."""
    doc = open_gltf(path)
    path = doc.path
    if "KHR_draco_mesh_compression" in (doc.doc.extensionsUsed or []):
        raise doc.fail("its meshes are Draco-compressed (KHR_draco_mesh_compression), which pygltflib does not "
                       "decode; export it without mesh compression")
    skin, meshes = _skinned_meshes(doc, skin)
    joint_nodes = list(doc.doc.skins[skin].joints or [])
    if not joint_nodes or not all(isinstance(j, int) and 0 <= j < len(doc.doc.nodes) for j in joint_nodes):
        raise doc.fail(f"skin {skin} has no joints or names nodes that are missing")
    names = [doc.doc.nodes[j].name or f"node_{j}" for j in joint_nodes]
    scheme, mapping = resolve_joint_map(names, str(path), joint_map)
    ibm = _bind_matrices(doc, skin, joint_nodes)
    world = rest_world_matrices(doc)[joint_nodes]
    if not (np.isfinite(world).all() and np.isfinite(ibm).all()):
        raise doc.fail("the node transforms or inverse bind matrices are not finite")
    bind, posed = _skin_to_world(world, ibm)
    if abs(np.linalg.det(bind[:3, :3])) < 1e-12:
        raise doc.fail(f"skin {skin}'s bind pose is degenerate (its joints times their inverse bind matrices are singular)")
    vertices, faces, skinning = _read_mesh(doc, meshes)
    vertices = vertices @ bind[:3, :3].T + bind[:3, 3]
    try:
        bind_joints = np.stack([bind @ np.linalg.inv(m) for m in ibm])[:, :3, 3]
    except np.linalg.LinAlgError:
        raise doc.fail(f"skin {skin} has an inverse bind matrix that cannot be inverted") from None
    # a short character (a child's body) is still in metres down to half the shortest adult
    scale = world_unit_scale(path, bind_joints, mapping, unit_scale=unit_scale, shortest_m=PLAUSIBLE_HEIGHT_M[0] / 2)
    joints, filled = _fill_optional({c: bind_joints[i] * scale for c, i in mapping.items()}, path)
    _check_biped(joints, path)
    turn = _upright(joints)
    vertices, joints = vertices * scale @ turn.T, joints @ turn.T
    shift = np.array([joints[0, 0], vertices[:, 1].min(), joints[0, 2]])
    if not np.isfinite(vertices).all():
        raise doc.fail("the skinned mesh's vertices are not finite in the world")
    weights = None if skinning is None else _canonical_weights(doc, skinning, joint_nodes, mapping)
    return Character(vertices - shift, faces, joints - shift, skin, scheme, scale,
                     posed_joints=tuple(names[i] for i in np.flatnonzero(posed)), turned=not np.allclose(turn, np.eye(3)),
                     filled_joints=filled, weights=weights)


def character_body(path: str | Path, skin: int | None = None, joint_map: dict | None = None,
                   unit_scale: float | None = None) -> tuple[BodyRecord, Character]:
    """The body of a skinned character file (``hrr-body fit`` writes it; ``hrr-animate --body``
    reads it in place): :func:`read_character`, then the skeleton and capsules fitted to its mesh
    (:func:`~.fit.fit_body`). An :class:`~hrr_garment.errors.InputError` naming the file where the
    mesh cannot be fitted or the character is not of a human's height."""
    character = read_character(path, skin=skin, joint_map=joint_map, unit_scale=unit_scale)
    try:
        fitted = fit_body(character.vertices, character.joints)
    except ValueError as exc:
        raise InputError(path, f"cannot fit a body to its mesh: {exc}") from None
    lo, hi = STATURE_RANGE_M
    if not lo <= fitted.stature <= hi:
        raise InputError(path, f"the character is {fitted.stature:.3g} m tall, not within [{lo}, {hi}] m; "
                               "if the file is not in metres, pass --unit-scale (metres per file unit)")
    return BodyRecord(fitted.skeleton, fitted.body, pelvis_height=fitted.pelvis_height, stature=fitted.stature,
                      report=fitted.report), character
