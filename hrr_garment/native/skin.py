"""The inverse-skinning collider as the kernel takes it (``skin_sdf.c``; the numpy reference is
:class:`hrr_garment.body.skin_collider.SkinCollider`): its arrays converted once, and the signed
distance of points to the body it follows, posed per frame.

    kernel = SkinKernel(collider, load_kernel())       # a SkinCollider, converted once
    distance, normal = kernel.query(points, global_rotations, joint_positions)
"""

from __future__ import annotations

import ctypes

import numpy as np

MAX_STARTS = 8  # SKIN_MAX_STARTS in skin_sdf.c
MAX_JOINTS = 255  # a node's joints are bytes
# skin_sdf.c's SkinNode: one node of the rest grid in 32 bytes
NODE = np.dtype([("distance", "<f4"), ("weights", "<f4", 4), ("joints", "u1", 4), ("pad", "<i4", 2)])


class SkinGrid(ctypes.Structure):
    """skin_sdf.c's SkinGrid."""

    _fields_ = [
        ("nodes", ctypes.c_void_p),
        ("face_start", ctypes.c_void_p),
        ("face_list", ctypes.c_void_p),
        ("faces", ctypes.c_void_p),
        ("neighbours", ctypes.c_void_p),
        ("corner_start", ctypes.c_void_p),
        ("corner_list", ctypes.c_void_p),
        ("rest", ctypes.c_void_p),
        ("vertex_joints", ctypes.c_void_p),
        ("vertex_weights", ctypes.c_void_p),
        ("shape", ctypes.c_int * 3),
        ("V", ctypes.c_int),
        ("F", ctypes.c_int),
        ("J", ctypes.c_int),
        ("vertex_k", ctypes.c_int),
        ("starts", ctypes.c_int),
        ("iterations", ctypes.c_int),
        ("origin", ctypes.c_double * 3),
        ("voxel", ctypes.c_double),
        ("step", ctypes.c_double),
        ("settled", ctypes.c_double),
        ("deep", ctypes.c_double),
        ("off_skin", ctypes.c_double),
        ("face_side", ctypes.c_double),
    ]


def vertex_corners(faces: np.ndarray, vertices: int) -> dict[str, np.ndarray]:
    """Each vertex's corners (3 f + k: face f's corner k) as the kernel's ``corner_start`` (V + 1,)
    and ``corner_list``, int32: where a point's nearest point is a vertex, its pseudonormal is
    measured over them."""
    flat = np.asarray(faces, np.int64).ravel()
    order = np.argsort(flat, kind="stable")
    start = np.searchsorted(flat[order], np.arange(vertices + 1))
    return {"corner_start": start.astype(np.int32), "corner_list": order.astype(np.int32)}


