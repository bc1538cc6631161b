"""Analysis: how much hem swing and sharpness can an accurate prediction have?

Against a chaotic truth the most accurate prediction is the conditional mean, and a mean of
simulations swings and folds less than each of them. This tool measures it on held-out clips with
the truth ensembles ``hrr-eval --ensemble K`` cached (perturbed re-simulations of each clip;
docs/results.md): the members' own mean (the best accurate prediction there is, up to the chaos a
mean of K samples keeps) scored as the evaluation scores a model (PVE to the members over the floor,
sharpness and hem swing over the members'), and the hem swing of the conditional mean itself,
extrapolated to infinitely many members: per hem vertex, the temporal variance of one member is
``V_c + s2`` and that of a mean of K is ``V_c + s2 / K`` (the chaos independent between members),
which gives the predictable part ``V_c``. Beside it, the model's own ceilings on the same clips
(against each clip's single simulation): the autoencoder's reconstruction of the true frames, and
the code space's (each true window through the garment encoder, its argmax code and the decoder,
windows blended): what the discrete code can give back of a garment it is shown.

    python tools/studies/swing_ceiling.py --model hrr_work/models/dress-real-quick --split test --sequences 12
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path

import numpy as np
import torch

from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.eval import metrics as M
from hrr_garment.eval.ensemble import truth_ensembles
from hrr_garment.eval.scoring import as_simulated
from hrr_garment.garment.fit import hem_vertices
from hrr_garment.inference.animator import Animator
from hrr_garment.inference.blending import blend_windows
from hrr_garment.inference.decoding import body_frame_vertices
from hrr_garment.motion.frame import to_body_frame, world_vertices
from hrr_garment.motion.windows import covering_windows
from hrr_garment.sim.quality import hem_swing
from hrr_garment.sim.simulator import SimSettings


def code_reconstruction(animator: Animator, latents: np.ndarray) -> np.ndarray:
    """(T, nodes, C) true latents -> (T, nodes, C): each window through the garment encoder, its
    argmax code and the code-space decoder, overlapping windows blended as inference blends them."""
    b, w = animator.bundle, animator.window
    if b.codespace.config.condition_features:
        raise SystemExit(
            "the code reconstruction reads a model of one body in one cloth (no condition columns)"
        )
    standard = b.latent_stats.normalize(latents.reshape(len(latents), -1)).reshape(latents.shape)
    windows = np.ascontiguousarray(covering_windows(standard.astype(np.float32), w))
    cs = b.codespace
    with torch.no_grad():
        logits = cs.garment_encoder(torch.from_numpy(windows.reshape(len(windows), -1)))
        decoded = cs.decode(cs.quantizer.embed(cs.quantizer.codes(logits))).numpy()
    decoded = b.latent_stats.denormalize(decoded.reshape(*decoded.shape[:2], -1)).reshape(decoded.shape)
    return blend_windows(decoded, len(windows) + w - 1)[w - 1 : w - 1 + len(latents)]


def ceilings(animator: Animator, records: list, hem: np.ndarray) -> dict:
    """PVE (mm) and hem swing over the truth's of the autoencoder's and the code space's own
    reconstructions of ``records``' true frames, and of the regression."""
    folder = Path(animator.bundle.folder) / "autoencoder" / "latents.npz"
    sums = {k: np.zeros(2) for k in ("autoencoder", "code space", "regression")}
    truth_swing = frames = 0.0
    with np.load(folder) as stored:
        for r in records:
            truth = r.garment.astype(np.float64)
            z = stored[r.name].astype(np.float32)
            outs = {"autoencoder": z, "code space": code_reconstruction(animator, z)}
            preds = {
                k: world_vertices(body_frame_vertices(animator.bundle, v, animator.decoder), r.motion)
                for k, v in outs.items()
            }
            preds["regression"] = animator.animate(
                r.motion, mode="regression", push_out=False, **as_simulated(animator.bundle, r)
            ).vertices
            for k, p in preds.items():
                p = np.asarray(p, np.float64)
                sums[k] += [M.pve_mm(p, truth) * len(truth), hem_swing(p, r.motion, hem) * len(truth)]
            truth_swing += hem_swing(truth, r.motion, hem) * len(truth)
            frames += len(truth)
    return {k: {"pve_mm": s[0] / frames, "hem_swing": s[1] / truth_swing} for k, s in sums.items()}


