"""Metrics against hand-computed answers on small meshes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hrr_garment.eval import metrics as M


def grid(n: int = 5, spacing: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """A flat n x n grid in the XZ plane (y = 0), two triangles per cell."""
    x, z = np.meshgrid(np.arange(n) * spacing, np.arange(n) * spacing, indexing="ij")
    v = np.stack([x.ravel(), np.zeros(n * n), z.ravel()], 1)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()
    return v, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def fold(v: np.ndarray, angle: float, at: float) -> np.ndarray:
    """Rotate the part x > at about the line x = at (along z) by ``angle``: one crease."""
    out = v.copy()
    right = v[:, 0] > at + 1e-9
    dx = v[right, 0] - at
    out[right, 0] = at + dx * math.cos(angle)
    out[right, 1] = dx * math.sin(angle)
    return out


def test_topology_of_a_quad():
    topo = M.MeshTopology.of(np.array([[0, 1, 2], [2, 1, 3]]), 4)
    assert topo.edges.tolist() == [[0, 1], [0, 2], [1, 2], [1, 3], [2, 3]]
    assert len(topo.interior) == 1 and topo.edges[topo.interior[0]].tolist() == [1, 2]
    assert sorted(topo.opposite[0].tolist()) == [0, 3] and sorted(topo.wings[0].tolist()) == [0, 1]


def test_pve_and_rmse_known_values():
    truth = np.zeros((2, 4, 3))
    pred = truth.copy()
    pred[:, :2, 0] = 0.002  # half the vertices 2 mm off
    assert M.pve_mm(pred, truth) == pytest.approx(1.0)
    assert M.rmse_mm(pred, truth) == pytest.approx(math.sqrt(2.0))
    assert M.pve_mm(truth + [0.003, 0.004, 0.0], truth) == pytest.approx(5.0)


def test_sted_zero_for_rigid_motion_and_known_for_growth():
    v, f = grid()
    topo = M.MeshTopology.of(f, len(v))
    truth = np.repeat(v[None], 4, 0)
    assert M.sted(truth + [0.5, 0.1, -2.0], truth, topo)["sted"] == pytest.approx(0.0, abs=1e-12)
    # uniform scaling: every edge deviates by the same relative amount: no local spread
    assert M.sted(truth * 1.1, truth, topo)["sted_spatial"] == pytest.approx(0.0, abs=1e-9)
    # growing by alpha per frame: edge length change alpha * l per frame, temporal part alpha
    alpha = 0.02
    grow = truth * (1 + alpha * np.arange(4))[:, None, None]
    out = M.sted(grow, truth, topo)
    assert out["sted_temporal"] == pytest.approx(alpha) and out["sted"] == pytest.approx(alpha)
    # one vertex pushed: the spread appears around it
    bumped = truth.copy()
    bumped[:, 12, 1] += 0.05
    assert M.sted(bumped, truth, topo)["sted_spatial"] > 0.005


def test_chamfer_of_a_lifted_grid():
    v, _ = grid()
    truth = v[None]
    assert M.chamfer_cm(truth, truth) == 0.0
    assert M.chamfer_cm(truth + [0, 0.01, 0], truth) == pytest.approx(1.0)  # 1 cm along the normal


@pytest.mark.parametrize("angle", [0.3, 1.0, -0.7])
def test_dihedral_and_curvature_error_of_one_crease(angle):
    v, f = grid(5, 0.1)
    topo = M.MeshTopology.of(f, len(v))
    folded = fold(v, angle, 0.2)
    theta = M.dihedral_angles(folded, topo)
    crease = np.isclose(v[topo.edges[topo.interior]][:, :, 0], 0.2).all(1)
    assert np.allclose(theta[crease], abs(angle), atol=1e-9) and np.allclose(theta[~crease], 0, atol=1e-7)
    # the crease is 0.4 m = 40 cm long: E_curv = 1/2 * |angle| * 40
    assert M.curvature_error_cm(folded[None], v[None], topo) == pytest.approx(0.5 * abs(angle) * 40, rel=1e-9)


def test_cloth_energies_known_values():
    v, f = grid(4, 0.1)
    topo = M.MeshTopology.of(f, len(v))
    stretch, bend = M.cloth_energies(v[None], v, topo)
    assert stretch[0] == pytest.approx(0) and bend[0] == pytest.approx(0, abs=1e-20)
    s, _ = M.cloth_energies((v * 1.1)[None], v, topo)  # every edge 10 % long: sum l0 * 0.01
    l0 = np.linalg.norm(v[topo.edges[:, 1]] - v[topo.edges[:, 0]], axis=1)
    assert s[0] == pytest.approx(0.01 * l0.sum())
    _, b = M.cloth_energies(fold(v, 0.5, 0.1)[None], v, topo)
    # crease at x = 0.1: three 0.1 m edges; each rest hinge's two triangles have heights
    # 0.1 (for the axis-aligned edge): h0 = 0.2 / 3; energy 3 * 0.25 * 0.1 / (0.2 / 3)
    assert b[0] == pytest.approx(3 * 0.25 * 0.1 / (0.2 / 3))
    ratios = M.energy_ratios((v * 1.2)[None], (v * 1.1)[None], v, topo)
    assert ratios["stretch_energy_ratio"] == pytest.approx(4.0)


def test_jitter_penetration_and_strain():
    t = np.arange(6)[:, None, None] * np.ones((6, 3, 3))
    truth = 0.01 * t**2  # constant acceleration
    assert M.jitter_mm(truth + 0.2, truth)["jitter_mm"] == pytest.approx(0.0, abs=1e-9)
    noisy = truth.copy()
    noisy[3, 0, 0] += 0.001  # one 1 mm blip: second differences -> 1, -2, 1 mm at one vertex
    assert M.jitter_mm(noisy, truth)["jitter_mm"] == pytest.approx((1 + 2 + 1) / (4 * 3))
    sd = np.array([[-0.001, 0.01, -0.006, 0.02]])
    assert M.penetration_pct(sd) == {"penetration_pct": 50.0, "penetration_5mm_pct": 25.0}
    v, f = grid(3)
    topo = M.MeshTopology.of(f, len(v))
    s = M.edge_strain_percentiles((v * 1.05)[None], v, topo)
    assert s["strain_p50"] == pytest.approx(1.05) and s["strain_max"] == pytest.approx(1.05)