class SkinKernel:
    """A :class:`~hrr_garment.body.skin_collider.SkinCollider`'s arrays in the kernel's layout (held
    here, so that the struct's addresses stay valid): the grid's nodes packed 32 bytes each, its face
    lists as they are, the mesh's faces as int32 and each vertex's skin as its joints with a weight
    (padded with weight 0)."""

    def __init__(self, collider, lib: ctypes.CDLL) -> None:
        body, settings = collider.body, collider.settings
        if not 1 <= settings.starts <= MAX_STARTS or body.weights.shape[1] > MAX_JOINTS:
            raise ValueError(
                f"the native skin collider takes 1 to {MAX_STARTS} starts and up to {MAX_JOINTS} joints, "
                f"not {settings.starts} and {body.weights.shape[1]}"
            )
        self.joint_transforms = body.joint_transforms
        used = body.weights != 0.0
        k = max(1, int(used.sum(1).max()))
        order = np.argsort(~used, axis=1, kind="stable")[:, :k]  # each vertex's joints with weight first
        nodes = np.zeros(len(collider.distance), NODE)
        nodes["distance"], nodes["weights"], nodes["joints"] = (
            collider.distance,
            collider.weights,
            collider.joints,
        )
        self.arrays = {
            "nodes": nodes,
            "face_start": np.ascontiguousarray(collider.face_start, np.int32),
            "face_list": np.ascontiguousarray(collider.face_list, np.int32),
            "faces": np.ascontiguousarray(body.faces, np.int32),
            "neighbours": np.ascontiguousarray(collider.neighbours, np.int32),
            **vertex_corners(body.faces, len(body.vertices)),
            "rest": np.ascontiguousarray(body.vertices, np.float64),
            "vertex_joints": np.ascontiguousarray(order, np.int32),
            "vertex_weights": np.ascontiguousarray(np.take_along_axis(body.weights, order, 1), np.float64),
        }
        self.struct = SkinGrid(
            **{name: a.ctypes.data for name, a in self.arrays.items()},
            shape=(ctypes.c_int * 3)(*(int(n) for n in collider.shape)),
            V=len(body.vertices),
            F=len(body.faces),
            J=body.weights.shape[1],
            vertex_k=k,
            starts=settings.starts,
            iterations=settings.iterations,
            origin=(ctypes.c_double * 3)(*(float(x) for x in collider.origin)),
            voxel=settings.voxel_m,
            step=settings.step,
            settled=settings.settled_m,
            deep=settings.deep_m,
            off_skin=settings.off_skin_m,
            face_side=settings.face_side_m,
        )
        self.vertices, self.lib = len(body.vertices), lib

    def query(
        self, points: np.ndarray, global_rotations: np.ndarray, joint_positions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(N,) signed distances and (N, 3) outward normals of points (N, 3) against the body posed by
        (J, 3, 3) global rotations and (J, 3) joint positions, as the reference's ``query``."""
        rot, trans = self.joint_transforms(
            np.asarray(global_rotations)[None], np.asarray(joint_positions)[None]
        )
        rot, trans = np.ascontiguousarray(rot[0]), np.ascontiguousarray(trans[0])
        posed = np.empty((self.vertices, 3))
        ref = ctypes.byref(self.struct)
        self.lib.hrr_skin_pose(ref, rot.ctypes.data, trans.ctypes.data, posed.ctypes.data)
        return self.query_posed(points, rot, trans, posed)

    def query_posed(
        self, points: np.ndarray, rot: np.ndarray, trans: np.ndarray, posed: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`query` of a body already posed: the joints' moves from rest (J, 3, 3) and (J, 3)
        and the mesh they pose (V, 3), as :meth:`pose_frames` gives them (a frame queried many times
        poses its mesh once)."""
        rot, trans = np.ascontiguousarray(rot, np.float64), np.ascontiguousarray(trans, np.float64)
        posed = np.ascontiguousarray(posed, np.float64)
        p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
        distance, normal = np.empty(len(p)), np.empty((len(p), 3))
        self.lib.hrr_skin_sdf(
            ctypes.byref(self.struct),
            rot.ctypes.data,
            trans.ctypes.data,
            posed.ctypes.data,
            p.ctypes.data,
            len(p),
            distance.ctypes.data,
            normal.ctypes.data,
        )
        return distance, normal

    def pose_frames(self, rot: np.ndarray, trans: np.ndarray, *, threads: int = 1) -> np.ndarray:
        """(T, V, 3) the mesh posed for the joints' moves ``rot`` (T, J, 3, 3) and ``trans`` (T, J, 3)
        (C-contiguous float64), frames in parallel."""
        return self.hulls(rot, trans, threads=threads)[0]

    def hulls(
        self,
        rot: np.ndarray,
        trans: np.ndarray,
        capsules: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        pieces: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        *,
        threads: int = 1,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`pose_frames` and, given the frames' ``capsules`` (ends a, b (T, C, 3), radii (C,)) and
        the skin's ``pieces`` (:class:`~hrr_garment.body.skin_envelope.SkinEnvelope`'s corners (P, 3)
        int32, bary (P, 3) and capsule (P,) int32), the hulls' radii (T, C): each capsule grown to
        hold its pieces of the posed skin, never narrower (hrr_skin_frames; the reference is the
        envelope's ``growth``)."""
        t = len(rot)
        posed = np.empty((t, self.vertices, 3))
        hull, args = None, (None, None, None, 0, None, None, None, 0)
        if capsules is not None and pieces is not None:
            a, b, radii = (np.ascontiguousarray(x, np.float64) for x in capsules)
            hull = np.empty((t, len(radii)))
            corners, bary, capsule = (x.ctypes.data for x in pieces)
            args = (a.ctypes.data, b.ctypes.data, radii.ctypes.data, len(radii), corners, bary, capsule)
            args += (len(pieces[2]),)
        self.lib.hrr_skin_frames(
            ctypes.byref(self.struct),
            t,
            rot.ctypes.data,
            trans.ctypes.data,
            posed.ctypes.data,
            *args,
            None if hull is None else hull.ctypes.data,
            threads,
        )
        return posed, hull

    def cells(
        self, posed: np.ndarray, margin: float, cell: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The broad phase of one posed frame (hrr_skin_cells; the reference is
        :func:`hrr_garment.body.skin_cells.skin_cells`): the grid's first corner, its cells along each
        axis and (cells,) uint8, 2 where a cell is farther than ``margin`` from the skin and outside
        it (a closed mesh's: the caller checks)."""
        origin, dims = cell_box(posed, margin, cell)
        out = np.empty(int(np.prod(dims, dtype=np.int64)), np.uint8)
        self.lib.hrr_skin_cells(
            ctypes.byref(self.struct),
            posed.ctypes.data,
            margin,
            cell,
            origin.ctypes.data,
            dims.ctypes.data,
            out.ctypes.data,
        )
        return origin, dims, out

    def far_outside(self, posed: np.ndarray, points: np.ndarray, margin: float, cell: float) -> np.ndarray:
        """(N,) whether each point (N, 3) is farther than ``margin`` from the posed closed mesh (V, 3)
        and outside it, as the push-out's broad phase answers it (its columns ``cell`` wide, built
        for this frame: hrr_skin_far)."""
        p = np.ascontiguousarray(points, np.float64).reshape(-1, 3)
        out = np.zeros(len(p), np.uint8)
        posed = np.ascontiguousarray(posed, np.float64)
        if not self.lib.hrr_skin_far(
            ctypes.byref(self.struct), posed.ctypes.data, margin, cell, p.ctypes.data, len(p), out.ctypes.data
        ):
            raise MemoryError("the broad phase could not allocate its columns")
        return out.astype(bool)


class SkinPose(ctypes.Structure):
    """skin_sdf.c's SkinPose (hrr_native.h): one frame's grid, joints' moves and posed mesh, and the
    width of its broad phase's columns (``cell`` 0: none); the kernel fills the columns in its own
    copy of the struct."""

    _fields_ = [(name, ctypes.c_void_p) for name in ("grid", "rot", "trans", "posed")] + [
        ("cell", ctypes.c_double),
        ("measure_after", ctypes.c_int),
        ("col_start", ctypes.c_void_p),
        ("col_list", ctypes.c_void_p),
        ("col_face", ctypes.c_void_p),
        ("col_reach", ctypes.c_void_p),
        ("ny", ctypes.c_int),
        ("nz", ctypes.c_int),
        ("y0", ctypes.c_double),
        ("z0", ctypes.c_double),
    ]


_NUMPY = {ctypes.c_void_p: np.uint64, ctypes.c_double: np.float64, ctypes.c_int: np.int32}
# SkinPose's fields as a numpy structured type, at ctypes' offsets (numpy cannot read its addresses' format)
_POSE_FIELDS = np.dtype(
    {
        "names": [name for name, _ in SkinPose._fields_],
        "formats": [_NUMPY[kind] for _, kind in SkinPose._fields_],
        "offsets": [getattr(SkinPose, name).offset for name, _ in SkinPose._fields_],
        "itemsize": ctypes.sizeof(SkinPose),
    }
)


def cell_box(posed: np.ndarray, margin: float, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """The broad phase's grid over a posed mesh (V, 3): (3,) its first corner and (3,) int32 cells
    along each axis, reaching ``margin`` plus two cells past the mesh's box on every side (so that
    every border cell is farther than the margin from the mesh: hrr_skin_cells)."""
    pad = margin + 2.0 * cell
    origin = posed.min(0) - pad
    return origin, (np.floor((posed.max(0) + pad - origin) / cell) + 1).astype(np.int32)


class PosedSkins:
    """T frames of skinned bodies posed, as the push-out kernel reads them (``hrr_push_out``'s
    ``skin``): frame t against ``kernels[which[t]]``, its joints' moves ``moves`` (rotations
    (T, J, 3, 3), translations (T, J, 3)) and ``skins[t]``, the mesh they pose
    (:meth:`SkinKernel.pose_frames`), with the broad phase's columns ``cell`` wide (which the kernel
    builds for the push's margin, frames in parallel) where ``cell`` is given and the body's mesh is
    closed (``closed[which[t]]``); with ``measure_after``, the kernel measures a frame its strain
    limit moved again, for the report. Holds every array the structs point at."""

    def __init__(
        self,
        kernels: list[SkinKernel],
        which: np.ndarray,
        moves: tuple[np.ndarray, np.ndarray],
        skins: tuple,
        *,
        closed: list[bool] | None = None,
        cell: float | None = None,
        measure_after: bool = False,
    ):
        self.rot = np.ascontiguousarray(moves[0], np.float64)
        self.trans = np.ascontiguousarray(moves[1], np.float64)
        self.kernels, self.which = kernels, np.asarray(which, np.int64)
        self.posed = [np.ascontiguousarray(posed, np.float64) for posed in skins]
        t = len(self.rot)
        self.structs = (SkinPose * t)()
        # filled as one numpy view of the structs, field by field (a ctypes struct a frame cost 60 us)
        view = np.frombuffer(self.structs, _POSE_FIELDS)
        view["grid"] = np.array([ctypes.addressof(k.struct) for k in kernels], np.uint64)[self.which]
        frame = np.arange(t, dtype=np.uint64)
        view["rot"] = self.rot.ctypes.data + frame * np.uint64(self.rot[0].nbytes)
        view["trans"] = self.trans.ctypes.data + frame * np.uint64(self.trans[0].nbytes)
        view["posed"] = [p.ctypes.data for p in self.posed]
        broad = np.zeros(len(kernels), bool) if closed is None or cell is None else np.asarray(closed, bool)
        view["cell"] = np.where(broad[self.which], cell or 0.0, 0.0)
        view["measure_after"] = int(measure_after)

    def address(self, first: int) -> int:
        """The address of frame ``first``'s struct (the kernel reads the frames from there on)."""
        return ctypes.addressof(self.structs) + first * ctypes.sizeof(SkinPose)
