"""The glTF 2.0 rules a document must keep before any of its arrays is made: every buffer, buffer
view and accessor, and the nodes, meshes, skins and animations that name them, checked for type,
range and reach (the core specification's property rules, as the Khronos validator states them, for
the properties this package reads). pygltflib parses a document without checking it, so a string
where an index belongs, a negative offset, a count of a billion or a stride that walks backwards
would otherwise reach numpy as a traceback, an allocation of gigabytes, or an array read from
bytes nobody wrote. Each rule fails naming the property::

    check_document(doc)        # raises MotionError: "accessor 3: count must be ... got 1e9"

The limits on size: an accessor's elements lie inside its buffer view and the view inside its
buffer, whose bytes the file holds (:meth:`~.gltf_file.GltfDocument.accessor` checks them against
the bytes present), so an array is never larger than the file's content; an accessor without a
buffer view (zeros, by the specification) may hold at most one element per byte of the file; a skin
at most :data:`~.limits.MAX_JOINTS` joints.
"""

from __future__ import annotations

import math
from typing import Callable

from .limits import MAX_JOINTS

COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
ELEMENT_WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
PRIMITIVE_MODES = range(7)  # points, lines, line loop, line strip, triangles, strip, fan
TARGET_PATHS = ("translation", "rotation", "scale", "weights")
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
TRS_LENGTHS = {"translation": 3, "rotation": 4, "scale": 3, "matrix": 16}


