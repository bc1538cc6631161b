"""Analysis: the detail mode's settings, and what lies beside them.

The detail mode (docs/inference.md) adds the high spatial frequencies of the database's simulated
frames (the bundle's fold store) to the regression, frame by frame from a playhead that follows
the matches forward (the fold track). This tool measures, on held-out clips of a trained model
(offline, no push-out, against each clip's single simulation), the mode as shipped and variants of
its settings: the folds' strength, the track's hold and fade, no track at all (each frame's own
proposal), the folds' following in time (:func:`~hrr_garment.inference.fold_track.follow_folds`: 1 is
none), the default output itself offline and causal (``auto``, as a game streams it), and a swing gain (the
regression's body-frame departure from the training frames' mean shape, or from its own causal running mean,
scaled up: the hem swing the mean lacks, at a price in PVE).

Sharpness is the bending energy over the truth's, hem swing the hem's amplitude over the truth's,
jitter the mean distance between predicted and true accelerations (docs/evaluation.md, Metrics).

    python tools/studies/detail_analysis.py --model hrr_work/models/dress-real-quick \\
        --split test --sequences 12
"""

from __future__ import annotations

import argparse
import json
from functools import partial

import numpy as np

from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.eval import metrics as M
from hrr_garment.garment.fit import hem_vertices
from hrr_garment.inference.animator import Animator
from hrr_garment.inference.detail import add_folds
from hrr_garment.inference.fold_track import (
    causal_proposals,
    follow_over_time,
    offline_proposals,
    track_folds,
)
from hrr_garment.inference.frame_path import FramePath
from hrr_garment.inference.run_settings import DetailLook
from hrr_garment.motion.frame import from_body_frame, to_body_frame
from hrr_garment.motion.windows import causal_windows, covering_windows
from hrr_garment.sim.quality import hem_swing

# (label, strength, hold, fade, follow): strength None is the model's calibrated one, follow None
# the shipped FOLD_FOLLOW; hold 1 and fade 0 take each frame's own proposal
TRACKS = [
    ("shipped", None, None, None, None),
    ("strength 0.6", 0.6, None, None, None),
    ("strength 1.0", 1.0, None, None, None),
    ("no track (each frame's proposal)", None, 1, 0, None),
    ("hold 4, fade 3", None, 4, 3, None),
    ("hold 16, fade 6", None, 16, 6, None),
    ("hold 8, fade 12", None, 8, 12, None),
    ("folds not followed (follow 1)", None, None, None, 1.0),
    ("follow 0.5", None, None, None, 0.5),
    ("follow 0.6", None, None, None, 0.6),
]
SWING_GAINS = (1.25, 1.5)
RUNNING_MEAN_S = 1.0  # time constant of the causal running mean a swing gain may scale from instead


def _running_mean(local: np.ndarray, fps: float, seconds: float = RUNNING_MEAN_S) -> np.ndarray:
    """Causal exponential running mean over frames of (T, V, 3), started at the first frame."""
    alpha = 1.0 - np.exp(-1.0 / (seconds * fps))
    out = np.empty_like(local)
    out[0] = local[0]
    for t in range(1, len(local)):
        out[t] = out[t - 1] + alpha * (local[t] - out[t - 1])
    return out


def _proposals(animator: Animator, motion, causal: bool) -> np.ndarray:
    w = animator.window
    path = FramePath(
        animator, animator.resolve(mode="detail", detail=DetailLook(base="regression"), causal=causal)
    )
    if causal:
        windows = causal_windows(animator.features(motion, causal=True), w)
        return causal_proposals(path.choose(windows, last_frame=True).match, w)
    windows = np.ascontiguousarray(covering_windows(animator.features(motion), w))
    return offline_proposals(path.choose(windows).match, motion.num_frames, w)


