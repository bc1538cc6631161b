"""glTF 2.0 / GLB files as documents: loading with pygltflib (the ``export`` extra), checked
access to accessors, the node tree and its rest transforms. What :mod:`.gltf` (a file's animations
as motion) and :mod:`hrr_garment.body.character` (a character's skinned mesh) read a file through.
"""

from __future__ import annotations

import json
import struct
import warnings
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ..errors import InputError, MotionError
from ..input_files import MAX_BINARY_BYTES, input_file, read_input
from .gltf_checks import check_document
from .rotations import matrix_to_quat, quat_to_matrix

GLTF_SUFFIXES = (".glb", ".gltf")
# componentType -> (little-endian dtype, divisor of a normalized integer)
_COMPONENTS = {
    5120: ("<i1", 127.0),
    5121: ("<u1", 255.0),
    5122: ("<i2", 32767.0),
    5123: ("<u2", 65535.0),
    5125: ("<u4", None),
    5126: ("<f4", None),
}
_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
MAX_GLTF_JSON_BYTES = 256 << 20  # a GLB's JSON chunk (a character's is a few hundred kilobytes)
# pygltflib's failures on a file that is not glTF (or is cut short): one line each, never a traceback
READ_ERRORS = (
    OSError,
    ValueError,
    KeyError,
    TypeError,
    IndexError,
    AttributeError,
    struct.error,
    UnicodeDecodeError,
)


def pygltflib_module():
    """pygltflib, or an ImportError naming the extra that brings it."""
    try:
        import pygltflib
    except ImportError:
        raise ImportError(
            "reading glTF / GLB motion needs pygltflib: pip install 'hrr_garment[export]'"
        ) from None
    return pygltflib


def _json_of(path: Path, data: bytes) -> dict:
    """The JSON of a .gltf file's bytes, or of a GLB's first chunk, as parsed (nothing coerced)."""
    text = data
    if data[:4] == b"glTF":
        size = int.from_bytes(data[12:16], "little") if len(data) >= 20 else 0
        if data[16:20] != b"JSON" or not 0 < size <= min(MAX_GLTF_JSON_BYTES, len(data) - 20):
            raise MotionError(
                path, "not a readable glTF 2.0 / GLB file: its first chunk is not JSON, or is cut short"
            )
        text = data[20 : 20 + size]
    try:
        doc = json.loads(text.decode("utf-8"))
    except RecursionError:
        raise MotionError(path, "its JSON is nested too deep to be a glTF document") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise MotionError(path, f"not a readable glTF 2.0 / GLB file, or cut short ({exc})") from None
    if not isinstance(doc, dict):
        raise MotionError(path, "not a glTF document: its JSON is not an object")
    return doc


