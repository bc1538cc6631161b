"""ctypes glue of the kernels that push a garment out of the capsule body: the collision push-out
and the push-out's strain limit, with what they take of a garment converted once (``push_out.c``;
library from :func:`hrr_garment.native.load_kernel`; the kernel's structs: :mod:`.kernel_structs`;
the signed distance to the body: :mod:`.capsules`)."""

from __future__ import annotations

import ctypes
from typing import NamedTuple

import numpy as np

from .capsules import capsule_arrays
from .kernel_structs import PushArgs, StrainArgs, SubspaceArgs

MAX_SUBSPACE_COMPONENTS = 512  # SUBSPACE_MAXK in push_out.c


class PushSteps(NamedTuple):
    """The push-out's steps as :func:`push_out_frames` takes them (what each does:
    :func:`hrr_garment.inference.collision.push_out`): ``mean`` the (V, V) CSR mean operator of the
    faces, the ``margin`` outside the body, ``smooth`` passes, ``rounds`` of pushes and the
    ``depth`` beyond which a vertex counts as inside; ``mesh`` (:class:`PushMesh`) the
    neighbour-follow and the patches measured against the capsules near them (None: neither);
    ``limit`` (:class:`StrainLimit`) the strain limit each frame gets right after its push (None: none);
    ``subspace`` (:class:`SubspaceMove`) the push in the garment's subspace before it (None: none)."""

    mean: object
    margin: float
    smooth: int
    rounds: int
    depth: float
    mesh: "PushMesh | None" = None
    limit: "StrainLimit | None" = None
    subspace: "SubspaceMove | None" = None

    def arguments(self) -> PushArgs:
        """The kernel's PushArgs of these steps."""
        return PushArgs(margin=self.margin, smooth=self.smooth, rounds=self.rounds, depth=self.depth)


