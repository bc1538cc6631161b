"""The simulator's solver and material settings (:class:`SimSettings`), shared by the newton scene
(:mod:`.scene`) and the simulation driver (:mod:`.simulator`, which re-exports it)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

from ..garment.material import Material, material_from
from ..settings import from_settings, require_number


@dataclass(frozen=True)
class SimSettings:
    """Solver and material values; configs/sim.yaml holds the project defaults."""

    substeps: int = 10
    iterations: int = 3
    tri_ke: float = 1.0e4  # membrane stretch stiffness
    tri_ka: float = 1.0e4  # membrane area stiffness
    tri_kd: float = 1.0e-4  # membrane damping
    edge_ke: float = 1.0e-3  # bending stiffness
    edge_kd: float = 1.0e-4  # bending damping
    density: float = 0.15  # kg per square metre
    particle_radius: float = 0.006
    contact_ke: float = 3.0e4  # 1e4 let running thighs push 1 % of a dress 2 cm in; 3e4: none
    contact_kd: float = 1.0e-2
    contact_mu: float = 0.3
    contact_gap: float = 0.01  # contact detection distance beyond the radius
    gravity: float = 9.81
    settle_s: float = 0.5
    blend_s: float = 0.8  # arms come down from the T-pose at under 3 m/s
    max_speed: float = 30.0  # m/s: a garment point moving faster has exploded
    max_strain: float = 2.5  # edge length / rest length beyond which the cloth has exploded
    retries: int = 1  # extra attempts, each with twice the substeps
    device: str = "auto"  # "auto" (a GPU when present), "cpu", "cuda:0"...
    # air resisting the cloth's motion across itself: the drag coefficient of a plate (about 1.2);
    # 0: none, as every dataset before materials was simulated (a light fabric's float and a heavy
    # one's swing come from it: the same drag slows a sheet a third as heavy three times as fast)
    air_drag: float = 0.0
    # the cloth's internal friction, a kinematic viscosity (m^2/s): the cloth's motion against itself
    # dies (sim/cloth_viscosity.py); 0: none, as every dataset before it was simulated, whose dress
    # never comes to rest on a standing body (the solver at few substeps gains energy)
    cloth_viscosity: float = 0.0
    # the cloth in physical units (a fabric's name, values, a Material: garment/material.py); it
    # replaces density, tri_* and edge_* above (sim/cloth_parameters.py maps it); None: those values
    material: Material | None = None

    def __post_init__(self) -> None:
        require_number("simulator settings", "air_drag", self.air_drag, low=0.0, high=10.0)
        require_number("simulator settings", "cloth_viscosity", self.cloth_viscosity, low=0.0, high=1.0)
        if self.material is not None and not isinstance(self.material, Material):
            object.__setattr__(self, "material", material_from(self.material, "simulator settings: material"))

    @classmethod
    def from_dict(cls, values: dict) -> "SimSettings":
        return from_settings(cls, values, "simulator")

    def to_dict(self) -> dict:
        """The settings as plain values; no ``material``, ``air_drag`` or ``cloth_viscosity`` key
        without them (the keys of datasets simulated before they existed stay as they were)."""
        out = asdict(self)
        for key in ("material", "air_drag", "cloth_viscosity"):
            if not out[key]:
                del out[key]
        return out

    def with_density_scaled(self, factor: float) -> "SimSettings":
        """These settings with the cloth's density times ``factor`` (the material's, when set)."""
        if self.material is None:
            return replace(self, density=self.density * factor)
        return replace(self, material=replace(self.material, density=self.material.density * factor))