class GltfDocument:
    """A loaded glTF document and its buffers' bytes, with checked access to accessors."""

    def __init__(self, path: Path):
        self.path = path
        gltf = pygltflib_module()
        data = read_input(path, limit=MAX_BINARY_BYTES, what="a glTF / GLB file")
        check_document(_json_of(path, data), self.fail, len(data))  # before pygltflib coerces it
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                doc = (
                    gltf.GLTF2.load_from_bytes(data)
                    if data[:4] == b"glTF"
                    else gltf.GLTF2.from_json(data.decode("utf-8"))
                )
        except RecursionError:
            raise MotionError(path, "its JSON is nested too deep to be a glTF document") from None
        except (*READ_ERRORS, json.JSONDecodeError) as exc:
            raise MotionError(
                path, f"not a readable glTF 2.0 / GLB file, or cut short ({type(exc).__name__}: {exc})"
            ) from None
        if doc is None or not isinstance(doc.nodes, list):
            raise MotionError(path, "not a readable glTF 2.0 / GLB file (no JSON chunk)")
        if "EXT_meshopt_compression" in (doc.extensionsRequired or []):
            raise MotionError(
                path,
                "its data is compressed with EXT_meshopt_compression, which pygltflib does not "
                "decode; export it without compression",
            )
        self.doc = doc
        self._buffers: dict[int, bytes] = {}

    def fail(self, problem: str) -> MotionError:
        """A :class:`MotionError` naming this file."""
        return MotionError(self.path, problem)

    def _buffer(self, index: int) -> bytes:
        if index not in self._buffers:
            buf = self.doc.buffers[index]
            uri = buf.uri
            try:
                if uri is None:
                    data = self.doc.binary_blob()
                elif uri.startswith("data:"):
                    data = self.doc.decode_data_uri(uri)
                else:
                    data = self._external(unquote(uri), buf.byteLength or 0)
            except READ_ERRORS as exc:
                raise self.fail(
                    f"cannot read buffer {index} ({uri or 'the GLB binary chunk'}: {exc})"
                ) from None
            if data is None or len(data) < (buf.byteLength or 0):
                held = 0 if data is None else len(data)
                raise self.fail(
                    f"buffer {index} declares {buf.byteLength} bytes but the file holds {held}: "
                    "the file is cut short"
                )
            self._buffers[index] = bytes(data)
        return self._buffers[index]

    def _external(self, uri: str, size: int) -> bytes:
        """The first ``size`` bytes of a buffer file beside a .gltf: never a path out of its folder,
        a link included (resolved before the check), and only a regular file."""
        relative = Path(uri)
        folder = self.path.parent.resolve()
        try:
            target = (folder / relative).resolve()
        except (OSError, RuntimeError, ValueError):
            target = None
        if relative.is_absolute() or target is None or not target.is_relative_to(folder):
            raise self.fail(f"buffer file {uri!r} is not a file beside the .gltf, in its folder")
        try:
            with open(input_file(target, what=f"buffer file {uri!r}"), "rb") as fh:
                return fh.read(size)  # a longer file's first byteLength bytes are the buffer
        except InputError as exc:
            raise self.fail(f"buffer file {uri!r}: {exc.problem}") from None

    def accessor(self, index: int, raw_integers: bool = False) -> np.ndarray:
        """Accessor ``index`` as (count, width) float64, normalized integers scaled to [-1, 1].
        ``raw_integers``: integers not flagged ``normalized`` are kept as they are (indices, joint
        numbers, quantized positions) instead of scaled as animation outputs' integers are."""
        try:
            acc = self.doc.accessors[index]
            view = self.doc.bufferViews[acc.bufferView] if acc.bufferView is not None else None
            dtype, divisor = _COMPONENTS[acc.componentType]
            width = _WIDTHS[acc.type]
        except (IndexError, KeyError, TypeError):
            raise self.fail(f"accessor {index} is missing or of an unknown type") from None
        if acc.sparse is not None:
            raise self.fail(f"accessor {index} is sparse, which this reader does not support")
        if view is None:
            return np.zeros((acc.count, width))  # the spec: an accessor without a buffer view holds zeros
        data = self._buffer(view.buffer)
        item = np.dtype(dtype).itemsize
        stride = view.byteStride or item * width
        start, end = (view.byteOffset or 0) + (acc.byteOffset or 0), (view.byteOffset or 0) + view.byteLength
        needed = stride * (acc.count - 1) + item * width if acc.count else 0
        if acc.count < 0 or start + needed > min(end, len(data)):
            raise self.fail(
                f"accessor {index} reaches past the end of its buffer: the file is cut short or corrupt"
            )
        values = np.ndarray(
            (acc.count, width), dtype=dtype, buffer=data, offset=start, strides=(stride, item)
        ).astype(np.float64)
        if divisor is not None and (acc.normalized or (dtype != "<u4" and not raw_integers)):
            values = np.maximum(values / divisor, -1.0)
        if not np.isfinite(values).all():
            raise self.fail(f"accessor {index} holds non-finite values (NaN or inf)")
        return values


# --- the node tree ---------------------------------------------------------------------------------


