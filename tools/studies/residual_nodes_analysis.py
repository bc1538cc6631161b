"""Analysis: the residual mode's borrowed swing only where the cloth hangs free of the body.

The residual mode adds a database match's deviation from its own regression (docs/inference.md):
another simulation's cloth. Where the cloth lies on the body (a bodice) that deviation puts it
inside a body of another shape; where it hangs free (a skirt) it is the swing the regression lacks.
The model weighs the deviation per latent node of the mesh autoencoder (each a region of the
garment) by how far that region hangs from the body at rest, from 0 (within ``lo`` mm) to 1
(beyond ``hi`` mm; hrr_garment/artifacts/residual.py, where the auto calibration chooses the ramp
on validation). This tool measures ramps on a dataset's test clips, offline without the push-out:
the vertices more than 5 mm inside the body (and which capsule holds them: a hand through the
skirt, the chest under the bodice), the hem's swing over the simulation's and the PVE against each
clip's simulation, beside the plain modes and the simulation itself.

    python tools/studies/residual_nodes_analysis.py --model hrr_work/models/dress-real-quick-bodies-contact \\
        --dataset hrr_work/datasets/dress-real-quick-short-heavy.h5 --ranges 10-40,20-60,30-100
"""

from __future__ import annotations

import argparse

import numpy as np


def inside_by_capsule(vertices: np.ndarray, motion, body) -> tuple[np.ndarray, np.ndarray]:
    """(T, V) whether each vertex is more than 5 mm inside ``body``, and (C,) how many of those
    lie deepest in each capsule."""
    from hrr_garment.body.capsules import frames_signed_distance
    from hrr_garment.sim.quality import PENETRATION_DEPTH_M

    a, b = body.pose_motion(motion)
    depth = np.stack(
        [
            frames_signed_distance(vertices, a[:, c : c + 1], b[:, c : c + 1], radii=body.radii[c : c + 1])[0]
            for c in range(len(body.radii))
        ],
        -1,
    )  # (T, V, C)
    inside = depth.min(-1) < -PENETRATION_DEPTH_M
    return inside, np.bincount(depth.argmin(-1)[inside], minlength=len(body.radii))


def analyse(model: str, dataset: str, ranges: list[tuple[float, float]], sequences: int = 8) -> list[dict]:
    """One row per variant: ``label``, ``inside_pct``, ``inside_by_capsule_pct`` (capsule -> % of
    the vertices), ``hem_swing_ratio``, ``pve_mm``, ``mean_weight`` (ranges in mm)."""
    from hrr_garment.artifacts.free_cloth import free_cloth_weights
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval import metrics as M
    from hrr_garment.eval.auto_mode import free_cloth
    from hrr_garment.eval.scoring import as_simulated, body_of
    from hrr_garment.eval.unseen_bodies import evenly
    from hrr_garment.garment.fit import hem_vertices
    from hrr_garment.inference.animator import Animator
    from hrr_garment.inference.run_settings import DetailLook
    from hrr_garment.sim.quality import hem_swing

    animator, ds = Animator.load(model), GarmentDataset(dataset)
    records = [ds.sequence(n) for n in evenly(ds.splits["test"], sequences)]
    hem = hem_vertices(animator.bundle.template)
    rows = []

    def measure(label: str, ramp: tuple[float, float] | None, **settings) -> None:
        inside = swing = truth_swing = error = frames = 0.0
        capsules = 0
        with free_cloth(animator.bundle, ramp):
            for r in records:
                v = (
                    r.garment
                    if label == "simulation"
                    else animator.animate(
                        r.motion, push_out=False, **as_simulated(animator.bundle, r), **settings
                    ).vertices
                )
                v, truth = v.astype(np.float64), r.garment.astype(np.float64)
                flags, where = inside_by_capsule(v, r.motion, body_of(r))
                inside += float(flags.mean()) * len(v)
                capsules = capsules + where / v.shape[1]
                swing += hem_swing(v, r.motion, hem) * len(v)
                truth_swing += hem_swing(truth, r.motion, hem) * len(v)
                error += M.pve_mm(v, truth) * len(v)
                frames += len(v)
        weight = None if ramp is None else float(free_cloth_weights(animator.bundle.node_hang_m, ramp).mean())
        names = [c.name for c in body_of(records[0]).capsules]
        rows.append(
            {
                "label": label,
                "inside_pct": 100 * inside / frames,
                "hem_swing_ratio": swing / truth_swing,
                "pve_mm": error / frames,
                "mean_weight": weight,
                "inside_by_capsule_pct": {n: 100 * float(k) / frames for n, k in zip(names, capsules) if k},
            }
        )

    detail = {"mode": "detail", "detail": DetailLook("residual", 1.0)}
    measure("simulation", None)
    measure("regression", None, mode="regression")
    measure("detail on the regression x1", None, mode="detail", detail=DetailLook("regression", 1.0))
    measure("residual", None, mode="residual")
    measure("detail on the residual x1", None, **detail)
    for lo, hi in ranges:
        measure(f"residual, nodes {lo:g}-{hi:g} mm", (lo, hi), mode="residual")
        measure(f"detail on the residual x1, nodes {lo:g}-{hi:g} mm", (lo, hi), **detail)
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True)
    p.add_argument("--dataset", required=True, help="its test clips are animated on their own body")
    p.add_argument("--sequences", type=int, default=8)
    p.add_argument("--ranges", default="10-40,20-60,30-100", help="lo-hi in mm: the node weight's ramp")
    args = p.parse_args()
    ranges = [tuple(float(x) for x in ramp.split("-")) for ramp in args.ranges.split(",")]
    for row in analyse(args.model, args.dataset, ranges, args.sequences):
        weight = "" if row["mean_weight"] is None else f" (mean weight {row['mean_weight']:.2f})"
        where = sorted(row["inside_by_capsule_pct"].items(), key=lambda kv: -kv[1])[:4]
        print(
            f"{row['label'] + weight:60s} inside {row['inside_pct']:5.2f} % ("
            + ", ".join(f"{n} {p:.2f}" for n, p in where)
            + f")  hem swing / sim {row['hem_swing_ratio']:.3f}  "
            f"PVE {row['pve_mm']:.2f} mm",
            flush=True,
        )


if __name__ == "__main__":
    main()
