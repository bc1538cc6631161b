"""Garment metrics against simulated ground truth (docs/evaluation.md), vectorised over frames.

All take world-space vertex arrays of the same template, ``pred`` and ``truth`` (T, V, 3) in
metres, and return plain floats in the units their names state. The formulas, exactly as
implemented (docs/evaluation.md repeats them):

- PVE (mm): mean over frames and vertices of ||p - g||.
- RMSE (mm): sqrt of the mean over frames and vertices of ||p - g||^2.
- STED (Vasa & Skala 2011), dimensionless. Per edge e and frame t the relative edge-length
  deviation d_e(t) = (l'_e(t) - l_e(t)) / l_e(t) (l' predicted, l ground truth). Spatial part:
  for each vertex, the standard deviation of d_e over its incident edges, weighted by l_e(t);
  STED_s = mean over vertices and frames. Temporal part: the relative difference of edge-length
  change between consecutive frames, STED_t = mean over edges and t of
  |(l'_e(t+1) - l'_e(t)) - (l_e(t+1) - l_e(t))| / l_e(t), per frame (dt = 1 frame).
  STED = sqrt(STED_s^2 + STED_t^2) (Vasa's weighting constant c = 1 per frame).
- Chamfer distance (cm): 0.5 * (mean over p of min_g ||p - g|| + mean over g of min_p ||g - p||)
  on the vertices, per frame, mean over frames.
- Penetration (%): garment vertices with negative signed distance to the capsule body (and, as
  hrr-animate reports it, deeper than 5 mm).
- E_curv (D-Garment Eq. 10), cm: per frame 1/2 |sum_e theta'_e l'_e - sum_e theta_e l_e| over
  interior edges, theta the dihedral angle (0 for flat, radians), l in cm; mean over frames.
- Edge strain: l_e(t) / l_e(rest template); percentiles 50/95/99 and max of the prediction.
- Stretch and bending energy ratios (cloth energies as in FNOpt, which takes them from Stotko et
  al. 2024): discrete membrane energy E_s = sum_e l0_e (l_e / l0_e - 1)^2 (springs on edges, rest
  lengths l0 from the template) and discrete-shell bending energy E_b = sum_e (theta_e -
  theta0_e)^2 l0_e / h0_e (Grinspun et al. 2003; h0_e a third of the summed heights of the two rest
  triangles over e). Material constants cancel in the reported ratio mean_t E(pred) / mean_t E(truth):
  1 is the ground truth's level; > 1 overstretched or overbent, < 1 too slack or too smooth.
- Jitter (mm/frame^2): mean over frames and vertices of ||a' - a|| with a the second difference
  in time; also the mean ||a'|| of the prediction on its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..sim.quality import PENETRATION_DEPTH_M


@dataclass(frozen=True)
class MeshTopology:
    """Edges and the two faces of each interior edge, from a triangle list (computed once)."""

    faces: np.ndarray  # (F, 3)
    edges: np.ndarray  # (E, 2) unique, sorted pairs
    interior: np.ndarray  # (I,) indices into edges of the edges with exactly two faces
    wings: np.ndarray  # (I, 2) the two faces of each interior edge
    opposite: np.ndarray  # (I, 2) the vertex of each wing face not on the edge
    num_vertices: int

    @classmethod
    def of(cls, faces: np.ndarray, num_vertices: int) -> "MeshTopology":
        faces = np.asarray(faces, np.int64)
        corner = np.stack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]], 1).reshape(-1, 2)
        opp = faces[:, [2, 0, 1]].reshape(-1)
        face_of = np.repeat(np.arange(len(faces)), 3)
        key = np.sort(corner, 1)
        edges, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
        inverse = inverse.reshape(-1)
        order = np.argsort(inverse, kind="stable")
        starts = np.r_[0, np.cumsum(counts)[:-1]]
        interior = np.flatnonzero(counts == 2)
        first, second = order[starts[interior]], order[starts[interior] + 1]
        return cls(
            faces,
            edges,
            interior,
            np.stack([face_of[first], face_of[second]], 1),
            np.stack([opp[first], opp[second]], 1),
            num_vertices,
        )


def _edge_lengths(v: np.ndarray, edges: np.ndarray) -> np.ndarray:
    return np.linalg.norm(v[..., edges[:, 1], :] - v[..., edges[:, 0], :], axis=-1)


def dihedral_angles(v: np.ndarray, topo: MeshTopology) -> np.ndarray:
    """(..., I) unsigned angle between the normals of the two faces of each interior edge."""
    tri = v[..., topo.faces, :]
    n = np.cross(tri[..., 1, :] - tri[..., 0, :], tri[..., 2, :] - tri[..., 0, :])
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-20)
    a, b = n[..., topo.wings[:, 0], :], n[..., topo.wings[:, 1], :]
    # atan2 of |a x b| and a . b: accurate for small angles, where arccos loses digits
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), (a * b).sum(-1))


def pve_mm(pred: np.ndarray, truth: np.ndarray) -> float:
    """Mean per-vertex Euclidean error (mm)."""
    return 1000.0 * float(np.linalg.norm(pred - truth, axis=-1).mean())


def rmse_mm(pred: np.ndarray, truth: np.ndarray) -> float:
    """Root mean square per-vertex error (mm)."""
    return 1000.0 * float(np.sqrt(((pred - truth) ** 2).sum(-1).mean()))


def per_frame_pve_mm(pred: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Mean per-vertex error (mm) of each frame, (T,)."""
    return 1000.0 * np.linalg.norm(pred - truth, axis=-1).mean(-1)


