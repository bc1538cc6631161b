"""Air resisting the cloth (``SimSettings.air_drag``, a drag coefficient): after each substep every
vertex's velocity along the cloth's normal loses 0.5 * air density * Cd * v^2 per unit area,
integrated exactly over the substep (:func:`.kernels.air_drag`). A sheet three times lighter is
slowed three times as fast: what makes a light fabric float and settle and a heavy one swing on
(docs/materials.md). Runs inside the scene's captured substep graph (extra ``sim``)."""

from __future__ import annotations

import numpy as np

# kg/m^3, sea level at 20 C
AIR_DENSITY = 1.204


class AirDrag:
    """The drag of one finalized newton model's cloth."""

    def __init__(self, wp, model, *, coefficient: float, device: str):
        from . import kernels  # warp at import: only with the sim extra

        self.wp, self.kernels, self.model, self.device = wp, kernels, model, device
        triangles = model.tri_indices.numpy()
        area = np.zeros(model.particle_count)  # each particle's share of the cloth's rest area
        np.add.at(area, triangles.ravel(), np.repeat(model.tri_areas.numpy() / 3.0, 3))
        mass = model.particle_mass.numpy()
        per_mass = np.where(mass > 0, 0.5 * AIR_DENSITY * coefficient * area / np.maximum(mass, 1e-12), 0.0)
        self.per_mass = wp.array(per_mass.astype(np.float32), dtype=float, device=device)  # 0: pinned
        self.normals = wp.zeros(model.particle_count, dtype=wp.vec3, device=device)

    def apply(self, state, dt: float) -> None:
        """Slow ``state``'s particle velocities over ``dt`` (after the solver's step)."""
        wp, k, model = self.wp, self.kernels, self.model
        wp.launch(k.zero_vectors, dim=model.particle_count, outputs=[self.normals], device=self.device)
        wp.launch(
            k.add_face_normals,
            dim=model.tri_count,
            inputs=[state.particle_q, model.tri_indices],
            outputs=[self.normals],
            device=self.device,
        )
        wp.launch(
            k.air_drag,
            dim=model.particle_count,
            inputs=[self.normals, self.per_mass, dt],
            outputs=[state.particle_qd],
            device=self.device,
        )