def node_parents(doc: GltfDocument) -> list[int]:
    """Each node's parent (-1 for roots); a node with two parents or a cycle is refused."""
    nodes = doc.doc.nodes
    parents = [-1] * len(nodes)
    for i, node in enumerate(nodes):
        for child in node.children or []:
            if not (0 <= child < len(nodes)) or parents[child] != -1 or child == i:
                raise doc.fail(f"node {i} lists child {child}, which is missing or already has a parent")
            parents[child] = i
    rooted = [False] * len(nodes)  # known to lead up to a root
    for i in range(len(nodes)):
        path, k = set(), i
        while k >= 0 and not rooted[k]:
            if k in path:
                raise doc.fail(f"the node tree has a cycle through node {k}")
            path.add(k)
            k = parents[k]
        for k in path:
            rooted[k] = True
    return parents


def rest_trs(node) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's own translation, rotation (w, x, y, z) and scale; a ``matrix`` is decomposed."""
    if node.matrix is not None and not np.allclose(node.matrix, np.eye(4).ravel()):
        m = np.asarray(node.matrix, dtype=np.float64).reshape(4, 4).T  # glTF matrices are column-major
        scale = np.linalg.norm(m[:3, :3], axis=0)
        if np.linalg.det(m[:3, :3]) < 0:
            scale[0] = -scale[0]
        rot = m[:3, :3] / np.where(scale == 0, 1.0, scale)
        return m[:3, 3], matrix_to_quat(rot), scale
    t = np.asarray(node.translation if node.translation is not None else (0.0, 0.0, 0.0), dtype=np.float64)
    q = np.asarray(node.rotation if node.rotation is not None else (0.0, 0.0, 0.0, 1.0), dtype=np.float64)[
        [3, 0, 1, 2]
    ]
    s = np.asarray(node.scale if node.scale is not None else (1.0, 1.0, 1.0), dtype=np.float64)
    return t, q, s


def node_chain(parents: list[int], nodes: list[int]) -> list[int]:
    """``nodes`` and all their ancestors, each after its parent."""
    order: list[int] = []
    seen: set[int] = set()
    for n in nodes:
        path = []
        while n >= 0 and n not in seen:
            path.append(n)
            seen.add(n)
            n = parents[n]
        order.extend(reversed(path))
    return order


def world_transforms(
    order: list[int], parents: list[int], local: dict[int, tuple]
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """World (linear part (F, 3, 3), translation (F, 3)) of each node in ``order`` from its local
    (translation (F, 3), rotation (F, 4), scale (F, 3))."""
    world: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for n in order:
        t, q, s = local[n]
        linear = quat_to_matrix(q) * s[..., None, :]
        if parents[n] in world:
            p_lin, p_t = world[parents[n]]
            linear, t = p_lin @ linear, p_t + (p_lin @ t[..., None])[..., 0]
        world[n] = (linear, t)
    return world


def open_gltf(path: str | Path) -> GltfDocument:
    """A glTF / GLB file loaded with its buffers (accessors read by ``.accessor(i)``, the pygltflib
    document as ``.doc``); a file that cannot be read raises :class:`MotionError` naming it."""
    return GltfDocument(Path(path))


def rest_world(
    doc: GltfDocument, order: list[int], parents: list[int]
) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """The world transforms (linear part, translation) of the nodes ``order`` in their rest transforms."""
    rest = {}
    for n in order:
        t, q, s = rest_trs(doc.doc.nodes[n])
        rest[n] = (t[None], q[None], s[None])
    return world_transforms(order, parents, rest)


def rest_world_matrices(doc: GltfDocument) -> np.ndarray:
    """(N, 4, 4) every node's world matrix in its rest transforms, through the whole node tree."""
    parents = node_parents(doc)
    world = rest_world(doc, node_chain(parents, list(range(len(parents)))), parents)
    out = np.tile(np.eye(4), (len(parents), 1, 1))
    for n, (linear, t) in world.items():
        out[n, :3, :3], out[n, :3, 3] = linear[0], t[0]
    return out


def rotation_part(linear: np.ndarray) -> np.ndarray:
    """The rotation of a world transform's linear part, its scale removed (polar decomposition)."""
    u, _, vt = np.linalg.svd(linear)
    d = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= d[..., None]
    return u @ vt


# --- animations ------------------------------------------------------------------------------------
