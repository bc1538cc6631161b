"""A body's own skinned mesh as its record and body.json carry it (format 2's ``mesh``): a fitted
character's rest mesh, its canonical joints in that pose and its skin weights, so that the body the
viewer sees travels with the body and is posed wherever the body is
(:func:`~.skinned_body.visible_body`).

    mesh = BodyMesh.of_character(character)     # hrr-body fit
    data = mesh_to_dict(mesh)                   # body.json's "mesh"
    mesh = mesh_from_dict(data, path)           # checked; InputError naming ``path``

The weights are kept sparse: each vertex's :data:`MAX_INFLUENCES` largest canonical weights and
their joints, renormalised. A glTF character has at most four skin joints per vertex (JOINTS_0),
and gathering them onto the canonical joints only merges them, so nothing is lost for one read by
:func:`~.character.read_character`; a mesh with more loses its smallest weights
(:func:`sparse_weights` says how far a vertex can move). Numbers are rounded to a micrometre and a
millionth of a weight; every value is checked on reading, and sizes are bounded before any array is
built.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..motion.skeleton import JOINT_NAMES

MAX_INFLUENCES = 4  # joints kept per vertex (glTF's JOINTS_0 holds four)
MAX_MESH_VERTICES = 200_000  # a game character has well under 100,000; hrr-body fit keeps no more
MAX_MESH_FACES = 2 * MAX_MESH_VERTICES
MAX_EXTENT_M = 10.0  # no coordinate of a body standing at the origin reaches further
WEIGHT_SUM_TOLERANCE = (
    1e-3  # rounded weights sum to 1 within a few millionths; a hand-edited file within this
)
DECIMALS = 6


@dataclass(frozen=True, eq=False)  # compared (and hashed) by identity: visible_body caches by it
class BodyMesh:
    """A rest mesh with its canonical joints in the same pose and its sparse canonical skin weights,
    each value as body.json holds it (rounded), so that a mesh read back is the mesh written, to
    the bit: what :func:`~.skinned_body.skinned_body` skins, and what a sequence's key hashes."""

    vertices: np.ndarray  # (V, 3) float64 metres, in the body's frame (soles on y = 0)
    faces: np.ndarray  # (F, 3) int64
    joints: np.ndarray  # (22, 3) float64 the canonical joints in the mesh's pose
    skin_joints: np.ndarray  # (V, K) int64 canonical joint indices, K <= MAX_INFLUENCES
    skin_weights: np.ndarray  # (V, K) float64 their weights, non-negative, summing to 1 within 1e-5

    @property
    def weights(self) -> np.ndarray:
        """(V, 22) float64 the canonical weights, each row summing to 1."""
        return dense_weights(self.skin_joints, self.skin_weights)

    @classmethod
    def of(cls, vertices: np.ndarray, faces: np.ndarray, joints: np.ndarray, weights: np.ndarray) -> BodyMesh:
        """The mesh of (V, 3) ``vertices``, (F, 3) ``faces``, the (22, 3) canonical ``joints`` in its
        pose and (V, 22) canonical ``weights``, rounded and kept sparse as body.json keeps them."""
        skin_joints, skin_weights = sparse_weights(weights)
        return cls(
            _rounded(vertices),
            np.asarray(faces, np.int64),
            _rounded(joints),
            skin_joints,
            np.round(skin_weights, DECIMALS),
        )

    @classmethod
    def of_character(cls, character) -> BodyMesh:
        """A :class:`~.character.Character`'s mesh with its file's weights; a ValueError where the
        mesh carries no skin weights."""
        if character.weights is None:
            raise ValueError("the character's mesh carries no skin weights (JOINTS_0 / WEIGHTS_0)")
        return cls.of(character.vertices, character.faces, character.joints, character.weights)


def _rounded(values: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(values, np.float64), DECIMALS) + 0.0  # + 0.0: no -0.0 written


def sparse_weights(weights: np.ndarray, k: int = MAX_INFLUENCES) -> tuple[np.ndarray, np.ndarray]:
    """(V, K) joints and weights: each row's K largest of (V, J) ``weights``, renormalised to sum to
    1; K is ``k`` or fewer where no vertex has more weights above zero."""
    weights = np.asarray(weights, np.float64)
    k = max(1, min(k, int((weights > 0).sum(1).max(initial=1))))
    joints = np.argsort(-weights, axis=1, kind="stable")[:, :k]
    kept = np.take_along_axis(weights, joints, 1)
    return joints, kept / kept.sum(1, keepdims=True)


