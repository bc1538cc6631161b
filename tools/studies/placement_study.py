"""The built-in garments carried onto anny bodies, measured against each body's visible mesh: the
placement by the capsules alone (``dress(..., visible=None)``, as before issue 82) and kept clear of
the mesh (``dress``'s default, :mod:`hrr_garment.garment.clearance`).

For each body and garment, in the rest pose the garment is dressed in (the mesh skinned into it,
:func:`~hrr_garment.garment.visible_surface.rest_mesh`): the share of the garment's vertices inside
the mesh (winding number) and nearer than the 12 mm clearance (exact distances), the nearest
vertex, the attached vertices' distance, the edge strain (p1 and p99) against the template made
for the mannequin and against the garment as the capsules placed it, how far the hem moved from
there, and the seconds ``dress`` took. Needs the bodies extra.

    python tools/studies/placement_study.py --vertices 1000
"""

from __future__ import annotations

import argparse
import time

import numpy as np

SHAPES = {  # tools/studies/collider_study.py's bodies and a short heavy one
    "average": {},
    "heavy": {"weight": 0.9, "gender": 0.0},
    "tall-slim": {"height": 0.85, "weight": 0.15, "gender": 1.0},
    "short-heavy": {"height": 0.2, "weight": 0.95, "gender": 0.0},
}
GARMENTS = ("dress", "skirt")


def measure(visible, garment, placed, on_capsules, seconds: float) -> dict:
    """One placement's row (distances in mm, shares in %); strain against the template and against
    the garment as the capsules placed it (``on_capsules``)."""
    from hrr_garment.body.mesh_distance import mesh_signed_distance
    from hrr_garment.garment.clearance import CLEARANCE_M
    from hrr_garment.garment.visible_surface import rest_mesh

    mesh = rest_mesh(visible, placed.record.body)
    v = placed.garment.vertices.astype(np.float64)
    signed = mesh_signed_distance(v, mesh, visible.faces)
    edges = garment.edges()
    length = [
        np.linalg.norm(x[edges[:, 0]] - x[edges[:, 1]], axis=1)
        for x in (garment.vertices, on_capsules.garment.vertices, v)
    ]
    strain, added = length[2] / length[0], length[2] / length[1]
    band = signed[garment.attached]
    return {
        "inside_%": 100 * float((signed < 0).mean()),
        "nearer_than_clearance_%": 100 * float((signed < CLEARANCE_M - 1e-4).mean()),
        "nearest_mm": 1000 * float(signed.min()),
        "band_within_2mm_%": 100 * float((np.abs(band - CLEARANCE_M) < 0.002).mean()),
        "band_median_mm": 1000 * float(np.median(band)),
        "strain_p1": float(np.percentile(strain, 1)),
        "strain_p99": float(np.percentile(strain, 99)),
        "added_p1": float(np.percentile(added, 1)),
        "added_p99": float(np.percentile(added, 99)),
        "hem_moved_mm": 1000
        * float(np.linalg.norm(v - on_capsules.garment.vertices, axis=1)[garment.groups["hem"]].max()),
        "seconds": seconds,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--vertices", type=int, default=1000)
    p.add_argument("--bodies", nargs="+", default=list(SHAPES), choices=list(SHAPES))
    args = p.parse_args()
    from hrr_garment.body.body_file import record_of
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.body.skinned_body import visible_body
    from hrr_garment.garment.dressing import dress
    from hrr_garment.garment.templates import make_garment

    garments = {g: make_garment(g, args.vertices) for g in GARMENTS}
    print(
        "| body | stature | garment | placement | inside | nearer than 12 mm | nearest | band at 12 +- 2 mm "
        "(median) | strain p1 / p99 | against the capsules' placement | hem moved | s |\n|" + " --- |" * 12
    )
    for name in args.bodies:
        record = record_of(parametric_body(BodyShape(**SHAPES[name])))
        visible = visible_body(record)
        for g, garment in garments.items():
            on_capsules = None
            for label, mesh in (("capsules", None), ("visible mesh", visible)):
                t0 = time.perf_counter()
                placed, _ = dress(name, record, garment, made_for=DEFAULT_BODY, visible=mesh)
                seconds = time.perf_counter() - t0
                on_capsules = on_capsules or placed
                r = measure(visible, garment, placed, on_capsules, seconds)
                print(
                    f"| {name} | {record.stature:.2f} m | {g} | {label} | {r['inside_%']:.1f} % | "
                    f"{r['nearer_than_clearance_%']:.1f} % | {r['nearest_mm']:.1f} mm | "
                    f"{r['band_within_2mm_%']:.0f} % ({r['band_median_mm']:.1f} mm) | "
                    f"{r['strain_p1']:.2f} / {r['strain_p99']:.2f} | "
                    f"{r['added_p1']:.2f} / {r['added_p99']:.2f} | "
                    f"{r['hem_moved_mm']:.1f} mm | {seconds:.1f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
