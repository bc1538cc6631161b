"""A cloth material's physical values as the VBD solver's parameters: the one place they are mapped
(docs/materials.md).

newton's VBD cloth stores, per triangle, a stable neo-Hookean membrane with Lame parameters
(``tri_ke`` = mu, ``tri_ka`` = lambda, N/m: energy per rest area) and, per interior edge, a hinge
whose energy is ``0.5 * edge_ke * rest_length * (theta - theta_rest)^2`` and whose damping moment
is ``edge_kd * rest_length * dtheta/dt``. So:

- **stretch and shear**: an isotropic membrane has 2D Young's modulus E = 4 mu (mu + lambda) /
  (2 mu + lambda) and shear modulus mu. E is the material's stretch, but never below
  MIN_MEMBRANE_STRETCH: measured fabrics are soft at small strain (73-2,127 N/m) and then lock
  (ARCSim, whose measurements these are, holds them with strain limits), which VBD cannot do; a
  dress at 2,000 N/m stretched to a strain p99 of 1.25 on a walk and at 162-488 N/m tore. A shear
  stiffness below 3/8 of E (Poisson's ratio above 1/3, as woven fabrics have: they shear far more
  easily than they stretch) is raised to 3/8 of E, the solver having no orthotropic membrane.
- **bending**: ``edge_ke`` per edge = B * L / (A1 + A2) (L the edge's rest length,
  A1, A2 its triangles' rest areas), so that a sheet rolled onto a cylinder of curvature k stores
  B k^2 / 2 per unit area whatever the mesh's resolution (tested against that known answer).
- **damping**: ``edge_kd`` = the loss time * ``edge_ke`` (a fold's viscous moment over its elastic
  moment rate); the membrane keeps the solver's own small damping.

Without a material (``SimSettings.material`` None) the solver's values in the settings are used as
they are: every dataset simulated before materials existed keeps its keys and its frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..garment.material import Material
from .config import SimSettings

# an isotropic membrane's shear at least this share of its stretch (Poisson's ratio at most 1/3)
MIN_SHEAR_SHARE = 3.0 / 8.0
# the softest membrane the solver is given, N/m: the project's cloth (mu = lambda = 1e4), whose
# dress keeps a strain p99 of 1.07 on a walk (see the module's note)
MIN_MEMBRANE_STRETCH = 26_667.0


@dataclass(frozen=True)
class ClothParameters:
    """The solver's cloth values for one garment; ``bend`` set: ``edge_ke``/``edge_kd`` are per edge
    (:func:`hinge_stiffness`), else the scalars apply to every edge."""

    density: float  # kg/m^2
    tri_ke: float  # membrane mu, N/m
    tri_ka: float  # membrane lambda, N/m
    tri_kd: float
    edge_ke: float
    edge_kd: float
    bend: float | None = None  # N m: per-edge stiffness from the edges' geometry
    damping_s: float = 0.0  # s: per-edge damping = this * per-edge stiffness


def membrane_lame(stretch: float, shear: float) -> tuple[float, float]:
    """(mu, lambda) of the isotropic membrane with 2D Young's modulus ``stretch`` and shear modulus
    ``shear`` raised to at least 3/8 of it (see the module's note)."""
    mu = max(shear, MIN_SHEAR_SHARE * stretch)
    lam = 2.0 * mu * (2.0 * mu - stretch) / (stretch - 4.0 * mu)
    return mu, lam


def membrane_moduli(mu: float, lam: float) -> tuple[float, float]:
    """(2D Young's modulus, shear modulus) of the membrane with Lame parameters ``mu``, ``lam``."""
    return 4.0 * mu * (mu + lam) / (2.0 * mu + lam), mu


def cloth_parameters(config: SimSettings) -> ClothParameters:
    """The solver's cloth values under ``config``: its material mapped, or its raw values."""
    m: Material | None = config.material
    if m is None:
        return ClothParameters(
            config.density, config.tri_ke, config.tri_ka, config.tri_kd, config.edge_ke, config.edge_kd
        )
    mu, lam = membrane_lame(max(m.stretch, MIN_MEMBRANE_STRETCH), m.shear)
    return ClothParameters(m.density, mu, lam, config.tri_kd, 0.0, 0.0, bend=m.bend, damping_s=m.damping)


def hinge_weights(positions: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(E,) L / (A1 + A2) per hinge at rest (``edges``: newton's rows (opposite 0, opposite 1, edge
    start, edge end), -1 where the edge has one triangle: weight 0). Times B, the hinge energy
    0.5 k L theta^2 summed over a sheet of equilateral triangles rolled onto a cylinder equals
    B k^2 / 2 per area (within 3 % in every direction of the roll); a mesh whose vertices stray by a
    tenth of an edge stores 7 % more."""
    edges = np.asarray(edges, np.int64)
    x = np.asarray(positions, np.float64)
    interior = (edges[:, 0] >= 0) & (edges[:, 1] >= 0)
    e = edges[interior]
    start, end = x[e[:, 2]], x[e[:, 3]]
    axis = end - start
    length = np.linalg.norm(axis, axis=1)
    area0 = 0.5 * np.linalg.norm(np.cross(axis, x[e[:, 0]] - start), axis=1)
    area1 = 0.5 * np.linalg.norm(np.cross(axis, x[e[:, 1]] - start), axis=1)
    weights = np.zeros(len(edges))
    weights[interior] = length / np.maximum(area0 + area1, 1e-12)
    return weights


def hinge_stiffness(params: ClothParameters, positions: np.ndarray, edges: np.ndarray) -> list[tuple]:
    """Per-edge (edge_ke, edge_kd) for newton's ``edge_bending_properties`` rows of one cloth."""
    ke = params.bend * hinge_weights(positions, edges)
    return list(zip(ke.tolist(), (params.damping_s * ke).tolist()))