def dense_weights(joints: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(V, 22) float64 canonical weights of sparse ``joints`` and ``weights`` (V, K), each row
    renormalised to sum to 1."""
    dense = np.zeros((len(joints), len(JOINT_NAMES)))
    np.add.at(dense, (np.repeat(np.arange(len(joints)), joints.shape[1]), joints.ravel()), weights.ravel())
    return dense / dense.sum(1, keepdims=True)


def mesh_to_dict(mesh: BodyMesh) -> dict:
    """body.json's ``mesh`` (JSON values): vertices, faces, joints and the sparse skin weights."""
    return {
        "vertices": mesh.vertices.tolist(),
        "faces": mesh.faces.tolist(),
        "joints": mesh.joints.tolist(),
        "skin_joints": mesh.skin_joints.tolist(),
        "skin_weights": mesh.skin_weights.tolist(),
    }


def mesh_json(data: dict) -> str:
    """``mesh_to_dict``'s dict as JSON text with one row (a vertex, a face, a joint) a line, not
    indented, to sit in body.json: a mesh of tens of thousands of vertices stays readable and the
    file a fraction of the size ``json.dumps(indent=2)`` makes of it (a number a line)."""
    parts = []
    for key, rows in data.items():
        compact = json.dumps(rows, separators=(",", ":"), allow_nan=False)  # no "],[" within a row
        one_a_line = compact[1:-1].replace("],[", "],\n[")
        parts.append(f'    "{key}": [\n{one_a_line}\n    ]')
    return "{\n" + ",\n".join(parts) + "\n  }"


def mesh_from_dict(data: object, path: Path) -> BodyMesh:
    """Check body.json's ``mesh`` (sizes first, then shapes, finite values, face indices, weights
    non-negative and summing to 1) and make the :class:`BodyMesh`; InputError naming ``path``."""
    if not isinstance(data, dict):
        raise InputError(
            path,
            f"'mesh' must be an object (vertices, faces, joints, skin weights), not {type(data).__name__}",
        )
    vertices = _array(path, data, "vertices", MAX_MESH_VERTICES, 3)
    v = len(vertices)
    faces = _array(path, data, "faces", MAX_MESH_FACES, 3, integers=True)
    joints = _array(path, data, "joints", len(JOINT_NAMES), 3)
    if v < 3 or not len(faces) or len(joints) != len(JOINT_NAMES):
        raise InputError(
            path,
            f"mesh: {v} vertices, {len(faces)} faces and {len(joints)} joints; a mesh needs at least 3 "
            f"vertices, a face and the {len(JOINT_NAMES)} canonical joints",
        )
    for what, arr in (("vertices", vertices), ("joints", joints)):
        if not (np.abs(arr) <= MAX_EXTENT_M).all():  # NaN fails this too
            raise InputError(path, f"mesh {what} must be finite and within {MAX_EXTENT_M:g} m of the origin")
    if faces.min() < 0 or faces.max() >= v:
        raise InputError(
            path,
            f"mesh faces must index its {v} vertices (0 to {v - 1}), found {faces.min()} to {faces.max()}",
        )
    skin_joints = _array(path, data, "skin_joints", v, None, integers=True)
    skin_weights = _array(path, data, "skin_weights", v, None)
    k = skin_joints.shape[1]
    if skin_joints.shape != (v, k) or skin_weights.shape != (v, k) or not 1 <= k <= len(JOINT_NAMES):
        raise InputError(
            path,
            f"mesh skin_joints {skin_joints.shape} and skin_weights {skin_weights.shape} must both be "
            f"(V, K) for its {v} vertices, with 1 <= K <= {len(JOINT_NAMES)}",
        )
    if skin_joints.min() < 0 or skin_joints.max() >= len(JOINT_NAMES):
        raise InputError(path, f"mesh skin_joints must name canonical joints (0 to {len(JOINT_NAMES) - 1})")
    total = skin_weights.sum(1)
    if not (skin_weights >= 0).all() or not (np.abs(total - 1.0) <= WEIGHT_SUM_TOLERANCE).all():
        bad = int(np.argmax(~(np.abs(total - 1.0) <= WEIGHT_SUM_TOLERANCE) | (skin_weights < 0).any(1)))
        raise InputError(
            path,
            f"mesh skin_weights must be non-negative and sum to 1 (within {WEIGHT_SUM_TOLERANCE:g}) at "
            f"each vertex; vertex {bad} has {skin_weights[bad].tolist()}",
        )
    return BodyMesh(vertices, faces, joints, skin_joints, skin_weights)


def _array(
    path: Path, data: dict, key: str, max_rows: int, columns: int | None, *, integers: bool = False
) -> np.ndarray:
    """``data[key]``: a list of at most ``max_rows`` rows of ``columns`` numbers (any equal count where
    None), as float64 (int64 for ``integers``); its length is checked before numpy reads it."""
    rows = data.get(key)
    kind = "integers" if integers else "numbers"
    if not isinstance(rows, list) or len(rows) > max_rows:
        raise InputError(path, f"mesh {key} must be a list of at most {max_rows} rows of {kind}")
    try:
        arr = np.asarray(rows) if rows else np.zeros((0, columns or 1))
    except (ValueError, TypeError):
        arr = None  # rows of different lengths
    if (
        arr is None
        or arr.ndim != 2
        or (columns is not None and arr.shape[1] != columns)
        or arr.dtype.kind not in ("iu" if integers else "iuf")
    ):
        rows_of = f"{len(rows)} rows of {columns}" if columns else "equal rows of"
        raise InputError(path, f"mesh {key} must be a list of {rows_of} {kind}")
    return arr.astype(np.int64 if integers else np.float64)
