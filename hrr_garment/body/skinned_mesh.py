"""The skinned mesh of a glTF / GLB document, as :mod:`.character` reads a character: the skin's
meshes (every primitive of triangles, strips and fans on a node skinned to it), their positions and
triangles, their skin weights gathered onto the canonical joints, and the skin's inverse bind
matrices. Placing them in the project's frame is :mod:`.character`'s."""

from __future__ import annotations

import numpy as np

from ..motion.gltf_file import node_parents
from ..motion.skeleton import JOINT_INDEX, JOINT_NAMES

MAX_VERTICES = 2_000_000  # a game or film character has well under a million
TRIANGLE_MODES = (4, 5, 6)  # TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN


def skinned_meshes(doc, skin: int | None) -> tuple[int, list[int]]:
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
        if (prim.mode if prim.mode is not None else 4) in TRIANGLE_MODES and position is not None:
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
        tri = np.stack([indices[:n], indices[1 : n + 1], indices[2 : n + 2]], 1)
        tri[1::2] = tri[1::2][:, [1, 0, 2]]
        return tri
    return np.stack(
        [np.full(n, indices[0] if len(indices) else 0), indices[1 : n + 1], indices[2 : n + 2]], 1
    )


def read_mesh(doc, meshes: list[int]) -> tuple[np.ndarray, np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """The meshes' triangle primitives as one (V, 3) vertex and (F, 3) face array, in the skin's
    space, and their skin joints and weights (V, 4) each (None unless every primitive has them)."""
    vertices, faces, skinning, offset = [], [], [], 0
    for m in meshes:
        for p, prim in enumerate(doc.doc.meshes[m].primitives or []):
            mode = prim.mode if prim.mode is not None else 4
            position = prim.attributes.POSITION if prim.attributes is not None else None
            if mode not in TRIANGLE_MODES or position is None:
                continue  # points and lines are no surface
            v = doc.accessor(position, raw_integers=True)
            if v.shape[1] != 3:
                raise doc.fail(f"mesh {m} primitive {p}: POSITION must be VEC3")
            idx = (
                np.arange(len(v))
                if prim.indices is None
                else doc.accessor(prim.indices, raw_integers=True)[:, 0].astype(np.int64)
            )
            if len(idx) and (idx.min() < 0 or idx.max() >= len(v)):
                raise doc.fail(f"mesh {m} primitive {p}: an index reaches past its {len(v)} vertices")
            vertices.append(v)
            faces.append(_triangles(idx, mode) + offset)
            skinning.append(_skin_weights(doc, prim.attributes, len(v)))
            offset += len(v)
            if offset > MAX_VERTICES:
                raise doc.fail(
                    f"the skinned meshes hold over {MAX_VERTICES} vertices; decimate the character first"
                )
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


def canonical_weights(
    doc, skinning: tuple[np.ndarray, np.ndarray], joint_nodes: list[int], *, mapping: dict[str, int]
) -> np.ndarray:
    """(V, 22) each vertex's weights gathered onto the canonical joints: a skin joint that is not
    one of them gives its weight to its nearest mapped ancestor (the pelvis where it has none)."""
    joints, weights = skinning
    if joints.size and (joints.min() < 0 or joints.max() >= len(joint_nodes)):
        raise doc.fail(f"JOINTS_0 names a joint outside the skin's {len(joint_nodes)}")
    parents = node_parents(doc)
    canonical = {joint_nodes[i]: JOINT_INDEX[c] for c, i in mapping.items()}
    return gather_weights(joints, weights, canonical_owners(joint_nodes, parents, canonical))


def canonical_owners(bones: list[int], parents: list[int], canonical: dict[int, int]) -> np.ndarray:
    """(len(bones),) the canonical joint each bone gives its skin weight to: its own where it is
    mapped (``canonical``: bone -> canonical joint index), else its nearest mapped ancestor up
    ``parents`` (-1 at a root), else the pelvis."""
    owner = np.zeros(len(bones), np.int64)
    for i, bone in enumerate(bones):
        while bone >= 0 and bone not in canonical:
            bone = parents[bone]
        owner[i] = canonical.get(bone, 0)
    return owner


def gather_weights(joints: np.ndarray, weights: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """(V, 22) skin weights (``joints`` (V, K) bone indices with their ``weights``) summed onto
    each bone's canonical ``owner`` and normalised; a vertex weighted to nothing follows the pelvis."""
    out = np.zeros((len(joints), len(JOINT_NAMES)))
    np.add.at(
        out, (np.repeat(np.arange(len(joints)), joints.shape[1]), owner[joints].ravel()), weights.ravel()
    )
    total = out.sum(1, keepdims=True)
    out[total[:, 0] <= 0, 0], total[total <= 0] = 1.0, 1.0
    return (out / total).astype(np.float32)


def bind_matrices(doc, skin: int, joints: list[int]) -> np.ndarray:
    """(J, 4, 4) the skin's inverse bind matrices."""
    accessor = doc.doc.skins[skin].inverseBindMatrices
    if accessor is None:
        raise doc.fail(f"skin {skin} has no inverseBindMatrices, so its bind pose is unknown")
    ibm = doc.accessor(accessor)
    if ibm.shape != (len(joints), 16):
        raise doc.fail(f"skin {skin}'s inverseBindMatrices hold {ibm.shape[0]} MAT4 for {len(joints)} joints")
    return np.swapaxes(ibm.reshape(-1, 4, 4), 1, 2)  # glTF matrices are column-major
