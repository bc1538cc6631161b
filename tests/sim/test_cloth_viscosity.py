"""The cloth's internal friction (hrr_garment.sim.cloth_viscosity): a viscosity's Laplacian on a
regular mesh, momentum kept, pinned vertices held, and in the solver a cloth's motion against
itself dying while its motion as a whole is kept."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from hrr_garment.sim.cloth_viscosity import relaxation_rates, step_shares
from hrr_garment.sim.config import SimSettings
from tests.sim.test_cloth_parameters import _still


def _lattice(n: int = 9, edge: float = 0.03):
    """An equilateral triangle lattice (n x n vertices) in the x-z plane: points and triangles."""
    points = np.array(
        [((i + 0.5 * (j % 2)) * edge, 1.0, j * edge * np.sqrt(3) / 2) for j in range(n) for i in range(n)]
    )
    triangles = []
    for j in range(n - 1):
        for i in range(n - 1):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1
            triangles += [(a, b, d), (a, d, c)] if j % 2 else [(a, b, c), (b, d, c)]
    return points, np.array(triangles)


def _change(offsets, neighbours, rates, v):
    """dv/dt of every vertex: sum over its neighbours of rate * (v_j - v_i)."""
    rows = np.repeat(np.arange(len(v)), np.diff(offsets))
    return np.array([np.bincount(rows, rates * (v[neighbours, c] - v[rows, c]), len(v)) for c in range(3)]).T


def test_on_a_regular_mesh_the_exchange_is_the_viscosity_times_the_laplacian():
    """A quadratic velocity field (laplacian 2 + 2 in x) relaxes at exactly nu * 4 at every vertex
    with its six neighbours, whatever the edge length."""
    for edge in (0.01, 0.03):
        points, triangles = _lattice(edge=edge)
        offsets, neighbours, rates = relaxation_rates(triangles, points, np.full(len(points), 1e-4), 0.02)
        v = np.zeros_like(points)
        v[:, 0] = points[:, 0] ** 2 + points[:, 2] ** 2
        inner = np.diff(offsets) == 6
        assert inner.sum() >= 25
        assert np.allclose(_change(offsets, neighbours, rates, v)[inner, 0], 0.02 * 4.0, rtol=1e-9)


def test_the_exchange_keeps_the_cloths_momentum_and_leaves_a_pinned_vertex_alone():
    points, triangles = _lattice()
    rng = np.random.default_rng(0)
    mass = rng.uniform(0.5e-4, 2e-4, len(points))
    v = rng.normal(size=points.shape)
    offsets, neighbours, rates = relaxation_rates(triangles, points, mass, 0.02)
    change = _change(offsets, neighbours, rates, v)
    assert np.abs((mass[:, None] * change).sum(0)).max() < 1e-12 * np.abs(mass[:, None] * change).sum()
    assert np.abs(change).max() > 1.0  # and something moved
    # a uniform velocity (the cloth moving as a whole) is not slowed
    assert np.allclose(_change(offsets, neighbours, rates, np.ones_like(v)), 0.0)
    pinned = mass.copy()
    pinned[[0, 40]] = 0.0
    offsets, neighbours, rates = relaxation_rates(triangles, points, pinned, 0.02)
    change = _change(offsets, neighbours, rates, v)
    assert not change[[0, 40]].any()
    # a pinned vertex's neighbours still follow it: the body drags the cloth it holds
    near_pin = neighbours[offsets[40] : offsets[41]]
    assert (rates[np.isin(np.repeat(np.arange(len(v)), np.diff(offsets)), near_pin)] > 0).all()


def test_each_vertexs_step_is_capped_at_its_neighbours_mean_and_keeps_the_momentum():
    points, triangles = _lattice()
    offsets, neighbours, rates = relaxation_rates(triangles, points, np.full(len(points), 1e-4), 0.02)
    rng = np.random.default_rng(1)
    mass = rng.uniform(0.5e-4, 2e-4, len(points))
    velocities = rng.normal(size=points.shape)
    _, _, uneven = relaxation_rates(triangles, points, mass, 0.02)
    small = step_shares(offsets, neighbours, rates, 1e-4)
    assert np.allclose(small, rates * 1e-4)  # under the cap: the rates as they are
    for dt in (0.01, 10.0):
        shares = step_shares(offsets, neighbours, uneven, dt)
        totals = np.add.reduceat(shares, offsets[:-1])
        assert totals.max() <= 1.0 + 1e-12 and (totals > 0.99).any()
        # capped or not, each exchange is equal and opposite: the momentum is kept
        change = _change(offsets, neighbours, shares, velocities)
        assert np.abs((mass[:, None] * change).sum(0)).max() < 1e-12 * np.abs(mass[:, None] * change).sum()


def test_settings_without_a_viscosity_keep_their_keys():
    assert "cloth_viscosity" not in SimSettings().to_dict()
    assert SimSettings(cloth_viscosity=0.02).to_dict()["cloth_viscosity"] == 0.02
    with pytest.raises(ValueError, match="cloth_viscosity"):
        SimSettings(cloth_viscosity=-1.0)


@pytest.fixture(scope="module")
def simulator():
    pytest.importorskip("newton", reason="the sim extra is not installed")
    from hrr_garment.sim.simulator import simulate_garment

    return simulate_garment


def _sheet(held: bool, height: float = 1.0):
    """The lattice as a level sheet far from the body, held along one side or free."""
    from hrr_garment.garment.mesh import GarmentMesh

    points, triangles = _lattice()
    points = points + np.array([2.0, height, 0.0])
    side = np.flatnonzero(np.isclose(points[:, 2], points[:, 2].min()))
    groups = {"held": side} if held else {}
    return GarmentMesh(
        "sheet",
        points.astype(np.float32),
        triangles.astype(np.int32),
        groups=groups,
        attached_groups=("held",) if held else (),
    )


@pytest.mark.sim
def test_a_swinging_sheet_comes_to_rest(simulator):
    """Held along one side, a level sheet swings down: with the viscosity it has nearly stopped 2.5 s
    after the lead-in, without it the solver keeps it moving (and its speed grows again)."""
    plain = SimSettings(air_drag=1.2, retries=0)
    speeds = {}
    for nu in (0.0, 0.02):
        run = simulator(_sheet(held=True), _still(75), replace(plain, cloth_viscosity=nu)).vertices
        # the mean speed over the last half second (measured: 0.064 m/s plain, 0.011 viscous)
        speeds[nu] = np.linalg.norm(np.diff(run[-16:].astype(np.float64), axis=0), axis=-1).mean() * 30
    assert speeds[0.02] < 0.02 and speeds[0.0] > 3 * speeds[0.02], speeds


@pytest.mark.sim
def test_a_falling_sheet_keeps_its_terminal_speed(simulator):
    """The friction is internal: a sheet falling free through air reaches the terminal speed of
    tests/sim/test_cloth_parameters.py with it as without it."""
    from hrr_garment.sim.air_drag import AIR_DENSITY

    config = SimSettings(air_drag=1.2, retries=0, cloth_viscosity=0.02)
    fall = simulator(_sheet(held=False, height=10.0), _still(20), config).vertices[:, :, 1].mean(axis=1)
    speed = (fall[-6] - fall[-1]) * 30 / 5
    expected = np.sqrt(config.density * config.gravity / (0.5 * AIR_DENSITY * 1.2))
    assert speed == pytest.approx(expected, rel=0.05), (speed, expected)


@pytest.mark.sim
def test_a_pinned_vertex_moves_with_the_body_in_the_exchange(simulator, monkeypatch):
    """The solver leaves a pinned vertex's velocity at zero; the exchange reads the pin's velocity
    over the frame instead, so that cloth carried by a moving body is not braked toward standing
    still. Dragged at 1 m/s, every pin's velocity after each frame is the body's."""
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT
    from hrr_garment.sim import scene

    frames = 12
    root = np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (frames, 1))
    root[:, 0] += np.arange(frames) / 30.0
    dragged = Motion(np.tile(np.eye(3, dtype=np.float32), (frames, 22, 1, 1)), root)
    seen = []
    step_frame = scene.SteppedScene.step_frame

    def watched(self, *args, **kwargs):
        out = step_frame(self, *args, **kwargs)
        seen.append(self.states[self.parity].particle_qd.numpy()[self.attached])
        return out

    monkeypatch.setattr(scene.SteppedScene, "step_frame", watched)
    config = SimSettings(air_drag=1.2, retries=0, cloth_viscosity=0.02)
    simulator(_sheet(held=True), dragged, config)
    assert np.allclose(seen[-1], [1.0, 0.0, 0.0], atol=1e-4)
    seen.clear()
    simulator(_sheet(held=True), dragged, replace(config, cloth_viscosity=0.0))
    assert np.allclose(seen[-1], 0.0)  # the solver's own: what the exchange must not read
