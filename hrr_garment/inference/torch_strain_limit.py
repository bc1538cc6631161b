"""The push-out's strain limit (:func:`~hrr_garment.inference.strain_limit.limit_push_strain`) as a
PyTorch module that ONNX can hold, the last part of :class:`~.torch_push_out.PushOutStage`:
Gauss-Seidel passes of edge-length projection, a colour of edges after another, on the characters
with an edge over its limit, each character stopping on its own (an ONNX ``Loop`` while any is
still over).

The passes measure the edges near a tear alone: those with an end within :data:`LIMIT_REACH` rings
of an end of an edge over its limit in any torn character. Every other edge keeps its length as
long as none of its ends moves, and was within its limit to begin with, so the passes do what
passes over every edge do wherever no vertex beyond those rings moved; where one did (a correction
carried that far), they stop at that pass and the passes run again over every edge, from the start.
A single character's passes otherwise read and scatter every edge of the mesh, at onnxruntime's
cost per row; and each pass costs onnxruntime a few microseconds a node whatever the crowd (a
1,046-vertex dress, one character: 22 passes near the tears, then 19 over every edge, before the
stop).

Tensors are (V, 3, N): gathers and scatters of whole vertex rows, the products broadcast over
the characters and the lengths summed a coordinate plane at a time (onnxruntime broadcasts over a
last axis of 3 and sums over a middle one several times slower). A pass runs about 26 nodes a colour
(7 colours on a dress), each once whatever the crowd."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from ..models.graph_loops import exportable_while
from .strain_limit import LIMIT_TOLERANCE_M, OVER_RELAXATION
from .torch_ops import constant

# Rings about a tear's ends whose edges the passes measure: on the real-quick jersey model through
# CMU 02_01 (32 characters, 60 frames), the vertices the passes moved lay at most 1 ring from those
# ends on 6 frames, 2 on 38, 3 on 14 and 4 on 2 (there every edge is measured again).
LIMIT_REACH = 3


class StrainLimitStage(nn.Module):
    """Pushed points (N, V, 3) with what of the push tears the cloth undone, against the points
    before the push."""

    def __init__(self, limits, *, max_strain: float, stretch_slack: float, passes: int = 60):
        super().__init__()
        self.passes = int(passes)
        constant(self, "first", limits.edges[:, 0], dtype=torch.int64)
        constant(self, "second", limits.edges[:, 1], dtype=torch.int64)
        constant(self, "ring", limits.ring, dtype=torch.int64)  # each vertex's 1-ring, padded with itself
        constant(self, "allowed", max_strain * limits.rest_length)
        constant(self, "slack", stretch_slack * limits.rest_length)
        # a pass projects the edges a colour at a time (no two of a colour share a vertex): each
        # colour's edges, their first and second ends, and both ends in one list (one scatter-add
        # moves them)
        self.colours = len(limits.colour_groups)
        for c, group in enumerate(limits.colour_groups):
            first, second = limits.edges[group, 0], limits.edges[group, 1]
            for name, value in (("", group), ("_first", first), ("_second", second)):
                constant(self, f"colour{name}_{c}", value, dtype=torch.int64)
            constant(self, f"colour_ends_{c}", np.concatenate([first, second]), dtype=torch.int64)

    def forward(self, pushed: torch.Tensor, unpushed: torch.Tensor) -> torch.Tensor:
        pushed, unpushed = pushed.permute(1, 2, 0), unpushed.permute(1, 2, 0)
        before = self._lengths(unpushed, self.first, self.second)
        limit = torch.maximum(self.allowed[:, None], before + self.slack[:, None])  # (E, N)
        length = self._lengths(pushed, self.first, self.second)
        # the passes on the torn characters alone, an edge more than a millionth over its limit (each
        # stops on its own: the others would pass through every pass unchanged) ...
        torn = torch.nonzero((length > limit * (1.0 + 1e-6)).any(0))[:, 0]
        start = torch.index_select(pushed, 2, torn).contiguous()
        # ... which correct every edge over its limit at all
        near = self._near((length > limit).any(1))
        limit = torch.index_select(limit, 1, torn)
        limited, strayed = self._passes(start, limit, self._colour_lists(near), near=near)
        # a vertex beyond the rings moved (the near passes stop at the first pass that moves one):
        # its other edges were not measured; all of them, again, from the start (a second loop that
        # runs no pass where none did: a conditional would lose the torn characters' count, which
        # the export cannot then match to the limits')
        again = torch.where(strayed, start, limited)
        skipped = torch.where(strayed, 0, self.passes)
        limited = self._passes(again, limit, self._colour_lists(None), skipped)[0]
        return pushed.index_copy(2, torn, limited).permute(2, 0, 1)

    def _near(self, over: torch.Tensor) -> torch.Tensor:
        """(V,) the vertices within :data:`LIMIT_REACH` rings of an end of an edge ``over`` (E,)."""
        over = torch.nonzero(over)[:, 0]
        ends = torch.cat([torch.index_select(self.first, 0, over), torch.index_select(self.second, 0, over)])
        near = torch.zeros(self.ring.shape[0], device=over.device).index_fill(0, ends, 1.0) > 0
        for _ in range(LIMIT_REACH):
            near = near | near[self.ring].any(1)
        return near

    def _colour_lists(self, near: torch.Tensor | None) -> list[tuple[torch.Tensor, ...]]:
        """Each colour's edges with an end ``near`` (all where None): their indices, first and second
        ends, and both ends in one list."""
        lists = []
        for c in range(self.colours):
            group, first, second = (getattr(self, f"colour{name}_{c}") for name in ("", "_first", "_second"))
            if near is None:
                lists.append((group, first, second, getattr(self, f"colour_ends_{c}")))
                continue
            kept = torch.nonzero(near[first] | near[second])[:, 0]
            # gathered each on its own: a loop's captured tensors may not be views of one another
            group, first, second = (torch.index_select(x, 0, kept) for x in (group, first, second))
            lists.append((group, first, second, torch.cat([first, second])))
        return lists

    def _passes(
        self, p: torch.Tensor, limit: torch.Tensor, lists, start=0, near: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The passes over the colours' ``lists`` on points (V, 3, K) from ``p``, each character until
        no edge is more than :data:`LIMIT_TOLERANCE_M` over its ``limit`` (E, K), at most
        ``self.passes`` counting from ``start`` (a scalar tensor or an int); with ``near`` (V,), the
        vertices the lists' edges were chosen about, stopping after the first pass that moves a vertex
        beyond them (their passes are then done again over every edge: on a dress of 1,046 vertices,
        one character, a correction carried past the rings on most frames, after a score of wasted
        passes). The points, and whether the passes stopped so.

        A colour's edges share no vertex, so a colour's correction writes each of its ends once (a
        scatter without sums), and everything a pass does not change is read before the loop (each
        colour's limits)."""
        state = (
            torch.zeros((), dtype=torch.int64, device=p.device) + start,
            p,
            torch.ones(p.shape[2], dtype=torch.bool, device=p.device),
            torch.zeros((), dtype=torch.bool, device=p.device),
        )
        # the vertices beyond the rings, as floats: an exported loop's body may not close over a
        # boolean tensor, nor on the tensor it carries (so the start is a copy)
        beyond = None if near is None else (~near).to(p.dtype)
        # each colour's limits (e, 1, K), gathered once, not every pass
        limits = [torch.index_select(limit, 0, group)[:, None] for group, _, _, _ in lists]

        def limiting(passes, p, active, strayed):
            return (passes < self.passes) & active.any() & ~strayed

        def one_pass(passes, p, active, strayed):
            weight = active.to(p.dtype)
            # a character stopped (weight 0) moves no vertex; the others move each end of an edge by
            # half its excess, over-relaxed
            share = (0.5 * OVER_RELAXATION) * weight
            excesses = [torch.zeros_like(weight)[None, None]]  # a list near the tears may be empty
            for (_, first, second, ends), allowed in zip(lists, limits):
                p, excess = self._project(p, first, second, ends, allowed, share)
                excesses.append(excess)
            # the worst edge of each character still moving
            worst = torch.cat(excesses).amax((0, 1)) * weight
            if beyond is None:  # (a loop's body may not return its input as it came)
                strayed = strayed.clone()
            else:
                strayed = ((p != origin).any(1).any(1).to(p.dtype) * beyond).amax(0) > 0
            # a character stops on its own
            return passes + 1, p, active & (worst > LIMIT_TOLERANCE_M), strayed

        origin = None if beyond is None else p.clone()
        return exportable_while(limiting, one_pass, state)[1::2]

    @staticmethod
    def _project(p, first, second, ends, allowed, share) -> tuple[torch.Tensor, torch.Tensor]:
        """One colour's projection of points (V, 3, K): its edges ``first`` -> ``second`` (e,) over
        their ``allowed`` lengths (e, 1, K) shortened by ``share`` (K,) of their excess at each end
        (``ends``: both ends in one list). The points and the excesses (e, 1, K)."""
        at_first, at_second = torch.index_select(p, 0, first), torch.index_select(p, 0, second)
        d = at_second - at_first  # (e, 3, K)
        x, y, z = d.split(1, 1)  # the planes: onnxruntime sums over a middle axis slowly
        length = torch.sqrt(x * x + y * y + z * z)  # (e, 1, K)
        excess = torch.clamp(length - allowed, min=0.0)
        corr = (excess * share / torch.clamp(length, min=1e-12)) * d
        # the colour's ends are distinct: each written once, no sums (as index_add's, bit for bit)
        return p.index_copy(0, ends, torch.cat([at_first + corr, at_second - corr])), excess

    @staticmethod
    def _lengths(p: torch.Tensor, first: torch.Tensor, second: torch.Tensor) -> torch.Tensor:
        """The lengths (E, N) of the edges ``first`` -> ``second`` (E,) of points (V, 3, N)."""
        d = torch.index_select(p, 0, second) - torch.index_select(p, 0, first)
        x, y, z = d[:, 0], d[:, 1], d[:, 2]
        return torch.sqrt(x * x + y * y + z * z)