def sted(pred: np.ndarray, truth: np.ndarray, topo: MeshTopology) -> dict[str, float]:
    """Spatio-temporal edge difference (STED): edge-length deviation, spatial and temporal."""
    lp, lg = _edge_lengths(pred, topo.edges), _edge_lengths(truth, topo.edges)  # (T, E)
    lg = np.maximum(lg, 1e-12)
    dev = (lp - lg) / lg
    # length-weighted mean and variance of dev over each vertex's incident edges
    ends = topo.edges.reshape(-1)
    w = np.repeat(lg, 2, axis=1)  # each edge counts for both its end vertices
    wd = np.repeat(dev, 2, axis=1)
    t = len(pred)
    wsum = np.zeros((t, topo.num_vertices))
    m1 = np.zeros((t, topo.num_vertices))
    m2 = np.zeros((t, topo.num_vertices))
    for arr, val in ((wsum, w), (m1, w * wd), (m2, w * wd * wd)):
        np.add.at(arr, (slice(None), ends), val)
    used = wsum[0] > 0
    mean = m1[:, used] / wsum[:, used]
    spatial = float(np.sqrt(np.maximum(m2[:, used] / wsum[:, used] - mean**2, 0.0)).mean())
    temporal = float((np.abs(np.diff(lp, axis=0) - np.diff(lg, axis=0)) / lg[:-1]).mean()) if t > 1 else 0.0
    return {"sted": float(np.hypot(spatial, temporal)), "sted_spatial": spatial, "sted_temporal": temporal}


def chamfer_cm(pred: np.ndarray, truth: np.ndarray) -> float:
    """Symmetric Chamfer distance (cm), mean over frames."""
    total = 0.0
    for p, g in zip(pred, truth):
        total += 0.5 * (cKDTree(g).query(p)[0].mean() + cKDTree(p).query(g)[0].mean())
    return 100.0 * total / len(pred)


def curvature_error_cm(pred: np.ndarray, truth: np.ndarray, topo: MeshTopology) -> float:
    """D-Garment Eq. 10 per frame, mean over frames (edge lengths in cm)."""
    edges = topo.edges[topo.interior]

    def integral(v):
        return (dihedral_angles(v, topo) * 100.0 * _edge_lengths(v, edges)).sum(-1)

    return float(0.5 * np.abs(integral(pred) - integral(truth)).mean())


def edge_strain_percentiles(pred: np.ndarray, rest: np.ndarray, topo: MeshTopology) -> dict[str, float]:
    """Percentiles and maximum of edge length over rest length."""
    strain = _edge_lengths(pred, topo.edges) / np.maximum(_edge_lengths(rest, topo.edges), 1e-12)
    p50, p95, p99 = np.percentile(strain, [50, 95, 99])
    return {
        "strain_p50": float(p50),
        "strain_p95": float(p95),
        "strain_p99": float(p99),
        "strain_max": float(strain.max()),
    }


def _rest_hinge_heights(rest: np.ndarray, topo: MeshTopology) -> np.ndarray:
    """h0_e: a third of the summed heights of the two rest triangles over each interior edge."""
    e = topo.edges[topo.interior]
    base = np.linalg.norm(rest[e[:, 1]] - rest[e[:, 0]], axis=-1)
    heights = []
    for k in range(2):
        apex = rest[topo.opposite[:, k]]
        area2 = np.linalg.norm(np.cross(rest[e[:, 1]] - rest[e[:, 0]], apex - rest[e[:, 0]]), axis=-1)
        heights.append(area2 / np.maximum(base, 1e-12))
    return (heights[0] + heights[1]) / 3.0


def cloth_energies(v: np.ndarray, rest: np.ndarray, topo: MeshTopology) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame (stretch, bending) energies up to material constants (see the module docstring)."""
    l0 = np.maximum(_edge_lengths(rest, topo.edges), 1e-12)
    stretch = (l0 * (_edge_lengths(v, topo.edges) / l0 - 1.0) ** 2).sum(-1)
    e0 = l0[topo.interior]
    theta0 = dihedral_angles(rest, topo)
    bend = (
        (dihedral_angles(v, topo) - theta0) ** 2 * e0 / np.maximum(_rest_hinge_heights(rest, topo), 1e-12)
    ).sum(-1)
    return stretch, bend


def energy_ratios(
    pred: np.ndarray, truth: np.ndarray, rest: np.ndarray, topo: MeshTopology
) -> dict[str, float]:
    """Predicted over true mean stretching and bending energies."""
    sp, bp = cloth_energies(pred, rest, topo)
    sg, bg = cloth_energies(truth, rest, topo)
    return {
        "stretch_energy_ratio": float(sp.mean() / max(sg.mean(), 1e-30)),
        "bending_energy_ratio": float(bp.mean() / max(bg.mean(), 1e-30)),
    }


def jitter_mm(pred: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Jitter: the predicted against the true acceleration (second differences), and the
    prediction's own mean acceleration (mm per frame squared)."""
    if len(pred) < 3:
        return {"jitter_mm": 0.0, "acceleration_mm": 0.0}
    ap, ag = np.diff(pred, 2, axis=0), np.diff(truth, 2, axis=0)
    return {
        "jitter_mm": 1000.0 * float(np.linalg.norm(ap - ag, axis=-1).mean()),
        "acceleration_mm": 1000.0 * float(np.linalg.norm(ap, axis=-1).mean()),
    }


def penetration_pct(signed_distance: np.ndarray) -> dict[str, float]:
    """From the garment's signed distances to the body (T, V), negative inside."""
    return {
        "penetration_pct": 100.0 * float((signed_distance < 0).mean()),
        "penetration_5mm_pct": 100.0 * float((signed_distance < -PENETRATION_DEPTH_M).mean()),
    }
