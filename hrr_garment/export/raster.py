"""A small z-buffered triangle rasterizer in numpy, for previews without an OpenGL context.

Every triangle is expanded into the pixels of its clipped bounding box at once (vectorised over
all triangles), pixel centres are tested with edge functions, and the nearest fragment per pixel
wins. Painter's ordering by triangle centre is not enough here: a capsule's long side triangles
and cloth that touches the body sort wrongly and show through.
"""

from __future__ import annotations

import numpy as np

_CHUNK = 4_000_000  # candidate pixels per batch: bounds the temporary arrays (~200 MB)


def rasterize(image: np.ndarray, depth: np.ndarray, triangles: np.ndarray, colours: np.ndarray) -> None:
    """Draw flat-coloured triangles into ``image`` (H, W, 3) uint8 where they are nearer than ``depth``
    (H, W) float, both updated in place.

    ``triangles`` (N, 3, 3): per corner pixel x (right), pixel y (down), depth (larger is nearer);
    ``colours`` (N, 3). A pixel is covered when its centre (x + 0.5, y + 0.5) lies inside the triangle
    (edges included), whatever the winding.
    """
    h, w = depth.shape
    tri = np.asarray(triangles, np.float64)
    x, y = tri[..., 0], tri[..., 1]
    x0 = np.clip(np.floor(x.min(1) - 0.5), 0, w).astype(np.int64)
    x1 = np.clip(np.ceil(x.max(1) - 0.5), -1, w - 1).astype(np.int64)
    y0 = np.clip(np.floor(y.min(1) - 0.5), 0, h).astype(np.int64)
    y1 = np.clip(np.ceil(y.max(1) - 0.5), -1, h - 1).astype(np.int64)
    planes, ok = _planes(tri)
    keep = np.flatnonzero((x1 >= x0) & (y1 >= y0) & ok)
    counts = (x1 - x0 + 1)[keep] * (y1 - y0 + 1)[keep]
    start = 0
    while start < len(keep):  # batches of triangles whose candidate pixels fit in _CHUNK
        stop = start + max(1, int(np.searchsorted(np.cumsum(counts[start:]), _CHUNK)))
        ids, n = keep[start:stop], counts[start:stop]
        _rasterize_batch(
            image, depth, planes, np.asarray(colours), (ids, n, x0[ids], (x1 - x0 + 1)[ids], y0[ids])
        )
        start = stop


def _planes(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per triangle, the linear functions of the pixel centre that give barycentric weights b1, b2
    (normalised edge functions, so any winding works) and depth, relative to the first corner for
    precision: rows (b1_x, b1_y, b2_x, b2_y, z_x, z_y, z_0, x_0, y_0) as float32 (N, 9). Also
    which triangles are not degenerate."""
    x, y, z = tri[..., 0], tri[..., 1], tri[..., 2]
    rx, ry, rz = x - x[:, :1], y - y[:, :1], z - z[:, :1]
    area = rx[:, 1] * ry[:, 2] - rx[:, 2] * ry[:, 1]
    ok = np.abs(area) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, area, 1.0), 0.0)
    b1x, b1y = ry[:, 2] * inv, -rx[:, 2] * inv  # b1 = (dx * ry2 - dy * rx2) / area
    b2x, b2y = -ry[:, 1] * inv, rx[:, 1] * inv  # b2 = (dy * rx1 - dx * ry1) / area
    zx, zy = b1x * rz[:, 1] + b2x * rz[:, 2], b1y * rz[:, 1] + b2y * rz[:, 2]
    planes = np.stack([b1x, b1y, b2x, b2y, zx, zy, z[:, 0], x[:, 0], y[:, 0]], 1).astype(np.float32)
    return planes, ok


def _rasterize_batch(image, depth, planes, colours, boxes: tuple) -> None:
    # boxes: the candidate triangles' ids, pixel counts and bounding boxes' left column, width and top row
    ids, counts, x0, bw, y0 = boxes
    # Candidates are grouped by triangle, so per-triangle values spread with np.repeat (about 2.5x
    # faster than fancy indexing); int32 division is the cheapest way to a box's column and row.
    offset = (np.arange(counts.sum(), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)).astype(
        np.int32
    )
    w_box = np.repeat(bw.astype(np.int32), counts)
    row = offset // w_box
    col = offset - row * w_box
    c = [np.repeat(planes[ids, k], counts) for k in range(9)]
    px = col + np.repeat(x0.astype(np.int32), counts)
    py = row + np.repeat(y0.astype(np.int32), counts)
    dx = px.astype(np.float32) + (np.float32(0.5) - c[7])
    dy = py.astype(np.float32) + (np.float32(0.5) - c[8])
    b1 = c[0] * dx + c[1] * dy
    b2 = c[2] * dx + c[3] * dy
    eps = np.float32(1e-6)
    inside = (b1 >= -eps) & (b2 >= -eps) & (b1 + b2 <= 1 + eps)
    z = (c[4] * dx + c[5] * dy + c[6])[inside].astype(np.float64)
    pix = py[inside].astype(np.int64) * depth.shape[1] + px[inside]
    tid = np.repeat(ids, counts)[inside]
    flat_depth = depth.reshape(-1)
    np.maximum.at(flat_depth, pix, z)
    won = z >= flat_depth[pix]  # ties: the last one written wins
    image.reshape(-1, 3)[pix[won]] = colours[tid[won]]