class SubspaceMove:
    """The push in the garment's subspace as the kernel takes it, converted once
    (:class:`hrr_garment.inference.subspace_push.SubspacePush` holds the reference): the components
    (k, V, 3), stored vertex-major (V, 3, k) so that a vertex's rows are contiguous, in float32 (the
    decoder's own values: exact), and again for the move by blocks of :attr:`BLOCK` vertices, each
    component-major (blocks, k, 3 BLOCK), zero past the last vertex; the stretch (k, k), and the
    push's settings."""

    BLOCK = 64  # subspace_push.c's MOVE_BLOCK

    def __init__(
        self,
        basis: np.ndarray,
        stretch: np.ndarray,
        strain_weight: float,
        ridge: float,
        clearance: float,
        iterations: int,
    ) -> None:
        if not 1 <= len(basis) <= MAX_SUBSPACE_COMPONENTS:
            raise ValueError(
                f"the native subspace push takes 1 to {MAX_SUBSPACE_COMPONENTS} components, not {len(basis)}"
            )
        basis = np.asarray(basis, np.float32)
        k, v = basis.shape[:2]
        self.basis = np.ascontiguousarray(basis.transpose(1, 2, 0))
        count = -(-v // self.BLOCK)
        padded = np.zeros((k, count * self.BLOCK, 3), np.float32)
        padded[:, :v] = basis
        self.blocks = np.ascontiguousarray(padded.reshape(k, count, 3 * self.BLOCK).transpose(1, 0, 2))
        self.stretch = np.ascontiguousarray(stretch, np.float64)
        self.struct = SubspaceArgs(
            basis=self.basis.ctypes.data,
            blocks=self.blocks.ctypes.data,
            stretch=self.stretch.ctypes.data,
            k=len(self.stretch),
            iterations=int(iterations),
            strain_weight=float(strain_weight),
            ridge=float(ridge),
            clearance=float(clearance),
        )


class PushMesh:
    """What the kernel's neighbour-follow and culled distances take of a garment, converted once:
    the padded 1-ring (V, D) int32 with ``slope`` x each slot's rest distance (float64, inf in the
    padding), ``follow`` passes, and the vertex patches (offsets (P + 1,), indices (V,) int32)."""

    def __init__(
        self,
        ring: np.ndarray,
        ring_length: np.ndarray,
        slope: float,
        follow: int,
        patches: tuple[np.ndarray, np.ndarray],
    ) -> None:
        self.ring = np.ascontiguousarray(ring, np.int32)
        self.ring_drop = np.ascontiguousarray(slope * np.asarray(ring_length, np.float64))
        self.follow = int(follow)
        self.patch_ptr, self.patch_idx = (np.ascontiguousarray(x, np.int32) for x in patches)

    def arguments(self) -> tuple:
        """hrr_push_out's ring, ring_drop, width, follow, patch_ptr, patch_idx, patches."""
        return (
            self.ring.ctypes.data,
            self.ring_drop.ctypes.data,
            self.ring.shape[1],
            self.follow,
            self.patch_ptr.ctypes.data,
            self.patch_idx.ctypes.data,
            len(self.patch_ptr) - 1,
        )


class EdgeArrays:
    """A garment's edges as the strain limit's kernel takes them, converted once: (E, 2) vertex
    pairs int32, rest lengths float64 (a row per body where the frames' bodies differ, with each
    frame's body ``body_of_frame``), colours uint8 (no two edges of a colour share a vertex) with
    each colour's offset in an E-long array, and each vertex's edges (CSR indptr and indices int32),
    with their addresses (a stream limits every frame, and asking numpy for five addresses cost a
    fifth of a one-frame limit)."""

    def __init__(
        self,
        edges: np.ndarray,
        rest_length: np.ndarray,
        colour: np.ndarray,
        vertex_edges_indptr: np.ndarray,
        vertex_edges_indices: np.ndarray,
        body_of_frame: np.ndarray | None = None,
    ) -> None:
        self.edges = np.ascontiguousarray(edges, np.int32)
        self.rest_length = np.ascontiguousarray(rest_length, np.float64)  # (E,) or (B, E) with body_of_frame
        self.body_of_frame = None if body_of_frame is None else np.ascontiguousarray(body_of_frame, np.int64)
        self.colour = np.ascontiguousarray(colour, np.uint8)
        self.colours = int(self.colour.max()) + 1 if len(self.colour) else 0
        self.colour_ptr = np.r_[0, np.cumsum(np.bincount(self.colour, minlength=self.colours))].astype(
            np.int32
        )
        self.indptr = np.ascontiguousarray(vertex_edges_indptr, np.int32)
        self.indices = np.ascontiguousarray(vertex_edges_indices, np.int32)
        self.addresses = tuple(
            a.ctypes.data
            for a in (self.edges, self.rest_length, self.colour, self.colour_ptr, self.indptr, self.indices)
        )


class StrainLimit(NamedTuple):
    """The strain limit as :func:`limit_strain` takes it: the garment's ``edge_arrays``
    (:class:`EdgeArrays`), the ``max_strain`` an edge may reach, at most ``iterations`` passes, the
    tolerance ``tol`` (metres) and the over-relaxation ``omega``."""

    edge_arrays: EdgeArrays
    max_strain: float
    iterations: int
    tol: float
    omega: float
    slack: float = 0.0
    # where the frames limited start among those the edge arrays' body_of_frame was made for (a
    # push in chunks of frames)
    first_frame: int = 0

    def arguments(self) -> StrainArgs:
        """The kernel's StrainArgs of this limit (the edge arrays' addresses: keep them alive)."""
        arrays = self.edge_arrays
        edges, rest, colour, colour_ptr, ve_ptr, ve_idx = arrays.addresses
        rows = arrays.body_of_frame
        return StrainArgs(
            rest_row=None if rows is None else rows.ctypes.data + rows.itemsize * self.first_frame,
            edges=edges,
            rest=rest,
            colour=colour,
            colour_ptr=colour_ptr,
            ve_ptr=ve_ptr,
            ve_idx=ve_idx,
            E=len(arrays.edges),
            colours=arrays.colours,
            iterations=self.iterations,
            max_strain=self.max_strain,
            slack=self.slack,
            tol=self.tol,
            omega=self.omega,
        )


def push_out_frames(  # noqa: PLR0913  (the frames, their regression, the body, the steps: each its own)
    lib: ctypes.CDLL,
    points: np.ndarray,
    capsules: tuple,
    steps: PushSteps,
    *,
    turn: np.ndarray | None = None,
    skin: int | None = None,
    threads: int = 1,
    out: np.ndarray | None = None,
    base: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`hrr_garment.inference.collision.push_out`'s per-frame steps in the kernel: points
    (T, V, 3) float32 or float64 (others are converted to float32), ``capsules`` (ends a, b
    (T, C, 3), radii (C,) or per frame (T, C)), the push's ``steps`` -> (pushed points float32,
    fraction deeper than ``steps.depth`` before (T,), after (T,), the (T,) mask of frames the strain
    limit moved). The push and the limit work in float64, a frame at a time. With
    ``steps.subspace``, each frame is first moved in the garment's subspace, its body frame turned
    by ``turn`` (T, 3, 3, body -> world), and ``before`` is the mesh push's. With ``steps.limit``,
    each frame is limited right after its push (as :func:`limit_strain` on the pushed and unpushed
    frames would, measuring only the edges of the vertices the push moved); ``after`` is the push's,
    before the limit. Frames in parallel; a single frame (streaming) shared by the threads. ``out``:
    a C-contiguous float32 array of the points' shape the pushed points are written to (and
    returned). ``skin``: the address of T :class:`~.skin.SkinPose` structs (:class:`~.skin.PosedSkins`),
    when the body is the skin the viewer sees; ``capsules`` then are its hulls
    (:mod:`hrr_garment.body.skin_envelope`), and the points within the margin of one are measured against
    the skin. ``base``: (T, V, 3) the regression under a mode's additions, taken back first where
    they carry the cloth into the body (:mod:`hrr_garment.inference.take_back`); ``before`` is then
    of the points as they came."""
    mean, *_, mesh, limit, subspace = steps
    a, b, r = capsule_arrays(*capsules)
    p = np.ascontiguousarray(points, np.float64 if np.asarray(points).dtype == np.float64 else np.float32)
    if out is None:
        out = np.empty(p.shape, np.float32)
    elif out.dtype != np.float32 or out.shape != p.shape or not out.flags.c_contiguous:
        raise ValueError("out must be a C-contiguous float32 array of the points' shape")
    t, v = p.shape[:2]
    if subspace is not None:
        if turn is None or np.shape(turn) != (t, 3, 3):
            raise ValueError(
                f"the subspace push needs each frame's body turn (T, 3, 3), got {np.shape(turn)}"
            )
        if subspace.basis.shape[0] != v:
            raise ValueError(f"a subspace of {subspace.basis.shape[0]} vertices for frames of {v}")
        turn = np.ascontiguousarray(turn, np.float64)
    indptr, indices = (np.ascontiguousarray(x, np.int32) for x in (mean.indptr, mean.indices))
    weights = np.ascontiguousarray(mean.data, np.float64)
    before, after, torn = np.empty(t), np.empty(t), np.zeros(t, np.uint8)
    if r.ndim == 2 and r.shape[0] != t:
        raise ValueError(f"per-frame radii for {r.shape[0]} frames, points for {t}")
    count = r.shape[-1]
    rows = None if limit is None else limit.edge_arrays.body_of_frame
    if rows is not None and len(rows) < limit.first_frame + t:
        raise ValueError(f"a strain limit for {len(rows)} frames, {t} from frame {limit.first_frame} pushed")
    push_args, strain_args = steps.arguments(), None if limit is None else limit.arguments()
    if base is not None:
        base = np.ascontiguousarray(base, np.float32)
        if base.shape != p.shape:
            raise ValueError(f"the regression's frames {base.shape} for points {p.shape}")
    lib.hrr_push_out(
        p.ctypes.data,
        int(p.dtype == np.float64),
        out.ctypes.data,
        t,
        v,
        a.ctypes.data,
        b.ctypes.data,
        r.ctypes.data,
        count,
        count if r.ndim == 2 else 0,
        indptr.ctypes.data,
        indices.ctypes.data,
        weights.ctypes.data,
        *(mesh.arguments() if mesh is not None else (None, None, 1, 0, None, None, 0)),
        ctypes.byref(push_args),
        None if strain_args is None else ctypes.byref(strain_args),
        None if subspace is None else ctypes.byref(subspace.struct),
        None if subspace is None else turn.ctypes.data,
        skin,
        None if base is None else base.ctypes.data,
        threads,
        before.ctypes.data,
        after.ctypes.data,
        torn.ctypes.data,
    )
    if np.isnan(before).any():
        raise MemoryError("the native push-out could not allocate its scratch memory")
    return out, before, after, torn.astype(bool)


def limit_strain(
    lib: ctypes.CDLL,
    pushed: np.ndarray,
    unpushed: np.ndarray,
    limit: StrainLimit,
    *,
    threads: int = 1,
    in_place: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hrr_garment.inference.strain_limit.limit_push_strain` in the kernel: pushed and unpushed
    points (T, V, 3), the ``limit`` (:class:`StrainLimit`) -> (the limited points, float64 (T, V, 3);
    the (T,) mask of frames that had an edge over its limit). Frames in parallel; each stops on its
    own. ``in_place``: a C-contiguous float64 ``pushed`` is moved where it lies (and returned)
    instead of copied."""
    rows = limit.edge_arrays.body_of_frame
    if rows is not None and len(rows) < limit.first_frame + len(pushed):
        raise ValueError(
            f"a strain limit for {len(rows)} frames, {len(pushed)} from frame {limit.first_frame} given"
        )
    own = in_place and pushed.dtype == np.float64 and pushed.flags.c_contiguous
    p = pushed if own else np.array(pushed, np.float64, order="C")  # moved in place
    u = np.ascontiguousarray(unpushed, np.float64)
    torn = np.zeros(len(p), np.uint8)
    if (
        lib.hrr_limit_strain(
            p.ctypes.data,
            u.ctypes.data,
            len(p),
            p.shape[1],
            ctypes.byref(limit.arguments()),
            threads,
            torn.ctypes.data,
        )
        != 0
    ):
        raise MemoryError("the native strain limit could not allocate its scratch memory")
    return p, torn.astype(bool)
