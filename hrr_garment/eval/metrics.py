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

import numpy as np
from scipy.spatial import cKDTree

from ..garment.cloth_energy import MeshTopology, cloth_energies, dihedral_angles, edge_lengths
from ..sim.quality import PENETRATION_DEPTH_M


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
    lp, lg = edge_lengths(pred, topo.edges), edge_lengths(truth, topo.edges)  # (T, E)
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
        return (dihedral_angles(v, topo) * 100.0 * edge_lengths(v, edges)).sum(-1)

    return float(0.5 * np.abs(integral(pred) - integral(truth)).mean())


def edge_strain_percentiles(pred: np.ndarray, rest: np.ndarray, topo: MeshTopology) -> dict[str, float]:
    """Percentiles and maximum of edge length over rest length."""
    strain = edge_lengths(pred, topo.edges) / np.maximum(edge_lengths(rest, topo.edges), 1e-12)
    p50, p95, p99 = np.percentile(strain, [50, 95, 99])
    return {
        "strain_p50": float(p50),
        "strain_p95": float(p95),
        "strain_p99": float(p99),
        "strain_max": float(strain.max()),
    }


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
