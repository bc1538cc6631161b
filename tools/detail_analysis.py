"""Analysis: where does the detail mode's sharpness stop, and what would lift it?

Every mode decodes its garment through the mesh autoencoder, whose own reconstruction of the true
frames keeps about three quarters of their bending energy (docs/results.md); the detail mode takes
its folds from the retrieved windows' *decoded* latents, so it inherits that ceiling and the blend
of overlapping windows averages what is left. This tool measures, on held-out clips of a trained
model (offline, no push-out, against each clip's single simulation), the detail mode with the
folds taken instead from the database's simulated frames themselves:

- ``raw retrieval``: each frame the simulated frame of its centred window's match (no decoding,
  no blending: as sharp as the database, and jittery where the match changes);
- ``detail (raw ...)``: the regression plus the high spatial frequencies of those frames
  (:func:`hrr_garment.inference.detail.add_detail`) at a few strengths and smoothing passes;
- ``detail (raw, blended)``: the same with every overlapping window's frame blended as the
  latents are (smooth in time; the blend averages folds of different matches away).

Sharpness is the bending energy over the truth's, hem swing the hem's amplitude over the truth's,
jitter the mean distance between predicted and true accelerations (docs/results.md, Metrics).

    python tools/detail_analysis.py --model hrr_work/models/dress-real-quick --split test --sequences 12
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.eval import metrics as M
from hrr_garment.garment.fit import hem_vertices
from hrr_garment.inference.animator import Animator
from hrr_garment.inference.blending import window_weights
from hrr_garment.inference.detail import add_detail
from hrr_garment.inference.gate import choose_windows
from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.windows import sequence_windows
from hrr_garment.sim.quality import hem_swing


def _raw_frames(animator: Animator, ds: GarmentDataset, record, cache: dict) -> tuple[np.ndarray, np.ndarray]:
    """(centre, blended) world vertices (T, V, 3) from the database's simulated frames: each frame
    its centred window's match, or every window's match weighted as the latents are blended."""
    names, w = animator.bundle.database.names, animator.window
    feats = animator.features(record.motion)
    t_frames = len(feats)
    choice = choose_windows(animator.bundle, np.ascontiguousarray(sequence_windows(feats, w)), "retrieval", 0.0)

    def body(seq: int) -> np.ndarray:
        name = names[seq]
        if name not in cache:
            rec = ds.sequence(name)
            cache[name] = to_body_frame(rec.garment.astype(np.float64), rec.motion)
        return cache[name]

    weights = window_weights(w)
    blended = np.zeros((t_frames, *body(int(choice.source[0, 0])).shape[1:]))
    total = np.zeros(t_frames)
    for i, (seq, start) in enumerate(choice.source):
        blended[i:i + w] += weights[:, None, None] * body(int(seq))[start:start + w]
        total[i:i + w] += weights
    centre = np.empty_like(blended)
    for t in range(t_frames):
        i = int(np.clip(t - w // 2, 0, len(choice.source) - 1))
        seq, start = choice.source[i]
        centre[t] = body(int(seq))[start + t - i]
    return from_body_frame(centre, record.motion), from_body_frame(blended / total[:, None, None], record.motion)


def analyse(model: str, split: str, sequences: int | None) -> dict:
    animator = Animator.load(model)
    ds = GarmentDataset(animator.bundle.meta["dataset"])
    names = ds.splits.get(split, [])
    if not names:
        raise SystemExit(f"{ds.path} has no {split!r} sequences")
    if sequences:
        names = [names[i] for i in sorted({int(round(i)) for i in np.linspace(0, len(names) - 1, min(sequences, len(names)))})]
    template = animator.bundle.template
    rest, topo = template.vertices.astype(np.float64), M.MeshTopology.of(template.faces, template.num_vertices)
    hem = hem_vertices(template)
    sums: dict[str, np.ndarray] = {}
    truth_sums = np.zeros(2)
    frames, cache = 0, {}
    for name in names:
        record = ds.sequence(name)
        truth = record.garment.astype(np.float64)
        regression = animator.animate(record.motion, mode="regression", collision=False).vertices.astype(np.float64)
        centre, blended = _raw_frames(animator, ds, record, cache)
        outputs = {
            "regression": regression,
            "retrieval (decoded, blended)": animator.animate(record.motion, mode="retrieval", collision=False).vertices,
            "raw retrieval (centre)": centre,
            "detail (decoded: the detail mode)": animator.animate(record.motion, mode="detail", collision=False).vertices,
            "detail (raw, centre)": add_detail(regression, centre, animator.smoothing),
            "detail (raw, centre, 1 pass)": add_detail(regression, centre, animator.smoothing, passes=1),
            "detail (raw, centre, 1 pass, strength 0.8)": add_detail(regression, centre, animator.smoothing, strength=0.8,
                                                                      passes=1),
            "detail (raw, centre, strength 1.2)": add_detail(regression, centre, animator.smoothing, strength=1.2),
            "detail (raw, blended)": add_detail(regression, blended, animator.smoothing),
        }
        truth_sums += [M.cloth_energies(truth, rest, topo)[1].sum(), hem_swing(truth, record.motion, hem) * len(truth)]
        frames += len(truth)
        for key, pred in outputs.items():
            pred = np.asarray(pred, np.float64)
            sums.setdefault(key, np.zeros(4))
            sums[key] += [M.pve_mm(pred, truth) * len(truth), M.cloth_energies(pred, rest, topo)[1].sum(),
                          hem_swing(pred, record.motion, hem) * len(truth), M.jitter_mm(pred, truth)["jitter_mm"] * len(truth)]
    regression_pve = sums["regression"][0] / frames
    rows = {k: {"pve_mm": s[0] / frames, "pve_vs_regression": s[0] / frames / regression_pve,
                "sharpness": s[1] / truth_sums[0], "hem_swing": s[2] / truth_sums[1], "jitter_mm": s[3] / frames}
            for k, s in sums.items()}
    return {"model": model, "split": split, "sequences": names, "frames": frames, "modes": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", required=True, help="a trained model directory")
    parser.add_argument("--split", default="test", help="dataset split of held-out clips (default test)")
    parser.add_argument("--sequences", type=int, default=None, help="at most this many of them, evenly spaced")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args()
    result = analyse(args.model, args.split, args.sequences)
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"{args.model}, {args.split}: {len(result['sequences'])} clips, {result['frames']} frames")
    print(f"{'':44s} {'PVE mm':>8s} {'x reg':>6s} {'sharp':>6s} {'hem':>6s} {'jitter':>7s}")
    for key, r in result["modes"].items():
        print(f"{key:44s} {r['pve_mm']:8.2f} {r['pve_vs_regression']:6.3f} {r['sharpness']:6.2f} {r['hem_swing']:6.2f} "
              f"{r['jitter_mm']:7.2f}")


if __name__ == "__main__":
    main()
