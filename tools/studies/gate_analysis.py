"""Analysis: how much could any retrieval gate gain on a trained model?

For every window of a dataset split (the window-level errors ``hrr-train`` calibrates tau on), it
computes the regression and retrieval candidates' per-vertex errors and prints:

- the per-mode means and the *oracle hybrid*: each window taking the better of its two candidates,
  a bound no gate (entropy threshold or other) can beat;
- how often retrieval is the better candidate;
- how well the gate signals (hrr_garment.artifacts.gate_signals) predict retrieval's advantage
  (regression error minus retrieval error): low doubt of each, i.e. low motion-code entropy (the
  paper's), high code similarity of the match, low motion distance of the match;
- the same oracle with the naive nearest-neighbour retrieval.

    python tools/studies/gate_analysis.py --model hrr_work/models/dress-quick --split val
    python tools/studies/gate_analysis.py --model hrr_work/models/dress-full --split test --json
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import torch

from hrr_garment.artifacts.bundle_loader import load_bundle
from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.data.windows import dataset_features
from hrr_garment.motion.windows import sequence_windows
from hrr_garment.train.calibration_windows import predict_windows, window_errors_mm
from hrr_garment.train.training_frames import body_frames


def analyse(model: str, dataset: str | None, split: str) -> dict:
    bundle = load_bundle(model)
    path = dataset or bundle.manifest.dataset
    if not path:
        raise SystemExit(f"{model} does not record its dataset; give --dataset")
    ds = GarmentDataset(path)
    names = ds.splits.get(split, [])
    if not names:
        raise SystemExit(f"{path} has no {split!r} sequences")
    w = bundle.codespace.config.window
    features = dataset_features(ds, names, bundle.codespace.config)
    names = [n for n in names if len(features[n]) >= w]
    motion = np.concatenate([sequence_windows(features[n], w) for n in names])
    truth = np.concatenate([sequence_windows(body_frames(ds, [n]), w) for n in names])
    pred = predict_windows(
        bundle.codespace, motion, bundle.motion_stats, bundle.latent_stats, bundle.database
    )
    naive = bundle.database.nearest_motion(bundle.motion_stats.normalize(motion))
    decode = bundle.autoencoder.inference_decoder()
    with torch.no_grad():
        reg = window_errors_mm(decode, pred.regression, truth)
        ret = window_errors_mm(decode, pred.retrieval, truth)
        nn = window_errors_mm(decode, bundle.database.latents[naive], truth)
    advantage = reg - ret  # > 0 where retrieval is the better candidate
    return {
        "model": model,
        "split": split,
        "windows": len(reg),
        "regression_mm": float(reg.mean()),
        "retrieval_mm": float(ret.mean()),
        "naive_nn_mm": float(nn.mean()),
        "oracle_hybrid_mm": float(np.minimum(reg, ret).mean()),
        "oracle_hybrid_naive_mm": float(np.minimum(reg, nn).mean()),
        "retrieval_better_fraction": float((advantage > 0).mean()),
        **{
            f"corr_advantage_low_{g}_doubt": float(np.corrcoef(advantage, -d)[0, 1])
            for g, d in pred.doubts().items()
        },
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--model", required=True, help="model bundle directory")
    p.add_argument("--dataset", default=None, help="dataset (default: the one the model was trained on)")
    p.add_argument("--split", default="val", choices=("train", "val", "test"))
    p.add_argument("--json", action="store_true", help="print one JSON object")
    args = p.parse_args(argv)
    r = analyse(args.model, args.dataset, args.split)
    if args.json:
        print(json.dumps(r))
        return
    print(
        f"{r['model']} {r['split']}: {r['windows']} windows; regression {r['regression_mm']:.2f} mm, "
        f"retrieval {r['retrieval_mm']:.2f} mm, naive NN {r['naive_nn_mm']:.2f} mm"
    )
    print(
        f"oracle hybrid (better candidate per window) {r['oracle_hybrid_mm']:.2f} mm = "
        f"{r['oracle_hybrid_mm'] / r['regression_mm']:.3f} x regression; with naive NN "
        f"{r['oracle_hybrid_naive_mm']:.2f} mm"
    )
    corr = ", ".join(
        f"{k.split('_low_')[1].removesuffix('_doubt')} {v:+.3f}"
        for k, v in r.items()
        if k.startswith("corr_")
    )
    print(
        f"retrieval better in {100 * r['retrieval_better_fraction']:.1f} % of windows; correlation of its "
        f"advantage with each gate's confidence (low doubt): {corr}"
    )


if __name__ == "__main__":
    main()
