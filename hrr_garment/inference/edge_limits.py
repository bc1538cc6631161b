"""What the push-out and its strain limit need of a garment, made once per template
(:class:`EdgeLimits`): its edges and rest lengths, the incidence, the edges' colours the strain
limit projects them by, the 1-ring table the neighbour-follow walks, and the vertex patches the
kernel measures against the capsules near them (:mod:`.collision` and :mod:`.strain_limit` run them)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import csr_matrix

from ..garment.mesh import unique_edges
from ..garment.smoothing import mean_operator
from ..native.body import EdgeArrays, PushMesh

if TYPE_CHECKING:
    from .collision import PushOutSettings


@dataclass(frozen=True)
class EdgeLimits:
    """What the push-out's neighbour-follow and :func:`~.strain_limit.limit_push_strain` need of a garment,
    made once per template (the streaming path calls the push-out every frame): its edges, their rest
    lengths, the (V, E) incidence (+1 first vertex, -1 second; its rows list each vertex's edges),
    the edges' colours (no two edges of a colour share a vertex: the strain limit projects a colour's
    edges at once, colour after colour), each vertex's 1-ring as a padded table (V, D) with each
    neighbour's rest distance (inf in the padding, which repeats the vertex itself), and the vertices
    in patches of neighbours (the kernel measures a patch only against the capsules near it)."""

    edges: np.ndarray
    rest_length: np.ndarray
    signs: csr_matrix
    colour: np.ndarray  # (E,) uint8
    ring: np.ndarray  # (V, D) int32
    ring_length: np.ndarray  # (V, D) float64, inf where padded
    patches: tuple[np.ndarray, np.ndarray]  # (P + 1,) offsets into (V,) vertex indices, int32

    @classmethod
    def of(cls, faces: np.ndarray, rest: np.ndarray, mean: csr_matrix | None = None) -> "EdgeLimits":
        """``mean``: the faces' :func:`mean_operator`, where the caller has it already (its order is the
        ring's)."""
        edges = unique_edges(faces)
        v, e = len(rest), len(edges)
        signs = csr_matrix(
            (
                np.r_[np.ones(e), -np.ones(e)],
                (np.r_[edges[:, 0], edges[:, 1]], np.r_[np.arange(e), np.arange(e)]),
            ),
            shape=(v, e),
        )
        ring, ring_length = _ring_table(mean_operator(faces, v) if mean is None else mean, rest)
        return cls(
            edges,
            np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=-1),
            signs,
            _edge_colours(edges, v),
            ring,
            ring_length,
            _patches(rest),
        )

    @cached_property
    def colour_groups(self) -> tuple[np.ndarray, ...]:
        """The edge indices of each colour, in colour order."""
        return tuple(
            np.flatnonzero(self.colour == c)
            for c in range(int(self.colour.max()) + 1 if len(self.colour) else 0)
        )

    @cached_property
    def _push_meshes(self) -> dict:
        return {}

    def push_mesh(self, settings: "PushOutSettings") -> PushMesh:
        """What the push-out's kernel takes of this garment under ``settings``, converted once per
        settings."""
        key = (settings.follow, settings.follow_slope)
        if key not in self._push_meshes:
            self._push_meshes[key] = PushMesh(
                self.ring,
                self.ring_length,
                settings.follow_slope,
                follow=settings.follow,
                patches=self.patches,
            )
        return self._push_meshes[key]

    @cached_property
    def native_arrays(self) -> EdgeArrays:
        """What the kernel takes, converted once (a stream limits every frame)."""
        return EdgeArrays(
            edges=self.edges,
            rest_length=self.rest_length,
            colour=self.colour,
            vertex_edges_indptr=self.signs.indptr,
            vertex_edges_indices=self.signs.indices,
        )

    def lengths(self, p: np.ndarray) -> np.ndarray:
        """(T, E) edge lengths of (T, V, 3) positions."""
        return np.linalg.norm(p[:, self.edges[:, 1]] - p[:, self.edges[:, 0]], axis=-1)


def _edge_colours(edges: np.ndarray, num_vertices: int) -> np.ndarray:
    """Greedy edge colouring in edge order: each edge the smallest colour neither of its vertices'
    edges has yet, (E,) uint8 (a triangle mesh needs about its largest vertex degree, 7 on the
    dress). Each vertex's colours are a bit mask."""
    taken = [0] * num_vertices
    colour = np.empty(len(edges), np.uint8)
    for e, (i, j) in enumerate(edges.tolist()):
        free = ~(taken[i] | taken[j])
        c = (free & -free).bit_length() - 1  # the lowest free colour
        if c > 255:
            raise ValueError(f"a vertex of more than 128 edges (edge {e}: {i}-{j}): not a garment mesh")
        colour[e] = c
        taken[i] |= 1 << c
        taken[j] |= 1 << c
    return colour


def _ring_table(mean: csr_matrix, rest: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each vertex's neighbours in the mean operator's order, padded to the widest ring with the
    vertex itself at an infinite distance, and their rest distances."""
    counts = np.diff(mean.indptr)
    width = max(int(counts.max(initial=0)), 1)
    ring = np.repeat(np.arange(len(rest), dtype=np.int32)[:, None], width, 1)
    slot = np.arange(len(mean.indices)) - np.repeat(mean.indptr[:-1], counts)
    rows = np.repeat(np.arange(len(rest)), counts)
    ring[rows, slot] = mean.indices
    length = np.full(ring.shape, np.inf)
    length[rows, slot] = np.linalg.norm(rest[mean.indices] - rest[rows], axis=-1)
    return ring, length


def _patches(rest: np.ndarray, size: int = 48) -> tuple[np.ndarray, np.ndarray]:
    """The vertices split into patches of at most ``size`` by halving along the longest side:
    (offsets (P + 1,), vertex indices (V,)), both int32."""
    stack, groups = [np.arange(len(rest))], []
    while stack:
        part = stack.pop()
        if len(part) <= size:
            groups.append(part)
            continue
        axis = np.ptp(rest[part], 0).argmax()
        order = part[np.argsort(rest[part, axis], kind="stable")]
        stack += [order[len(order) // 2 :], order[: len(order) // 2]]
    return (
        np.r_[0, np.cumsum([len(g) for g in groups])].astype(np.int32),
        np.concatenate(groups).astype(np.int32) if groups else np.zeros(0, np.int32),
    )