class _Rules:
    """The checks over one document; ``fail(problem)`` makes the error that names its file."""

    def __init__(self, doc, fail: Callable[[str], Exception], file_bytes: int):
        self.doc, self.fail, self.file_bytes = doc, fail, file_bytes

    def items(self, name: str) -> list:
        value = self.doc.get(name)
        if value is None:
            return []
        if not isinstance(value, list):
            raise self.fail(f"'{name}' must be a list, got {type(value).__name__}")
        for i, item in enumerate(value):
            if not isinstance(item, dict):
                raise self.fail(f"{name}[{i}] must be an object, got {type(item).__name__}")
        return value

    def index(self, where: str, value: object, length: int, of: str, optional: bool = True) -> None:
        if value is None and optional:
            return
        if not _is_int(value) or not 0 <= value < length:
            raise self.fail(f"{where} must index one of the {length} {of}, got {value!r}")

    def whole(self, where: str, value: object, low: int, high: float = math.inf) -> int:
        if not _is_int(value) or not low <= value <= high:
            top = "" if high == math.inf else f" and at most {high:,}"
            raise self.fail(f"{where} must be a whole number of at least {low}{top}, got {value!r}")
        return int(value)

    def buffers(self) -> list[int]:
        sizes = []
        for i, buf in enumerate(self.items("buffers")):
            # at least 0, where the specification says 1: writers (pygltflib among them) give a file
            # with no arrays an empty buffer, and nothing can reach into one
            sizes.append(self.whole(f"buffer {i}: byteLength", buf.get("byteLength"), 0))
            uri = buf.get("uri")
            if uri is not None and not isinstance(uri, str):
                raise self.fail(f"buffer {i}: uri must be a string, got {uri!r}")
        return sizes

    def views(self, sizes: list[int]) -> list[dict]:
        views = self.items("bufferViews")
        for i, view in enumerate(views):
            buffer = view.get("buffer")
            self.index(f"bufferView {i}: buffer", buffer, len(sizes), "buffers", optional=False)
            offset = self.whole(f"bufferView {i}: byteOffset", view.get("byteOffset", 0), 0)
            length = self.whole(f"bufferView {i}: byteLength", view.get("byteLength"), 1)
            if view.get("byteStride") is not None:
                stride = self.whole(f"bufferView {i}: byteStride", view["byteStride"], 4, 252)
                if stride % 4:
                    raise self.fail(f"bufferView {i}: byteStride must be a multiple of 4, got {stride}")
            if offset + length > sizes[buffer]:
                raise self.fail(
                    f"bufferView {i} reaches byte {offset + length:,} of buffer {buffer}, which holds "
                    f"{sizes[buffer]:,}"
                )
        return views

    def accessors(self, views: list[dict]) -> int:
        accessors = self.items("accessors")
        for i, acc in enumerate(accessors):
            where = f"accessor {i}"
            component, kind, normalized = acc.get("componentType"), acc.get("type"), acc.get("normalized")
            if not _is_int(component) or component not in COMPONENT_BYTES:
                raise self.fail(f"{where}: componentType {component!r} is not a glTF component type")
            if not isinstance(kind, str) or kind not in ELEMENT_WIDTHS:
                raise self.fail(f"{where}: type {kind!r} is not a glTF element type")
            count = self.whole(f"{where}: count", acc.get("count"), 1)
            if normalized is not None and not isinstance(normalized, bool):
                raise self.fail(f"{where}: normalized must be true or false, got {normalized!r}")
            item = COMPONENT_BYTES[component]
            element = item * ELEMENT_WIDTHS[kind]
            offset = self.whole(f"{where}: byteOffset", acc.get("byteOffset", 0), 0)
            if acc.get("bufferView") is None:
                if count * ELEMENT_WIDTHS[kind] > self.file_bytes:
                    raise self.fail(
                        f"{where} holds {count:,} elements without a buffer view, more than its "
                        f"{self.file_bytes:,}-byte file can mean"
                    )
                continue
            index = acc["bufferView"]
            self.index(f"{where}: bufferView", index, len(views), "buffer views", optional=False)
            if offset % item:
                raise self.fail(
                    f"{where}: byteOffset {offset} is not a multiple of its {item}-byte component"
                )
            stride = views[index].get("byteStride") or element
            if stride < element:
                raise self.fail(
                    f"{where}: its view's byteStride {stride} is shorter than one element ({element} bytes)"
                )
            end, length = offset + stride * (count - 1) + element, views[index]["byteLength"]
            if end > length:
                raise self.fail(
                    f"{where}: {count:,} elements reach byte {end:,} of bufferView {index}, which holds "
                    f"{length:,}"
                )
        return len(accessors)

    def nodes(self, meshes: int, skins: int) -> int:
        nodes = self.items("nodes")
        for i, node in enumerate(nodes):
            where = f"node {i}"
            children = node.get("children", [])
            if not isinstance(children, list):
                raise self.fail(f"{where}: children must be a list, got {children!r}")
            for child in children:
                self.index(f"{where}: a child", child, len(nodes), "nodes", optional=False)
            self.index(f"{where}: mesh", node.get("mesh"), meshes, "meshes")
            self.index(f"{where}: skin", node.get("skin"), skins, "skins")
            for name, length in TRS_LENGTHS.items():
                value = node.get(name)
                if value is not None and not _numbers(value, length):
                    raise self.fail(f"{where}: {name} must be {length} finite numbers, got {value!r}")
        return len(nodes)

    def meshes(self, accessors: int) -> None:
        for m, mesh in enumerate(self.items("meshes")):
            primitives = mesh.get("primitives")
            if not isinstance(primitives, list):
                raise self.fail(f"mesh {m}: primitives must be a list, got {primitives!r}")
            for p, prim in enumerate(primitives):
                where = f"mesh {m} primitive {p}"
                if not isinstance(prim, dict):
                    raise self.fail(f"{where} must be an object")
                self.index(f"{where}: indices", prim.get("indices"), accessors, "accessors")
                mode = prim.get("mode")
                if mode is not None and (not _is_int(mode) or mode not in PRIMITIVE_MODES):
                    raise self.fail(f"{where}: mode must be 0-6, got {mode!r}")
                attributes = prim.get("attributes")
                if not isinstance(attributes, dict):
                    raise self.fail(f"{where}: attributes must be an object, got {attributes!r}")
                for name, value in attributes.items():
                    self.index(f"{where}: attribute {name}", value, accessors, "accessors", optional=False)

    def skins(self, nodes: int, accessors: int) -> None:
        for s, skin in enumerate(self.items("skins")):
            joints = skin.get("joints")
            if not isinstance(joints, list) or not joints:
                raise self.fail(f"skin {s}: joints must be a list of nodes, got {joints!r}")
            if len(joints) > MAX_JOINTS:
                raise self.fail(
                    f"skin {s} lists {len(joints):,} joints, more than {MAX_JOINTS} (a human rig with "
                    "hands and face has a few hundred)"
                )
            for joint in joints:
                self.index(f"skin {s}: a joint", joint, nodes, "nodes", optional=False)
            if len(set(joints)) != len(joints):
                raise self.fail(f"skin {s} lists a joint twice")
            self.index(
                f"skin {s}: inverseBindMatrices", skin.get("inverseBindMatrices"), accessors, "accessors"
            )
            self.index(f"skin {s}: skeleton", skin.get("skeleton"), nodes, "nodes")

    def choice(self, where: str, value: object, options: tuple[str, ...]) -> None:
        if not isinstance(value, str) or value not in options:
            raise self.fail(f"{where} must be one of {', '.join(options)}, got {value!r}")

    def animations(self, nodes: int, accessors: int) -> None:
        for a, animation in enumerate(self.items("animations")):
            samplers, channels = animation.get("samplers"), animation.get("channels")
            if not isinstance(samplers, list) or not isinstance(channels, list):
                raise self.fail(f"animation {a}: samplers and channels must be lists")
            for k, sampler in enumerate(samplers):
                where = f"animation {a} sampler {k}"
                if not isinstance(sampler, dict):
                    raise self.fail(f"{where} must be an object")
                for end in ("input", "output"):
                    self.index(f"{where}: {end}", sampler.get(end), accessors, "accessors", optional=False)
                if sampler.get("interpolation") is not None:
                    self.choice(f"{where}: interpolation", sampler["interpolation"], INTERPOLATIONS)
            for c, channel in enumerate(channels):
                where = f"animation {a} channel {c}"
                if not isinstance(channel, dict) or not isinstance(channel.get("target"), dict):
                    raise self.fail(f"{where} must be an object with a target")
                self.index(
                    f"{where}: sampler", channel.get("sampler"), len(samplers), "samplers", optional=False
                )
                self.index(f"{where}: target node", channel["target"].get("node"), nodes, "nodes")
                self.choice(f"{where}: target path", channel["target"].get("path"), TARGET_PATHS)


def check_document(doc: dict, fail: Callable[[str], Exception], file_bytes: int) -> None:
    """Check the glTF JSON ``doc`` (as parsed, before pygltflib, which turns "12" and 12.5 into 12,
    reads it; from a file of ``file_bytes`` bytes, the GLB's binary chunk included) against the
    rules above; ``fail(problem)`` makes the error raised."""
    rules = _Rules(doc, fail, file_bytes)
    views = rules.views(rules.buffers())
    accessors = rules.accessors(views)
    meshes, skins = len(rules.items("meshes")), len(rules.items("skins"))
    nodes = rules.nodes(meshes, skins)
    rules.meshes(accessors)
    rules.skins(nodes, accessors)
    rules.animations(nodes, accessors)


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _numbers(value: object, length: int) -> bool:
    return (
        isinstance(value, list)
        and len(value) == length
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    )
