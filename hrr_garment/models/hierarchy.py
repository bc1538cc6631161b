"""The mesh sampling hierarchy of the FCMAE autoencoder (Zhou et al. 2020), built from a template.

Level 0 is the template's vertex graph. Each coarser level keeps a subset of the previous level's
vertices as *centres*, chosen greedily in breadth-first order from vertex 0: a vertex becomes a
centre when no centre lies within ``stride - 1`` hops. A centre pools the vertices within
``radius`` hops (radius >= stride - 1, so every vertex is pooled by some centre); unpooling uses the
transpose (each fine vertex gathers the centres that pool it). Two centres are neighbours on the
coarse level when their pooling neighbourhoods overlap. Deterministic for a given mesh; cached per
template by a hash of its faces.
"""

from __future__ import annotations

import hashlib
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix, csr_matrix

from ..garment.mesh import GarmentError, components, unique_edges


@dataclass(frozen=True)
class Neighbourhoods:
    """Padded neighbour lists: ``index`` (V_out, S) into the input level, ``mask`` (V_out, S) bool."""

    index: np.ndarray
    mask: np.ndarray

    @classmethod
    def from_lists(cls, lists: list[list[int]]) -> "Neighbourhoods":
        width = max(len(x) for x in lists)
        index = np.zeros((len(lists), width), np.int64)
        mask = np.zeros((len(lists), width), bool)
        for i, items in enumerate(lists):
            index[i, : len(items)] = items
            mask[i, : len(items)] = True
        return cls(index, mask)


@dataclass(frozen=True)
class Hierarchy:
    """sizes[l]: vertices at level l; conv[l]: 1-ring (+ self) neighbourhoods at level l;
    down[l]: level l -> l+1 pooling neighbourhoods; up[l]: level l+1 -> l (the transpose)."""

    sizes: tuple[int, ...]
    conv: tuple[Neighbourhoods, ...]
    down: tuple[Neighbourhoods, ...]
    up: tuple[Neighbourhoods, ...]
    centres: tuple[np.ndarray, ...]  # centres[l]: indices into level l of level l+1's vertices

    @property
    def levels(self) -> int:
        return len(self.sizes)

    def node_vertices(self) -> np.ndarray:
        """(sizes[-1],) the level-0 vertex each coarsest-level node (a latent node of the
        autoencoder) is centred on, traced down through the levels' centres."""
        index = np.arange(self.sizes[-1])
        for centres in reversed(self.centres):
            index = centres[index]
        return index


