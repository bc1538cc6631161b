"""Placing a garment authored in another convention on the canonical body, and finding the
vertices that should follow it (``hrr-simulate --template dress.obj --fit --attached auto``).

An artist's dress rarely arrives in the canonical rest pose (metres, Y up, feet on the ground at
the origin): it may be in centimetres, Z up, modelled around a pelvis at the origin. :func:`fit_garment`
finds, in this order:

1. the unit: the scale among metres, centimetres, millimetres and inches that makes the garment's
   largest extent a garment's size (0.2 to 2.2 m), preferring metres;
2. the up axis: the coordinate axis nearest the normal of the hem, the mesh's longest open
   boundary (a skirt or dress is a tube open at the hem), pointing from the hem into the garment
   (``up`` overrides);
3. the place: centred horizontally on the torso at the height of its top band, then raised or
   lowered (a 5 mm grid over the body's height) to where the top band lies nearest the built-in
   garments' clearance from the torso (12 mm) without pushing cloth into the body.

:func:`auto_attached` picks the top band of vertices that lie on the torso: within ``band`` of the
garment's highest point and within ``contact`` of a torso capsule (pelvis to neck and collars), so
the waistband of a skirt or the strap tops of a dress. Both say what they did in words.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..body.capsules import DEFAULT_BODY, BodyModel, capsule_signed_distance
from .attachment import TORSO_JOINTS
from .mesh import GarmentError, GarmentMesh, boundary_edges, edge_components

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001, "in": 0.0254}
GARMENT_SIZE_M = (0.2, 2.2)  # largest extent of any plausible garment
TOP_BAND_M = 0.03
CONTACT_M = 0.02
CLEARANCE_M = 0.012  # the built-in garments' distance from the body (tube_shapes.TubeShape.gap)
INSIDE_WARNING = 0.01  # a fitted garment with more of its vertices inside the body is pointed to --made-for


@dataclass(frozen=True)
class Fit:
    """World = (R @ file vertex) * scale + offset: what :func:`fit_garment` chose, and why."""

    scale: float
    unit: str
    rotation: np.ndarray  # (3, 3), the file's up axis onto +Y
    up: str  # the file's axis that became +Y, e.g. "+z"
    offset: np.ndarray  # (3,) metres
    top_gap_m: float  # mean difference of the top band's distance from the torso and the 12 mm clearance
    inside: float = 0.0  # fraction of the garment's vertices more than 5 mm inside the body where it lands

    def apply(self, vertices: np.ndarray) -> np.ndarray:
        return (np.asarray(vertices, np.float64) @ self.rotation.T) * self.scale + self.offset

    def describe(self) -> str:
        moved = ", ".join(f"{v:+.3f}" for v in self.offset)
        note = (
            f"unit {self.unit} (x{self.scale:g}), up axis {self.up} -> +y, moved by ({moved}) m; its top "
            f"band sits on average {1000 * self.top_gap_m:.0f} mm off a 12 mm clearance from the torso; "
            f"{100 * self.inside:.1f} % of its vertices land more than 5 mm inside the body"
        )
        if self.inside > INSIDE_WARNING:
            note += (
                " (a garment modelled on another body: declare that body with --made-for instead of --fit, "
                "so the garment is carried onto the body rather than moved)"
            )
        return note


def _torso(body: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a, b = body.rest_pose()
    keep = [i for i, c in enumerate(body.capsules) if c.joint in TORSO_JOINTS]
    return a[keep], b[keep], body.radii[keep]


def _rotation_to_y(axis: int, sign: float) -> np.ndarray:
    """A proper rotation taking the file's axis (0 x, 1 y, 2 z) times sign onto +Y."""
    if axis == 1:
        return np.eye(3) if sign > 0 else np.diag([1.0, -1.0, -1.0])
    if axis == 2:  # z up: (x, y, z) -> (x, z, -y) is a rotation about x
        r = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    else:  # x up: a rotation about z
        r = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return r if sign > 0 else np.diag([1.0, -1.0, -1.0]) @ r


def hem_loop(vertices: np.ndarray, faces: np.ndarray, source: str = "garment") -> np.ndarray:
    """Vertex indices of the hem: the mesh's longest open boundary loop (a skirt or dress is a tube
    open at the hem; the waist, neck and arm openings are shorter)."""
    open_edges = boundary_edges(faces)
    if not len(open_edges):
        raise GarmentError(source, "the mesh has no open boundary (no hem): give its up axis with --up")
    labels = edge_components(len(vertices), open_edges)[open_edges[:, 0]]
    length = np.linalg.norm(vertices[open_edges[:, 1]] - vertices[open_edges[:, 0]], axis=1)
    return np.unique(open_edges[labels == np.argmax(np.bincount(labels, weights=length))])


def hem_vertices(mesh: GarmentMesh) -> np.ndarray:
    """The hem's vertex indices: the mesh's ``hem`` group, or for a mesh without one (a bundle from
    before templates kept their groups, a user garment) its :func:`hem_loop`."""
    hem = mesh.groups.get("hem")
    return hem_loop(mesh.vertices, mesh.faces, mesh.name) if hem is None else hem


