"""The contact phase's weight and margin against what they cost: each pair run on a trained model,
then its regression animated (push-out off) on another dataset's test clips, against their simulation.

    python tools/studies/contact_sweep.py --model hrr_work/models/dress-real-quick-bodies \\
        --eval-dataset hrr_work/datasets/dress-real-quick-short-heavy.h5 --weights 0,0.5,1,2 --steps 300
    python tools/studies/contact_sweep.py --model M --eval-dataset D --weights 2 --margins 0.002,0.006,0.01

The latent loss beside the body term is the vertex metric (the real-motion presets'). Prints, per weight, the
PVE (mm, against each clip's single simulation) and the share of vertices more than 5 mm inside the clip's
body before the push-out (docs/decisions/0020-contact-phase.md). The model on disk is not changed: each weight
starts from its trained decoder.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np


def main() -> None:
    from hrr_garment.artifacts.bundle_loader import load_bundle
    from hrr_garment.data.dataset import GarmentDataset
    from hrr_garment.eval.scoring import as_simulated
    from hrr_garment.eval.unseen_bodies import evenly
    from hrr_garment.inference.animator import Animator
    from hrr_garment.sim.quality import body_signed_distance, penetration_fraction
    from hrr_garment.train.codespace_settings import CodeSpaceTrainSettings
    from hrr_garment.train.contact import FrameDecoder, model_contact_windows, teach_contact
    from hrr_garment.train.vertex_metric import VertexMetric, sample_frames

    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", type=Path, required=True)
    p.add_argument("--eval-dataset", type=Path, required=True, help="a dataset whose test clips are animated")
    p.add_argument("--weights", default="0,0.5,1,2")
    p.add_argument("--margins", default="0.002", help="clearances in metres (contact_margin_m)")
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--sequences", type=int, default=8, help="test clips animated, evenly spaced")
    args = p.parse_args()
    trained_on = GarmentDataset(load_bundle(args.model).manifest.dataset)
    train = model_contact_windows(args.model, trained_on, "train")
    evaluation = GarmentDataset(args.eval_dataset)
    records = [evaluation.sequence(n) for n in evenly(evaluation.splits["test"], args.sequences)]
    print(
        f"{args.model}: {len(train.windows)} training windows; {len(records)} test clips of "
        f"{args.eval_dataset}"
    )
    latents = train.windows.latents  # standardised; the latent loss is the real-motion presets' vertex metric
    raw = (
        load_bundle(args.model)
        .latent_stats.denormalize(latents.reshape(len(latents), -1).numpy())
        .reshape(latents.shape)
    )
    pairs = [(float(w), float(m)) for w in args.weights.split(",") for m in args.margins.split(",")]
    for weight, margin in pairs:
        animator = Animator.load(args.model)
        bundle = animator.bundle
        metric = VertexMetric.of_decoder(
            bundle.autoencoder, sample_frames(raw), bundle.latent_stats.std, progress=False
        )
        config = CodeSpaceTrainSettings(
            contact_steps=args.steps, contact_weight=weight, contact_margin_m=margin
        )
        with tempfile.TemporaryDirectory() as tmp:
            teach_contact(
                bundle.codespace,
                FrameDecoder(bundle.autoencoder, bundle.latent_stats),
                train,
                val=None,
                config=config,
                latent_loss=metric,
                checkpoint=(Path(tmp) / "contact.pt", "sweep"),
            )
        errors, inside, frames = 0.0, 0.0, 0
        for r in records:
            vertices = animator.animate(
                r.motion, mode="regression", push_out=False, **as_simulated(animator.bundle, r)
            ).vertices
            errors += float(np.linalg.norm(vertices - r.garment, axis=-1).mean()) * 1000 * len(vertices)
            inside += float(
                penetration_fraction(body_signed_distance(vertices, r.motion, r.dressed.body)).sum()
            )
            frames += len(vertices)
        print(
            f"weight {weight:g}, margin {1000 * margin:g} mm, {args.steps} steps: "
            f"PVE {errors / frames:.2f} mm, {100 * inside / frames:.2f} % of vertices > 5 mm inside before "
            "the push-out",
            flush=True,
        )


if __name__ == "__main__":
    main()
