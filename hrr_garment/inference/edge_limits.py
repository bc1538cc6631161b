"""What the push-out and its strain limit need of a garment, made once per template
(:class:`EdgeLimits`): its edges and rest lengths, the incidence, the edges' colours the strain
limit projects them by, the 1-ring table the neighbour-follow walks, and the vertex patches the
kernel measures against the capsules near them (:mod:`.collision` and :mod:`.strain_limit` run them)."""

from __future__ import annotations

from dataclasses import dataclass, replace
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
    rest_length: np.ndarray  # (E,), or (B, E) a row per body where ``body_of_frame`` is set
    signs: csr_matrix
    colour: np.ndarray  # (E,) uint8
    ring: np.ndarray  # (V, D) int32
    ring_length: np.ndarray  # (V, D) float64, inf where padded
    patches: tuple[np.ndarray, np.ndarray]  # (P + 1,) offsets into (V,) vertex indices, int32
    # (T,) int64 the body of each frame pushed, where the frames' garments rest in different shapes (a
    # crowd of bodies: :meth:`on_bodies`); None: ``rest_length`` is every frame's
    body_of_frame: np.ndarray | None = None

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

    def on_bodies(self, rests: np.ndarray, body_of_frame: np.ndarray | None = None) -> "EdgeLimits":
        """The same garment resting in other shapes: ``rests`` (V, 3), or (B, V, 3) with
        ``body_of_frame`` (T,) the one each pushed frame's garment rests in. Why: a garment carried
        onto a body is not the template (on a character its edges run 0.65 to 1.9 x the template's),
        and a strain limit measured against the template's lengths takes the carried garment's own
        long edges for torn ones. One rest shape also gives the neighbour-follow its 1-ring
        distances; several keep the template's there (the follow is off in the product's push)."""
        rests = np.asarray(rests, np.float64)
        single = rests.ndim == 2
        rests = rests[None] if single else rests
        lengths = self.lengths(rests)
        if single or len(rests) == 1:
            ring_length = _ring_lengths(self.ring, rests[0])
            return replace(self, rest_length=lengths[0], ring_length=ring_length, body_of_frame=None)
        if body_of_frame is None:
            raise ValueError(f"{len(rests)} rest shapes need each frame's body (body_of_frame)")
        which = np.asarray(body_of_frame, np.int64)
        if which.size and (which.min() < 0 or which.max() >= len(rests)):
            raise ValueError(f"body_of_frame names bodies outside 0..{len(rests) - 1}")
        return replace(self, rest_length=lengths, body_of_frame=which)

    def of_frames(self, rows: np.ndarray) -> "EdgeLimits":
        """These limits for the frames ``rows`` (indices) of the frames they were made for."""
        if self.body_of_frame is None:
            return self
        return replace(self, body_of_frame=self.body_of_frame[rows])

    def frame_rest_length(self, frames: int) -> np.ndarray:
        """The rest lengths of ``frames`` frames: (E,) the one rest's, or (T, E) each frame's body's."""
        if self.body_of_frame is None:
            return self.rest_length
        if len(self.body_of_frame) != frames:
            raise ValueError(f"limits made for {len(self.body_of_frame)} frames, given {frames}")
        return self.rest_length[self.body_of_frame]

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
            body_of_frame=self.body_of_frame,
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
    return ring, _ring_lengths(ring, rest)


def _ring_lengths(ring: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """(V, D) float64 the rest distance from each vertex to each of its ring's neighbours, inf in the
    padding (the slots that repeat the vertex itself: no vertex is its own neighbour)."""
    own = np.arange(len(rest))[:, None]
    length = np.linalg.norm(rest[ring] - rest[own], axis=-1).astype(np.float64)
    return np.where(ring == own, np.inf, length)


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
