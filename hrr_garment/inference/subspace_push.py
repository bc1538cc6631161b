"""The push in the garment's own subspace: a decoded frame whose cloth lies inside the body is
moved, before the mesh push-out, by the combination of the fast decoder's principal components
(:mod:`hrr_garment.models.subspace`) that best takes the cloth out.

Why: the mesh push-out (:mod:`.collision`) moves each vertex to the nearest surface; where a trained
model decodes a patch centimetres inside a curved limb, its vertices leave along normals that
diverge and the cloth tears, which the strain limit then undoes (docs/decisions/0023: 58.5 % of
frames on the trained 4,156-vertex subset model). The principal components are the ways the
garment moves as a whole; moving along them a region comes out together, and the mesh push-out
has millimetres left to do.

Per frame, ``iterations`` times: the vertices within the push-out's margin plus ``clearance`` of the
body (S), each with the depth it must rise along the nearest capsule's normal to be that far out,
give one row each of J (|S| x k): the normal (in the body frame) against each component at that
vertex. A row weighs from 0 where its vertex enters S to 1 at the margin and inside (W), so that the
move grows from nothing as cloth nears the body instead of starting at once (streams and offline
alike: no jitter from a vertex crossing the margin). The coefficients s solve
(J^T W J + w G + r tr(W) I) s = J^T W depth, where G (k x k, made once) is the first-order stretch
of the garment's edges (along their rest directions) per pair of components: a move that would
stretch the cloth costs ``strain_weight`` per square metre of stretch, as a missed metre of depth
does. The frame moves by s over the components, turned into the world. A frame with no vertex near
the body is left exactly as it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from ..body.capsules import frames_signed_distance
from ..motion.frame import body_heading
from ..motion.motion import Motion
from ..native.body import SubspaceMove

if TYPE_CHECKING:
    from .visible_push import PosedSkin

# components the push uses: on the trained 4,156-vertex subset model (docs/decisions/0032) 32 of its
# 128 tore as few frames as 128 (36.7 against 35.6 %), for the same error and a lower strain max
COMPONENTS = 32


@dataclass(frozen=True)
class SubspacePush:
    """The subspace push of one garment and basis (:meth:`of`), run on frames by calling it."""

    basis: np.ndarray  # (k, V, 3) float64, orthonormal components in the body frame
    stretch: np.ndarray  # (k, k) G: the edges' first-order stretch per pair of components
    strain_weight: float = 10.0  # w: what a square metre of edge stretch costs against one of missed depth
    # r: per unit of weight in S: keeps the solve well posed and the move small where it buys little
    # depth; on the subset model 1e-4 tore 25.4 % of frames with jitter 1.11 x the truth's, 1e-6
    # 23.6 % with 1.18, 1e-3 33.8 % with 1.09 (the mesh push alone: 58.5 %, 1.09; docs/decisions/0032)
    ridge: float = 1e-4
    clearance: float = (
        0.003  # metres past the push-out's margin the subspace aims for (the mesh push-out does the rest)
    )
    # (and the band over which a vertex's weight grows from 0 to 1 as it nears the body)
    iterations: int = 2  # solves a frame (a move can bring other vertices near the body)

    def __post_init__(self) -> None:
        if not self.clearance > 0:
            raise ValueError(
                "clearance must be > 0 metres (the band a vertex's weight grows over), got "
                f"{self.clearance!r}"
            )

    @classmethod
    def of(
        cls, basis: np.ndarray, rest: np.ndarray, edges: np.ndarray, components: int = COMPONENTS, **settings
    ) -> "SubspacePush":
        """``basis`` (K, 3V) orthonormal rows (:class:`~hrr_garment.models.subspace.SubspaceDecoder`'s),
        the template's ``rest`` vertices (V, 3) and ``edges`` (E, 2); the first ``components`` (at most K)."""
        if components < 1:
            raise ValueError(f"components must be at least 1, got {components}")
        k = min(int(components), len(basis))
        b3 = np.asarray(basis[:k], np.float64).reshape(k, len(rest), 3)
        direction = rest[edges[:, 1]].astype(np.float64) - rest[edges[:, 0]]
        direction /= np.maximum(np.linalg.norm(direction, axis=1, keepdims=True), 1e-12)
        rows = np.einsum("ei,kei->ek", direction, b3[:, edges[:, 1]] - b3[:, edges[:, 0]])  # (E, k)
        return cls(b3, rows.T @ rows, **settings)

    @cached_property
    def native(self) -> SubspaceMove:
        """What the push-out's kernel takes of this push (:class:`~hrr_garment.native.body.SubspaceMove`),
        converted once."""
        return SubspaceMove(
            self.basis,
            self.stretch,
            strain_weight=self.strain_weight,
            ridge=self.ridge,
            clearance=self.clearance,
            iterations=self.iterations,
        )

    def __call__(
        self,
        vertices: np.ndarray,
        motion: Motion,
        body: "tuple[np.ndarray, np.ndarray, np.ndarray] | PosedSkin",
        margin: float,
    ) -> np.ndarray:
        """(T, V, 3) world vertices, their frames' ``motion`` (the body frame's heading) and the body
        posed for them -> the moved copy, float32. ``body``: capsules (a, b (T, C, 3), radii (C,) or
        (T, C)), or the mesh the viewer sees (:class:`~.visible_push.PosedSkin`: the skin's distances
        and normals, :meth:`~.visible_push.PosedSkin.distance`, measured within the push's reach)."""
        reach = margin + self.clearance
        if isinstance(body, tuple):
            a, b, radii = body

            def distance(points: np.ndarray, t: int) -> tuple[np.ndarray, np.ndarray]:
                frame_radii = radii[t] if np.ndim(radii) == 2 else radii
                return frames_signed_distance(points, a[t : t + 1], b[t : t + 1], radii=frame_radii)
        else:

            def distance(points: np.ndarray, t: int) -> tuple[np.ndarray, np.ndarray]:
                return body.distance(points, slice(t, t + 1), reach)

        _, turn = body_heading(motion)  # (T, 3, 3) body frame -> world: local rows = world rows @ turn
        out = np.array(vertices, np.float64)
        k, v = self.basis.shape[:2]
        flat = self.basis.reshape(k, -1)
        for t in range(len(out)):
            for _ in range(self.iterations):
                d, n = distance(out[t : t + 1], t)
                near = np.nonzero(d[0] < reach)[0]
                if not len(near):
                    break
                depth = reach - d[0, near]
                weight = np.minimum(depth / self.clearance, 1.0)
                jac = np.einsum("si,ksi->sk", n[0, near] @ turn[t], self.basis[:, near])  # (|S|, k)
                weighted = jac * weight[:, None]
                system = (
                    weighted.T @ jac
                    + self.strain_weight * self.stretch
                    + self.ridge * weight.sum() * np.eye(k)
                )
                s = np.linalg.solve(system, weighted.T @ depth)
                out[t] += (s @ flat).reshape(v, 3) @ turn[t].T
        return out.astype(np.float32)
