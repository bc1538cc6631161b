"""The detail mode's fold strain limit against what it changes: a model's default output (push-out
on) on a dataset's test clips with the limit at each value, against each clip's simulation.

    python tools/studies/fold_limit_sweep.py --model hrr_work/models/dress-real-quick-bodies-contact \\
        --dataset hrr_work/datasets/dress-real-quick.h5 --sequences 6 --limits none,1.5,1.3,1.2

Prints, per limit, the PVE (mm), the edge strain p99 and max of the output beside the truth's (on
the template's rest lengths: use a dataset simulated on the template's own body), the bending
energy ratio (sharpness) and the mean acceleration ratio (jitter), averaged over the clips.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    import hrr_garment.inference.detail as detail
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.metrics import MeshTopology, edge_strain_percentiles, energy_ratios, pve_mm
    from hrr_garment.eval.scoring import as_simulated
    from hrr_garment.eval.unseen_bodies import evenly
    from hrr_garment.inference.animator import Animator

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True)
    p.add_argument("--dataset", required=True)
    p.add_argument("--sequences", type=int, default=6, help="test clips, evenly spaced")
    p.add_argument("--limits", default="none,1.5", help="strain limits (x rest length); none: no limit")
    args = p.parse_args()
    animator = Animator.load(args.model)
    ds = GarmentDataset(args.dataset)
    records = [ds.sequence(name) for name in evenly(ds.splits["test"], args.sequences)]
    template = animator.bundle.template
    topo = MeshTopology.of(template.faces, template.num_vertices)
    for text in args.limits.split(","):
        limit = None if text.strip() == "none" else float(text)
        detail.FOLD_MAX_STRAIN = limit if limit is not None else np.inf
        rows, started = [], time.perf_counter()
        for r in records:
            v = animator.animate(r.motion, **as_simulated(animator.bundle, r)).vertices.astype(np.float64)
            g = r.garment.astype(np.float64)
            out, truth = (edge_strain_percentiles(x, template.vertices, topo) for x in (v, g))
            acceleration = (
                np.linalg.norm(np.diff(v, 2, 0), axis=-1).mean()
                / np.linalg.norm(np.diff(g, 2, 0), axis=-1).mean()
            )
            rows.append(
                (
                    pve_mm(v, g),
                    out["strain_p99"],
                    out["strain_max"],
                    truth["strain_p99"],
                    truth["strain_max"],
                    energy_ratios(v, g, template.vertices, topo)["bending_energy_ratio"],
                    acceleration,
                )
            )
        a = np.array(rows)
        print(
            f"limit {text.strip()}: PVE {a[:, 0].mean():.2f} mm, strain p99 {a[:, 1].mean():.3f} (truth "
            f"{a[:, 3].mean():.3f}), max {a[:, 2].max():.2f} (truth {a[:, 4].max():.2f}), bending energy "
            f"ratio {a[:, 5].mean():.2f}, acceleration ratio {a[:, 6].mean():.2f} "
            f"({time.perf_counter() - started:.0f} s)",
            flush=True,
        )


if __name__ == "__main__":
    main()
