"""The broad phase of the push-out against the skin: which cells of a uniform grid over a posed
mesh lie farther than the push's margin from it and outside it (the reference of ``hrr_skin_cells``
in ``hrr_garment/native/skin_sdf.c``, cell for cell).

    cells = skin_cells(posed, faces, margin, cell)     # one frame of a closed mesh
    far = cells.far(points)                            # (N,) nothing to measure there

Why: the skin's hulls (:mod:`.skin_envelope`) hold the skin loosely, 4 to 13 cm wider than the capsules,
so two thirds of a dress lies within them while a twentieth lies within 2 mm of the skin; each of
those would cost the skin collider's few microseconds. A cell goes to the band where its centre lies
within the margin plus half the cell's diagonal of a triangle (or near it: of its plane and of the
inner side of its edges), so that a cell outside the band is farther than the margin from the skin
everywhere; the free cells the grid's border reaches through
free cells (6-neighbours) are outside: a closed mesh's winding number is the same all over a
connected set that does not touch it, and it is 0 at the border, past the mesh's box. That needs a
closed mesh (every edge shared by two faces, each way once: :func:`closed_mesh`); on any other the
push-out measures every point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from ..native.skin import cell_box

BAND, OUTSIDE = 1, 2  # the cells' values (hrr_skin_cells'); 0: free, not reached from the border


@dataclass(frozen=True)
class SkinCells:
    """One frame's grid: its first corner, cells along each axis and (cells,) uint8 values x-major."""

    origin: np.ndarray
    dims: np.ndarray
    cells: np.ndarray
    cell: float

    def far(self, points: np.ndarray) -> np.ndarray:
        """(N,) whether each point (N, 3) lies in a cell far outside the skin or beyond the grid's box
        (outside it too: farther than the margin from the mesh's box); a NaN point is not."""
        with np.errstate(invalid="ignore"):
            f = np.floor((points - self.origin) / self.cell)
        finite = ~np.isnan(f).any(1)
        beyond = finite & ((f < 0) | (f >= self.dims)).any(1)
        idx = np.clip(np.nan_to_num(f), 0, self.dims - 1).astype(np.int64)
        at = (idx[:, 0] * self.dims[1] + idx[:, 1]) * self.dims[2] + idx[:, 2]
        return beyond | (finite & (self.cells[at] == OUTSIDE))


def closed_mesh(faces: np.ndarray) -> bool:
    """Whether every directed edge of ``faces`` (F, 3) is met once by its reverse: a closed surface,
    whose winding number is an integer constant off it."""
    f = np.asarray(faces, np.int64)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(f.max()) + 1 if len(f) else 1
    forward, backward = edges[:, 0] * n + edges[:, 1], edges[:, 1] * n + edges[:, 0]
    forward.sort()
    backward.sort()
    return bool(len(np.unique(forward)) == len(forward) and np.array_equal(forward, backward))


def _dot(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (..., 3) arrays, summed in the kernel's order (DOT3)."""
    return u[..., 0] * w[..., 0] + u[..., 1] * w[..., 1] + u[..., 2] * w[..., 2]


def _planes(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each triangle's (F, 3) unit normal, (F,) plane offset, (F, 3, 3) edges' outward unit normals in
    the plane (edge e from corner e to e + 1) and (F, 3) their offsets; zero where degenerate
    (``unit_normal`` in skin_sdf.c, op for op)."""
    u, w = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    n = np.stack(
        [
            u[:, 1] * w[:, 2] - u[:, 2] * w[:, 1],
            u[:, 2] * w[:, 0] - u[:, 0] * w[:, 2],
            u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0],
        ],
        1,
    )
    length = np.sqrt(_dot(n, n))[:, None]
    nh = np.where(length > 0, n / np.where(length > 0, length, 1.0), 0.0)
    d = np.roll(tri, -1, axis=1) - tri  # (F, 3 edges, 3)
    q = np.stack(
        [
            d[..., 1] * nh[:, None, 2] - d[..., 2] * nh[:, None, 1],
            d[..., 2] * nh[:, None, 0] - d[..., 0] * nh[:, None, 2],
            d[..., 0] * nh[:, None, 1] - d[..., 1] * nh[:, None, 0],
        ],
        -1,
    )
    ql = np.sqrt(_dot(q, q))[..., None]
    m = np.where(ql > 0, q / np.where(ql > 0, ql, 1.0), 0.0)
    return nh, _dot(nh, tri[:, 0]), m, _dot(m, tri)


def skin_cells(posed: np.ndarray, faces: np.ndarray, margin: float, cell: float) -> SkinCells:
    """The broad phase of the closed mesh ``posed`` (V, 3), ``faces`` (F, 3) for the push's
    ``margin`` (see the module docstring): a cell is in the band where its centre lies within
    ``margin`` plus half the cell's diagonal of a triangle's plane and of the inner side of each of
    its edges (every cell within that of the triangle is, and a few about the corners)."""
    origin, dims = cell_box(posed, margin, cell)
    reach = margin + 0.5 * np.sqrt(3.0) * cell
    tri = posed[np.asarray(faces, np.int64)]  # (F, 3, 3)
    lo = np.maximum(np.ceil((tri.min(1) - reach - origin) / cell - 0.5), 0).astype(np.int64)
    hi = np.minimum(np.floor((tri.max(1) + reach - origin) / cell - 0.5), dims - 1).astype(np.int64)
    span = np.maximum(hi - lo + 1, 0)  # (F, 3)
    count = span.prod(1)
    face = np.repeat(np.arange(len(tri)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)  # each pair's rank in its box
    sy, sz = span[face, 1], span[face, 2]
    idx = lo[face] + np.stack([k // (sy * sz), (k // sz) % sy, k % sz], 1)
    x = origin + (idx + 0.5) * cell
    nh, po, m, o = _planes(tri)
    band = (np.abs(_dot(nh[face], x) - po[face]) <= reach) & (
        _dot(m[face], x[:, None]) - o[face] <= reach
    ).all(1)
    band |= (nh[face] == 0.0).all(1)  # a degenerate triangle: its whole box
    flat = (idx[:, 0] * dims[1] + idx[:, 1]) * dims[2] + idx[:, 2]
    cells = np.zeros(int(np.prod(dims)), np.uint8)
    cells[flat[band]] = BAND
    grid = cells.reshape(tuple(dims))
    labels, _ = ndimage.label(grid == 0)  # 6-neighbours, as the kernel's flood
    border = np.concatenate(
        [labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(), labels[:, :, [0, -1]].ravel()]
    )
    grid[np.isin(labels, border[border > 0])] = OUTSIDE
    return SkinCells(origin, dims, cells, cell)
