"""The cloth's internal friction (``SimSettings.cloth_viscosity``, a kinematic viscosity in m^2/s):
after each substep every vertex's velocity relaxes toward its neighbours', dv/dt = nu * laplacian(v)
on the cloth, so that motion of the cloth against itself (a fold's flutter, the hem's sway against
the skirt) dies while the cloth moving as a whole keeps its momentum (docs/materials.md).

Why: the solver at the real presets' 15 substeps x 1 iteration does not dissipate the energy a real
fabric loses to its own hysteresis, and on a free-hanging dress it gains energy (with no hinge
stiffness the quick dress reaches 1,900 m/s within 10 s). A dress on a standing body never came to
rest: its hem moved at 0.28 m/s, 25-45 mm about its place, for as long as it was simulated.
Relative motion over a length L decays in about L^2 / (pi^2 nu): at 0.02 m^2/s a flutter across
5 cm in 13 ms, a sway across 50 cm in 1.3 s.

Discretised per edge (i, j) of rest length l as an exchange of momentum k_ij (v_j - v_i) with
k_ij = (2/3) nu (m_i + m_j) / 2 / l^2 (the 2/3 makes a regular mesh's six neighbours sum to
nu * laplacian), so every exchange is equal and opposite and the cloth's momentum is kept. A pinned
vertex moves with the body: its velocity in the exchange is the pin's over the frame, so that
cloth carried by a moving body is not braked toward standing still. Integrated explicitly each
substep; where a vertex's shares would sum past 1 (a step beyond its neighbours' mean), its edges'
exchanges shrink until they do not, each edge by the same factor both ways (at 0.02 m^2/s the quick
dress's largest sum is 0.2-0.4). Runs inside the scene's captured substep graph (extra ``sim``).

On a curved cloth the exchange also brakes the cloth turning as a rigid body, at about nu / R^2
(R the radius of curvature; about 0.2-0.5 per second on a skirt at 0.02 m^2/s), which no fabric's
internal friction does; a skirt twisted by a spin untwists slowly (docs/materials.md, "After a
stop"). The form that leaves rigid turning alone (each edge's exchange less its ends' fitted spin)
was tried: the hem then moved at 0.27-0.29 m/s twelve seconds after the stop, as with no viscosity
(2026-12-05). The energy the solver gains goes into the skirt's swing about the waist, which is,
locally, a turning."""

from __future__ import annotations

import numpy as np

# makes sum_j (v_j - v_i) / l^2 over a regular triangle mesh's six neighbours nu * laplacian(v)
REGULAR_MESH_FACTOR = 2.0 / 3.0


def relaxation_rates(
    triangles: np.ndarray, rest: np.ndarray, mass: np.ndarray, viscosity: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each vertex's neighbours as CSR (offsets (V+1,), neighbours (2E,)) and the rate (1/s) at which
    its velocity moves toward each (2E,): k_ij / m_i, 0 on a pinned vertex's (zero mass) row."""
    tri = np.asarray(triangles, np.int64)
    pairs = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    edges = np.unique(np.sort(pairs, axis=1), axis=0)
    length_sq = ((rest[edges[:, 1]] - rest[edges[:, 0]]) ** 2).sum(1)
    # a degenerate edge exchanges as one a hundredth of the mean length would (not without bound)
    length_sq = np.maximum(length_sq, 1e-4 * length_sq.mean())
    mass = np.asarray(mass, np.float64)
    # a pinned end (zero mass) exchanges with the free end's mass
    pair_mass = np.where(mass[edges] > 0, mass[edges], mass[edges[:, ::-1]]).mean(1)
    k = REGULAR_MESH_FACTOR * viscosity * pair_mass / length_sq
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    order = np.argsort(rows, kind="stable")
    rows, cols, k = rows[order], cols[order], np.concatenate([k, k])[order]
    rates = np.where(mass[rows] > 0, k / np.where(mass[rows] > 0, mass[rows], 1.0), 0.0)
    offsets = np.zeros(len(rest) + 1, np.int64)
    np.add.at(offsets, rows + 1, 1)
    return np.cumsum(offsets), cols, rates


def step_shares(offsets: np.ndarray, neighbours: np.ndarray, rates: np.ndarray, dt: float) -> np.ndarray:
    """(2E,) each neighbour's share of one explicit step of ``dt``: ``rates * dt``, where a vertex's
    total (its CSR row ``offsets[i]:offsets[i + 1]``) passes 1 each of its edges scaled down by
    1 / total, the same factor both ways along an edge (the smaller of its two ends'), so that the
    exchanges stay equal and opposite and every total at most 1."""
    rows = np.repeat(np.arange(len(offsets) - 1), np.diff(offsets))
    shares = np.asarray(rates, np.float64) * dt
    totals = np.bincount(rows, weights=shares, minlength=len(offsets) - 1)
    scale = 1.0 / np.maximum(totals, 1.0)
    return shares * np.minimum(scale[rows], scale[neighbours])


class ClothViscosity:
    """The internal friction of one finalized newton model's cloth."""

    def __init__(self, wp, model, *, viscosity: float, pinned, device: str):
        """``pinned``: the scene's device array (int32) of the pinned vertices' indices."""
        from . import kernels  # warp at import: only with the sim extra

        self.wp, self.kernels, self.device = wp, kernels, device
        self.count = model.particle_count
        offsets, neighbours, rates = relaxation_rates(
            model.tri_indices.numpy(), model.particle_q.numpy(), model.particle_mass.numpy(), viscosity
        )
        self.offsets_host, self.neighbours_host = offsets, neighbours
        self.offsets = wp.array(offsets.astype(np.int32), dtype=wp.int32, device=device)
        self.neighbours = wp.array(neighbours.astype(np.int32), dtype=wp.int32, device=device)
        self.rates = rates  # 1/s; the substep's shares are made on its first call
        self.shares = None
        self.dt: float | None = None  # the substep the shares are for
        self.relaxed = wp.zeros(self.count, dtype=wp.vec3, device=device)
        self.pinned = pinned
        self.pinned_velocity = wp.zeros(pinned.shape[0], dtype=wp.vec3, device=device)

    def set_pinned_velocity(self, velocity: np.ndarray) -> None:
        """The pinned vertices' velocity (A, 3) over the coming frame (outside the captured graph)."""
        self.pinned_velocity.assign(np.asarray(velocity, np.float32))

    def apply(self, state, dt: float) -> None:
        """Relax ``state``'s particle velocities over ``dt`` (after the solver's step, which leaves a
        pinned vertex's velocity zero: the pin's is written first)."""
        wp, k = self.wp, self.kernels
        if self.dt is None:  # the scene replays one substep length (its graphs are captured)
            shares = step_shares(self.offsets_host, self.neighbours_host, self.rates, dt)
            self.shares = wp.array(shares.astype(np.float32), dtype=float, device=self.device)
            self.dt = dt
        elif dt != self.dt:
            raise ValueError(f"the cloth's viscosity was made for substeps of {self.dt} s, not {dt}")
        if self.pinned.shape[0]:
            wp.launch(
                k.scatter_vectors,
                dim=self.pinned.shape[0],
                inputs=[self.pinned_velocity, self.pinned],
                outputs=[state.particle_qd],
                device=self.device,
            )
        wp.launch(
            k.relax_velocities,
            dim=self.count,
            inputs=[state.particle_qd, self.offsets, self.neighbours, self.shares],
            outputs=[self.relaxed],
            device=self.device,
        )
        wp.launch(
            k.copy_vectors,
            dim=self.count,
            inputs=[self.relaxed],
            outputs=[state.particle_qd],
            device=self.device,
        )
