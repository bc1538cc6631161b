"""What a GLB is built from: pygltflib (the ``export`` extra), glTF's component types and buffer
targets, and :class:`GlbBlob`, the binary chunk with its buffer views and accessors, which the
garment (:mod:`.glb`), the capsule body (:mod:`.glb_body`) and a character (:mod:`.character`)
append to."""

from __future__ import annotations

import numpy as np

FLOAT, UINT, USHORT = 5126, 5125, 5123
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


def pygltflib_module():
    """pygltflib, or an ImportError that says how to install it."""
    try:
        import pygltflib
    except ImportError:
        raise ImportError("GLB export needs pygltflib: pip install 'hrr_garment[export]'") from None
    return pygltflib


class GlbBlob:
    """The GLB binary chunk under construction: buffer views and accessors appended in order."""

    def __init__(self, gl):
        self.gl, self.parts, self.size = gl, [], 0
        self.views: list = []
        self.accessors: list = []

    def view(self, array: np.ndarray, target: int | None = None, stride: int | None = None) -> int:
        """``stride`` is required by glTF when several vertex accessors share one view."""
        data = np.ascontiguousarray(array).tobytes()
        self.views.append(
            self.gl.BufferView(
                buffer=0, byteOffset=self.size, byteLength=len(data), target=target, byteStride=stride
            )
        )
        pad = (-len(data)) % 4
        self.parts.append(data + b"\0" * pad)
        self.size += len(data) + pad
        return len(self.views) - 1

    def accessor(self, view: int, array: np.ndarray, kind: str, bounds: bool = False, offset: int = 0) -> int:
        """An accessor over ``array`` (already stored in ``view`` at byte ``offset``)."""
        flat = array.reshape(len(array), -1)
        component = {np.dtype(np.uint32): UINT, np.dtype(np.uint16): USHORT}.get(array.dtype, FLOAT)
        extra = {"min": flat.min(0).tolist(), "max": flat.max(0).tolist()} if bounds else {}
        self.accessors.append(
            self.gl.Accessor(
                bufferView=view,
                byteOffset=offset,
                componentType=component,
                count=len(array),
                type=kind,
                **extra,
            )
        )
        return len(self.accessors) - 1

    def stored(self, array: np.ndarray, kind: str, target: int | None = None, bounds: bool = False) -> int:
        """``array`` stored in a view of its own, and its accessor."""
        return self.accessor(self.view(array, target), array, kind, bounds)

    def bytes(self) -> bytes:
        """The chunk's bytes, each view padded to 4."""
        return b"".join(self.parts)