def _adjacency(num: int, edges: np.ndarray) -> csr_matrix:
    return coo_matrix(
        (np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
        shape=(num, num),
    ).tocsr()


def _within_hops(adj: csr_matrix, start: int, hops: int) -> list[int]:
    seen = {start: 0}
    queue = deque([start])
    while queue:
        v = queue.popleft()
        if seen[v] == hops:
            continue
        for w in adj.indices[adj.indptr[v] : adj.indptr[v + 1]]:
            if w not in seen:
                seen[w] = seen[v] + 1
                queue.append(int(w))
    return sorted(seen)


def _bfs_order(adj: csr_matrix) -> list[int]:
    order, seen = [], np.zeros(adj.shape[0], bool)
    queue = deque([0])
    seen[0] = True
    while queue:
        v = queue.popleft()
        order.append(v)
        for w in adj.indices[adj.indptr[v] : adj.indptr[v + 1]]:
            if not seen[w]:
                seen[w] = True
                queue.append(int(w))
    return order


def _coarsen(adj: csr_matrix, stride: int, radius: int) -> tuple[np.ndarray, list[list[int]], csr_matrix]:
    """Centres, their pooling neighbourhoods, and the coarse adjacency."""
    n = adj.shape[0]
    dist = np.full(n, np.iinfo(np.int64).max)
    centres = []
    for v in _bfs_order(adj):
        if dist[v] >= stride:
            centres.append(v)
            for w in _within_hops(adj, v, stride - 1):
                dist[w] = 0  # covered: within stride - 1 hops of a centre
    pools = [_within_hops(adj, c, radius) for c in centres]
    # Coarse neighbours: centres whose (stride - 1)-hop cells touch, i.e. at most 2 * stride - 1
    # hops apart. A mesh-like graph; linking overlapping pools instead gave degree ~18 and coarsened
    # the next level eight-fold.
    cells = [_within_hops(adj, c, stride - 1) for c in centres]
    rows = np.concatenate([np.full(len(p), i) for i, p in enumerate(cells)])
    member = coo_matrix((np.ones(len(rows)), (rows, np.concatenate(cells))), shape=(len(centres), n)).tocsr()
    touch = (member @ (adj + _identity(n)) @ member.T).tocoo()
    keep = touch.row != touch.col
    coarse = coo_matrix(
        (np.ones(keep.sum()), (touch.row[keep], touch.col[keep])), shape=(len(centres),) * 2
    ).tocsr()
    return np.array(centres, np.int64), pools, coarse


def _identity(n: int) -> csr_matrix:
    return coo_matrix((np.ones(n), (np.arange(n), np.arange(n))), shape=(n, n)).tocsr()


def _ring_lists(adj: csr_matrix) -> list[list[int]]:
    return [
        [v] + sorted(int(w) for w in adj.indices[adj.indptr[v] : adj.indptr[v + 1]])
        for v in range(adj.shape[0])
    ]


def build_hierarchy(
    faces: np.ndarray,
    num_vertices: int,
    latent_fraction: float = 0.01,
    stride: int = 2,
    radius: int = 2,
    max_levels: int = 8,
    name: str = "template",
    min_latent_nodes: int = 4,
) -> Hierarchy:
    """Coarsen towards ``latent_fraction`` of the vertices but not below ``min_latent_nodes``: the
    coarsest level is the one nearest that target (the paper's garments have 78-160 latent nodes; a
    1,000-vertex dress at 1 % would keep 18, too few to hold its folds)."""
    if components(num_vertices, faces).max() > 0:
        raise GarmentError(
            name, "the autoencoder needs one connected mesh; this template has several components"
        )
    if radius < stride - 1:
        raise ValueError("radius must be at least stride - 1 so that every vertex is pooled")
    adj = _adjacency(num_vertices, unique_edges(faces))
    sizes, conv, down, up, centres_all = (
        [num_vertices],
        [Neighbourhoods.from_lists(_ring_lists(adj))],
        [],
        [],
        [],
    )
    target = max(min_latent_nodes, 4, int(round(latent_fraction * num_vertices)))
    while sizes[-1] > target and len(sizes) < max_levels:
        centres, pools, coarse = _coarsen(adj, stride, radius)
        # Stop at the level nearest the target on a log scale (coarsening is about 4x per level).
        if len(centres) >= sizes[-1] or abs(np.log(len(centres) / target)) > abs(np.log(sizes[-1] / target)):
            break
        transpose: list[list[int]] = [[] for _ in range(sizes[-1])]
        for i, pool in enumerate(pools):
            for v in pool:
                transpose[v].append(i)
        down.append(Neighbourhoods.from_lists(pools))
        up.append(Neighbourhoods.from_lists(transpose))
        centres_all.append(centres)
        adj = coarse
        sizes.append(len(centres))
        conv.append(Neighbourhoods.from_lists(_ring_lists(adj)))
    return Hierarchy(tuple(sizes), tuple(conv), tuple(down), tuple(up), tuple(centres_all))


def template_key(faces: np.ndarray, num_vertices: int, **options) -> str:
    """A short hash of a template's faces, size and hierarchy options (the cache key)."""
    h = hashlib.sha1(np.ascontiguousarray(faces, np.int64).tobytes())
    h.update(repr((num_vertices, sorted(options.items()))).encode())
    return h.hexdigest()[:16]


def cached_hierarchy(
    faces: np.ndarray, num_vertices: int, cache_dir: Path | None = None, **options
) -> Hierarchy:
    """``build_hierarchy`` with an npz cache (arrays only) keyed by the mesh and options."""
    if cache_dir is None:
        return build_hierarchy(faces, num_vertices, **options)
    shape_options = {k: v for k, v in options.items() if k != "name"}  # the name only labels errors
    path = Path(cache_dir) / f"hierarchy-{template_key(faces, num_vertices, **shape_options)}.npz"
    if path.exists():
        with np.load(path, allow_pickle=False) as z:
            levels = int(z["levels"])
            nb = lambda k: Neighbourhoods(z[f"{k}_index"], z[f"{k}_mask"])  # noqa: E731
            return Hierarchy(
                tuple(int(s) for s in z["sizes"]),
                tuple(nb(f"conv{i}") for i in range(levels)),
                tuple(nb(f"down{i}") for i in range(levels - 1)),
                tuple(nb(f"up{i}") for i in range(levels - 1)),
                tuple(z[f"centres{i}"] for i in range(levels - 1)),
            )
    h = build_hierarchy(faces, num_vertices, **options)
    arrays = {"levels": np.array(h.levels), "sizes": np.array(h.sizes)}
    for kind, items in (("conv", h.conv), ("down", h.down), ("up", h.up)):
        for i, item in enumerate(items):
            arrays[f"{kind}{i}_index"], arrays[f"{kind}{i}_mask"] = item.index, item.mask
    for i, c in enumerate(h.centres):
        arrays[f"centres{i}"] = c
    from ..io_utils import atomic_path

    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, **arrays)
    return h