def analyse(model: str, split: str, sequences: int | None) -> dict:
    animator = Animator.load(model)
    store = animator.bundle.folds
    if store is None:
        raise SystemExit(f"{model} has no fold store (hrr-train --stage codespace adds it)")
    ds = GarmentDataset(animator.bundle.manifest.dataset)
    names = ds.splits.get(split, [])
    if not names:
        raise SystemExit(f"{ds.path} has no {split!r} sequences")
    if sequences:
        names = [
            names[i]
            for i in sorted(
                {int(round(i)) for i in np.linspace(0, len(names) - 1, min(sequences, len(names)))}
            )
        ]
    template = animator.bundle.template
    rest, topo = (
        template.vertices.astype(np.float64),
        M.MeshTopology.of(template.faces, template.num_vertices),
    )
    hem = hem_vertices(template)
    mean_shape = np.mean(
        [
            to_body_frame(ds.sequence(n).garment.astype(np.float64), ds.sequence(n).motion).mean(0)
            for n in ds.splits["train"][::4]
        ],
        axis=0,
    )  # the body-frame mean the swing gain scales from
    sums: dict[str, np.ndarray] = {}
    truth_sums = np.zeros(2)
    frames = 0
    for name in names:
        record = ds.sequence(name)
        motion, truth = record.motion, record.garment.astype(np.float64)
        outputs = {}
        for causal in (False, True):
            kind = "causal" if causal else "offline"
            regression = animator.animate(
                motion, mode="regression", push_out=False, causal=causal
            ).vertices.astype(np.float64)
            local = to_body_frame(regression, motion)
            proposals = _proposals(animator, motion, causal)
            outputs[f"regression ({kind})"] = regression
            outputs[f"auto, the default output ({kind})"] = animator.animate(
                motion, push_out=False, causal=causal
            ).vertices
            for label, strength, hold, fade, follow in TRACKS if not causal else TRACKS[:1]:
                rows, weights = track_folds(
                    proposals,
                    store.offsets,
                    **{k: v for k, v in (("hold", hold), ("fade", fade)) if v is not None},
                )
                folds = store.folds(rows, weights)
                strength = animator.bundle.detail_strength if strength is None else strength
                followed = partial(follow_over_time, mean=animator.smoothing, follow=follow)
                outputs[f"detail, {label} ({kind})"] = from_body_frame(
                    add_folds(local, folds, animator.smoothing, store.passes, strength, follow=followed),
                    motion,
                )
                if label == "shipped" and not causal:
                    running = _running_mean(local, motion.fps)
                    for gain in SWING_GAINS:
                        for ref, centre in (
                            ("mean shape", mean_shape),
                            (f"{RUNNING_MEAN_S:g} s running mean", running),
                        ):
                            swung = centre + gain * (local - centre)
                            outputs[f"regression, swing gain {gain:g} ({ref})"] = from_body_frame(
                                swung, motion
                            )
                            outputs[f"detail, swing gain {gain:g} ({ref})"] = from_body_frame(
                                add_folds(
                                    swung, folds, animator.smoothing, store.passes, strength, follow=followed
                                ),
                                motion,
                            )
        truth_sums += [
            M.cloth_energies(truth, rest, topo)[1].sum(),
            hem_swing(truth, motion, hem) * len(truth),
        ]
        frames += len(truth)
        for key, pred in outputs.items():
            pred = np.asarray(pred, np.float64)
            sums.setdefault(key, np.zeros(4))
            sums[key] += [
                M.pve_mm(pred, truth) * len(truth),
                M.cloth_energies(pred, rest, topo)[1].sum(),
                hem_swing(pred, motion, hem) * len(truth),
                M.jitter_mm(pred, truth)["jitter_mm"] * len(truth),
            ]
    regression_pve = {k: sums[f"regression ({k})"][0] / frames for k in ("offline", "causal")}
    rows = {
        k: {
            "pve_mm": s[0] / frames,
            "pve_vs_regression": s[0] / frames / regression_pve["causal" if "causal" in k else "offline"],
            "sharpness": s[1] / truth_sums[0],
            "hem_swing": s[2] / truth_sums[1],
            "jitter_mm": s[3] / frames,
        }
        for k, s in sums.items()
    }
    return {"model": model, "split": split, "sequences": names, "frames": frames, "modes": rows}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", required=True, help="a trained model directory")
    parser.add_argument("--split", default="test", help="dataset split of held-out clips (default test)")
    parser.add_argument(
        "--sequences", type=int, default=None, help="at most this many of them, evenly spaced"
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args()
    result = analyse(args.model, args.split, args.sequences)
    if args.json:
        print(json.dumps(result, indent=1))
        return
    print(f"{args.model}, {args.split}: {len(result['sequences'])} clips, {result['frames']} frames")
    print(f"{'':52s} {'PVE mm':>8s} {'x reg':>6s} {'sharp':>6s} {'hem':>6s} {'jitter':>7s}")
    for key, r in result["modes"].items():
        print(
            f"{key:52s} {r['pve_mm']:8.2f} {r['pve_vs_regression']:6.3f} {r['sharpness']:6.2f} "
            f"{r['hem_swing']:6.2f} {r['jitter_mm']:7.2f}"
        )


if __name__ == "__main__":
    main()