def hem_up_axis(vertices: np.ndarray, faces: np.ndarray, source: str = "garment") -> tuple[int, float]:
    """(axis 0/1/2, sign): the coordinate axis nearest the normal of the hem (:func:`hem_loop`),
    signed to point from the hem toward the rest of the mesh."""
    ring = vertices[hem_loop(vertices, faces, source)]
    normal = np.linalg.svd(ring - ring.mean(0))[2][-1]  # the loop's plane normal
    axis = int(np.argmax(np.abs(normal)))
    sign = 1.0 if (vertices.mean(0) - ring.mean(0))[axis] > 0 else -1.0
    return axis, sign


def fit_garment(
    vertices: np.ndarray,
    faces: np.ndarray,
    body: BodyModel = DEFAULT_BODY,
    up: str | None = None,
    unit: str | None = None,
    source: str = "garment",
) -> Fit:
    """Where the garment (``vertices`` (V, 3) in its file's units and axes, ``faces``) goes on the
    canonical body."""
    v = np.asarray(vertices, np.float64)
    extent = np.ptp(v, axis=0)
    if unit is None:
        fits = [u for u, s in UNITS.items() if GARMENT_SIZE_M[0] <= extent.max() * s <= GARMENT_SIZE_M[1]]
        if not fits:
            raise GarmentError(
                source,
                f"cannot tell the unit: the largest extent is {extent.max():.4g} file units, no "
                f"garment's size in {', '.join(UNITS)}; give --unit",
            )
        unit = fits[0]
    if unit not in UNITS:
        raise GarmentError(source, f"unknown unit {unit!r}; one of {', '.join(UNITS)}")
    scale = UNITS[unit]
    if up is None:
        axis, sign = hem_up_axis(v, faces, source)
    else:
        if len(up) != 2 or up[0] not in "+-" or up[1] not in "xyz":
            raise GarmentError(source, f"--up must be one of +x -x +y -y +z -z, got {up!r}")
        axis, sign = "xyz".index(up[1]), 1.0 if up[0] == "+" else -1.0
    rotation = _rotation_to_y(axis, sign)
    placed = (v @ rotation.T) * scale
    a, b, radii = _torso(body)
    top = placed[placed[:, 1] >= placed[:, 1].max() - TOP_BAND_M]
    centre = np.concatenate([a, b])[:, [0, 2]].mean(0)  # the torso's axis, horizontally
    shift_xz = centre - top[:, [0, 2]].mean(0)
    placed[:, [0, 2]] += shift_xz
    whole_a, whole_b = body.rest_pose()
    sample = placed[:: max(1, len(placed) // 2000)]
    # a garment hangs from the waist or the shoulders: its top lies between the hips and the neck
    lo, hi = float(np.concatenate([a, b])[:, 1].min()), float(np.concatenate([a, b])[:, 1].max()) + 0.05
    best = None
    for height in np.arange(lo, hi, 0.005):  # where the top band's highest point sits
        dy = height - placed[:, 1].max()
        gap = np.abs(
            capsule_signed_distance(top + [shift_xz[0], dy, shift_xz[1]], a, b, radii=radii)[0] - CLEARANCE_M
        ).mean()
        inside = (
            capsule_signed_distance(sample + [0.0, dy, 0.0], whole_a, whole_b, radii=body.radii)[0] < -0.005
        ).mean()
        score = gap + 0.5 * inside  # cloth inside the body costs as much as a 5 mm gap per 1 % of it
        if best is None or score < best[0]:
            best = (score, dy, gap, inside)
    _, dy, gap, inside = best
    offset = np.array([shift_xz[0], dy, shift_xz[1]])
    return Fit(
        scale,
        unit,
        rotation,
        ("+" if sign > 0 else "-") + "xyz"[axis],
        offset,
        float(gap),
        inside=float(inside),
    )


def auto_attached(
    vertices: np.ndarray,
    body: BodyModel = DEFAULT_BODY,
    band: float = TOP_BAND_M,
    contact: float = CONTACT_M,
    source: str = "garment",
) -> np.ndarray:
    """Indices of the top band's vertices (within ``band`` of the highest) that lie within
    ``contact`` of the torso, for a garment in the canonical rest pose (metres, Y up)."""
    v = np.asarray(vertices, np.float64)
    a, b, radii = _torso(body)
    near_top = np.flatnonzero(v[:, 1] >= v[:, 1].max() - band)
    on_torso = np.abs(capsule_signed_distance(v[near_top], a, b, radii=radii)[0]) <= contact
    if not on_torso.any():
        raise GarmentError(
            source,
            f"no vertex of the garment's top band ({len(near_top)} vertices within "
            f"{100 * band:.0f} cm of its top) lies within {100 * contact:.0f} cm of the torso: "
            "place it on the body (--fit) or name the attached vertices (--attached GROUP)",
        )
    return near_top[on_torso]
