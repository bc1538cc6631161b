"""The push-out's strain limit: undoing as much of a push as tears the cloth (edges stretched past a
limit by the push are shortened again, frame by frame), in the kernel of :mod:`hrr_garment.native`
where there is a C compiler and in numpy otherwise (the reference). :mod:`.collision` runs it last."""

from __future__ import annotations

import numpy as np

from .edge_limits import EdgeLimits

# edges a push may stretch to (times their rest length): the simulator's own data reach 2.1-2.5 at
# their worst frame and 1.12-1.15 at p99; a push that needs more is across a limb, not out of the body
MAX_PUSH_STRAIN = 1.5
LIMIT_TOLERANCE_M = 1e-5  # an edge this little over its limit counts as within it (the limiter stops)
# the strain limiter's over-relaxation: an over-long edge is shortened this x its excess. Its Gauss-Seidel
# passes (a colour of edges after another) reach 0.01 mm in 5 at the median on a trained model's torn
# frames, where Jacobi's (each vertex moved by its corrections over its degree) left 0.1 mm after 60
OVER_RELAXATION = 1.7
LIMIT_ITERATIONS = 60  # the strain limiter's passes at most (a frame stops once within its limits)


def limit_push_strain(
    pushed: np.ndarray,
    unpushed: np.ndarray,
    limits: EdgeLimits,
    max_strain: float = MAX_PUSH_STRAIN,
    iterations: int = LIMIT_ITERATIONS,
    in_place: bool = False,
    slack: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Undo as much of a push as tears the cloth: at most ``iterations`` Gauss-Seidel passes of
    edge-length projection (an over-long edge's two ends move toward each other by half its excess
    each, over-relaxed; the edges a colour at a time, :attr:`EdgeLimits.colour`) on the frames where
    an edge of ``pushed`` is longer than ``max_strain`` times its rest length and longer than it was
    ``unpushed`` plus ``slack`` times its rest length; a frame stops after a pass with no edge more
    than :data:`LIMIT_TOLERANCE_M` over; every other edge and frame is left as it is. Returns the
    vertices and the (T,) mask of the frames it changed.

    Why: where the capture drives a limb through the body (a hand in the belly), a vertex caught in
    both capsules is pushed out of the nearest surface, across the limb, while its neighbours stay:
    edges ten times their length (CMU 131_03), which no simulator would produce."""
    from ..native import default_threads, load_kernel
    from ..native.body import limit_strain

    lib = load_kernel()
    if lib is not None:  # the same in C: the limits, the torn frames and the passes, which measure only
        # the edges that can have changed
        limit = native_strain_limit(limits, max_strain, slack, iterations)
        p, torn = limit_strain(
            lib, pushed, unpushed, limit=limit, threads=default_threads(), in_place=in_place
        )
        if p is pushed or not torn.any():
            return pushed, torn
        # the frames it left are ``pushed``'s widened to float64: narrowing them back is exact
        return p.astype(pushed.dtype, copy=False), torn
    rest = limits.frame_rest_length(len(pushed))
    limit = np.maximum(max_strain * rest, limits.lengths(unpushed.astype(np.float64)) + slack * rest)
    torn = (limits.lengths(pushed.astype(np.float64)) > limit * (1 + 1e-6)).any(1)
    if not torn.any():
        return pushed, torn
    out = pushed.copy()
    out[torn] = _limit_frames(pushed[torn].astype(np.float64), limit[torn], limits, iterations).astype(
        pushed.dtype
    )
    return out, torn


def native_strain_limit(
    limits: EdgeLimits, max_strain: float, slack: float, iterations: int = LIMIT_ITERATIONS
):
    """The strain limit as the kernel takes it (:class:`~hrr_garment.native.body.StrainLimit`)."""
    from ..native.body import StrainLimit

    return StrainLimit(
        edge_arrays=limits.native_arrays,
        max_strain=max_strain,
        iterations=iterations,
        tol=LIMIT_TOLERANCE_M,
        omega=OVER_RELAXATION,
        slack=slack,
    )


def _limit_frames(p: np.ndarray, limit: np.ndarray, limits: EdgeLimits, iterations: int) -> np.ndarray:
    """The reference (and the path without a C compiler) of :func:`limit_push_strain`'s passes:
    (T, V, 3) float64 positions with their (T, E) limits, moved in place."""
    active = np.arange(len(p))  # frames still over the limit: each stops on its own, so a frame's result
    for _ in range(iterations):  # does not depend on the others it is batched with (streaming = offline)
        q, lim, worst = p[active], limit[active], np.zeros(len(active))  # this pass's frames, moved in q
        for group in limits.colour_groups:  # no two edges of a colour share a vertex: projected at once
            i, j = limits.edges[group, 0], limits.edges[group, 1]
            d = q[:, j] - q[:, i]  # (a, e, 3)
            length = np.sqrt((d * d).sum(-1))
            excess = np.maximum(length - lim[:, group], 0.0)
            worst = np.maximum(worst, excess.max(1, initial=0.0))
            corr = (OVER_RELAXATION * 0.5 * excess / np.maximum(length, 1e-12))[..., None] * d
            q[:, i] += corr
            q[:, j] -= corr
        p[active] = q
        active = active[worst > LIMIT_TOLERANCE_M]
        if not len(active):
            break
    return p
