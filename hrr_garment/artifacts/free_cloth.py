"""The residual's weight by free cloth: how far each region of a garment hangs from the body at rest.

Where the cloth lies on the body (a bodice), the residual's match
(:mod:`hrr_garment.artifacts.residual`) deviates by another simulation's contact, on another body
for a model across bodies: it puts cloth inside the body. Where the cloth hangs free (a skirt) it is
the swing the regression lacks. The residual can be weighted per latent node (each a region of the
garment) by how far that region hangs from the body at rest: 0 within ``lo`` mm, 1 beyond ``hi`` mm
(:func:`free_cloth_weights`). Whether and with which ramp (:data:`FREE_CLOTH_RAMPS_MM`) is the auto
calibration's choice on validation (:mod:`hrr_garment.eval.auto_mode`), recorded as bundle.json
``auto.residual_free_mm``.
"""

from __future__ import annotations

import numpy as np

from ..body.capsules import BodyModel, capsule_signed_distance

#: the free-cloth ramps (lo, hi) in mm the auto calibration tries beside the plain residual: at rest
#: the dress's bodice nodes sit at its 12 mm clearance, its skirt's at 34-300 mm
FREE_CLOTH_RAMPS_MM = ((10.0, 40.0), (20.0, 60.0))


def rest_hang_m(rest_vertices: np.ndarray, body: BodyModel) -> np.ndarray:
    """(V,) how far each vertex of the garment at rest on ``body`` (``rest_vertices`` (V, 3)) hangs
    from it (metres, signed: negative inside)."""
    a, b = body.rest_pose()
    return capsule_signed_distance(np.asarray(rest_vertices, np.float64), a, b, radii=body.radii)[0].astype(
        np.float32
    )


def free_cloth_weights(hang_m: np.ndarray, ramp_mm: tuple[float, float]) -> np.ndarray:
    """(nodes,) float32 the residual's weight per node: 0 where the node hangs within ``lo`` mm of
    the body, 1 beyond ``hi`` mm, linear between (``ramp_mm`` = (lo, hi), lo < hi; negative: inside)."""
    lo, hi = (float(x) / 1000.0 for x in ramp_mm)
    if not -np.inf < lo < hi < np.inf:
        raise ValueError(f"a free-cloth ramp is (lo, hi) mm with lo < hi, got {tuple(ramp_mm)}")
    return np.clip((np.asarray(hang_m, np.float64) - lo) / (hi - lo), 0.0, 1.0).astype(np.float32)