def analyse(model: str, split: str, sequences: int | None, members: int) -> dict:
    animator = Animator.load(model)
    ds = GarmentDataset(animator.bundle.manifest.dataset)
    names = ds.splits.get(split, [])
    if sequences:
        names = [
            names[i]
            for i in sorted(
                {int(round(i)) for i in np.linspace(0, len(names) - 1, min(sequences, len(names)))}
            )
        ]
    records = [ds.sequence(n) for n in names]
    ensembles = truth_ensembles(
        ds.template, records, SimSettings.from_dict(ds.info["sim"]), members, jobs=2, bodies=ds.bodies
    )
    template = animator.bundle.template
    rest, topo = (
        template.vertices.astype(np.float64),
        M.MeshTopology.of(template.faces, template.num_vertices),
    )
    hem = hem_vertices(template)
    # frames x: floor, PVE of the mean; bending of the mean, of the members; swing ditto; sqrt V_c, sqrt var_1
    sums = np.zeros(8)
    for record in records:
        if record.name not in ensembles:
            continue
        m = ensembles[record.name].members.astype(np.float64)
        k, t = len(m), m.shape[1]
        mean = m.mean(0)
        floor = np.mean([M.pve_mm(a, b) for a, b in itertools.combinations(m, 2)])
        local = np.stack([to_body_frame(x[:, hem], record.motion, ground=True) for x in m])  # (K, T, H, 3)
        var_one = local.var(axis=1).sum(-1).mean(0)  # (H,) a member's temporal variance, mean over members
        var_mean = local.mean(0).var(axis=0).sum(-1)  # the mean's
        chaos = np.maximum(var_one - var_mean, 0.0) * k / (k - 1)
        sums += t * np.array(
            [
                floor,
                np.mean([M.pve_mm(mean, x) for x in m]),
                M.cloth_energies(mean, rest, topo)[1].mean(),
                np.mean([M.cloth_energies(x, rest, topo)[1].mean() for x in m]),
                hem_swing(mean, record.motion, hem),
                np.mean([hem_swing(x, record.motion, hem) for x in m]),
                np.sqrt(np.maximum(var_one - chaos, 0.0)).mean(),
                np.sqrt(var_one).mean(),
            ]
        )
    own = ceilings(animator, records, hem)
    frames = sum(len(r.garment) for r in records if r.name in ensembles)
    return {
        "clips": len(ensembles),
        "members": members,
        "floor_mm": sums[0] / max(frames, 1),
        "mean_pve_over_floor": sums[1] / sums[0],
        "mean_sharpness": sums[2] / sums[3],
        "mean_hem_swing": sums[4] / sums[5],
        "conditional_mean_hem_swing": sums[6] / sums[7],
        "reconstructions": own,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--model", required=True, help="a trained model directory (its dataset and template)")
    parser.add_argument("--split", default="test", help="dataset split of held-out clips (default test)")
    parser.add_argument(
        "--sequences", type=int, default=None, help="at most this many of them, evenly spaced"
    )
    parser.add_argument(
        "--ensemble", type=int, default=4, help="members per clip, as hrr-eval ran them (default 4)"
    )
    args = parser.parse_args()
    r = analyse(args.model, args.split, args.sequences, args.ensemble)
    print(f"{r['clips']} clips, {r['members']} members each, floor {r['floor_mm']:.2f} mm")
    print(
        f"the members' mean: PVE / floor {r['mean_pve_over_floor']:.3f}, sharpness "
        f"{r['mean_sharpness']:.2f}, hem swing {r['mean_hem_swing']:.2f}"
    )
    print(f"the conditional mean (infinitely many members): hem swing {r['conditional_mean_hem_swing']:.2f}")
    for k, c in r["reconstructions"].items():
        print(
            f"{k + (' reconstruction' if k != 'regression' else ''):28s} PVE {c['pve_mm']:6.2f} mm, "
            f"hem swing {c['hem_swing']:.2f}"
        )


if __name__ == "__main__":
    main()
