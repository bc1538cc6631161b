"""Study: the hem after the body stops, a model against its truth, per cloth (issue 85: the model's
hem swing and settle time within 10 % of the truth's, on held-out cloths).

One clip plays, then its last frame is held ``--hold`` seconds: the body stops dead and stands. Per
clip (``--clip`` takes several: one clip's settling is one draw of its chaos) and in
each cloth the dataset's own simulator (its settings, on the mannequin) makes a truth ensemble of
``--members`` (hrr_garment/eval/ensemble.py: cached, shared with hrr-eval), and the model animates
the same motion in the same cloth (``--mode``, the push-out on, as a user runs it). Per cloth:

- ``hem_swing_cm``: the hem's swing while the body moves (hrr_garment.sim.quality.hem_swing);
  the truth's is its members' mean;
- ``settle_s``: seconds after the stop until the hem stays within ``--near`` (mm, mean over hem
  vertices) of where it stands at the end (its mean over the hold's last second), its positions
  averaged over ``--smooth`` seconds: a jitter about a place is not a swing, and the solver's hem
  jitters (docs/materials.md). The truth's is its members' mean, None where any member does not
  settle within the hold;
- ``hem_speed_last_s``: the hem's mean speed (m/s) over the hold's last second;
- ``away_mm``: the hem's smoothed distance from its resting place at the stop and 0.5 / 1 / 2 / 4 s
  after it: the decay the settle time summarises;
- ``truth_mean``: the same of the members' mean cloth (their vertices averaged frame by frame).
  The members' hems come to rest 15-17 mm from their mean (chaos); what they share is the part of the
  settling that the motion decides, which a model predicting the expected cloth can learn: its
  ``settle_s`` is the reference such a model's is read against (``settle_ratio_to_mean``);
- ``stand_pve_mm``: the model's PVE over the stand against each member (their mean);
- ``curve_gap_mm``: the mean distance between the model's and the truth's (members' mean) distance
  from rest over the hold, every quarter second: whether the model comes to rest as the truth does,
  which a settle time alone does not say (a hem swinging back out until late settles late too).

The run's last second (held past ``--hold``) is left out (an offline animation's last frames were
its last windows' ends alone before the clip's ends were padded; the cached truths keep the length).
With several clips, ``by_cloth`` (printed after the rows) averages each cloth's over the clips
(:func:`by_cloth`): the settle times' means (None where any is), the hem swings' ratio of means, the
curve gaps' mean, and the settle ratio's floor: each truth member's settle time over the other
members' (both averaged over the clips), what a second simulation of the same motion and cloth
scores against the truth (:func:`member_settle_ratios`). A model's ``settle_ratio`` inside that band
cannot be told from a member's; a bar tighter than the band is one the solver itself fails.

Run from the repository root:

    python tools/studies/settle_study.py --model hrr_work/models/dress-real-quick-materials \\
        --dataset hrr_work/datasets/dress-real-quick-materials.h5 \\
        --clip /work/shared/data/mocap/cmu/131_03.bvh dataset-1_walk_sad_001.bvh \\
        --cloths jersey cotton-twill cloth02 --hold 12

(clips the model never trained on: 131_03 and walk_sad_001 are in the materials dataset's test
split, 131_01 in its training split).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from hrr_garment.data.dataset import GarmentDataset, SequenceRecord
from hrr_garment.eval.ensemble import truth_ensembles
from hrr_garment.eval.metrics import pve_mm
from hrr_garment.garment.material import Material, material_from
from hrr_garment.inference.animator import Animator
from hrr_garment.io_utils import atomic_write_text
from hrr_garment.motion.compose import held_still
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.motion import Motion
from hrr_garment.sim.quality import hem_swing
from hrr_garment.sim.simulator import SimSettings

AFTER_S = (0.0, 0.5, 1.0, 2.0, 4.0)
# the run's last second is held past the hold and left out: an offline animation's last frames were
# its last windows' trailing positions alone (up to 25 mm off the blend on a standing body) until the
# clip's ends were padded (motion/windows.covering_windows); kept, so that the cached truths' length holds
END_S = 1.0


def stopping(motion: Motion, seconds: float | None, hold: float) -> Motion:
    """The first ``seconds`` of ``motion`` (None: all of it), then its last frame held ``hold``
    seconds: the body stops dead."""
    frames = motion.num_frames if seconds is None else min(motion.num_frames, round(seconds * motion.fps))
    return held_still(motion.slice(0, frames), round(hold * motion.fps))


def smoothed(hem: np.ndarray, fps: float, smooth_s: float) -> np.ndarray:
    """``hem`` (T, H, 3) with each position averaged over ``smooth_s`` (centred, the ends held): a
    jitter about a place is not a swing."""
    width = max(1, round(smooth_s * fps))
    padded = np.pad(hem, ((width // 2, width - 1 - width // 2), (0, 0), (0, 0)), mode="edge")
    total = np.concatenate([np.zeros_like(padded[:1]), np.cumsum(padded, axis=0)])
    return (total[width:] - total[:-width]) / width


def away_from_rest(hem: np.ndarray, fps: float, smooth_s: float) -> np.ndarray:
    """(T,) the hem's mean distance (m) from where it stands at the end (``hem``: (T, H, 3) after
    the stop; the resting place: its mean over the last second), its positions first averaged over
    ``smooth_s`` (:func:`smoothed`)."""
    rest = hem[-round(fps) :].mean(axis=0)
    return np.linalg.norm(smoothed(hem, fps, smooth_s) - rest, axis=-1).mean(axis=1)


def _stays_below(values: np.ndarray, threshold: float, fps: float) -> float | None:
    """Seconds until ``values`` (one a frame) stay below ``threshold``; None if they are above it
    within the last second."""
    above = np.flatnonzero(values >= threshold)
    if not len(above):
        return 0.0
    if above[-1] >= len(values) - round(fps):
        return None
    return float(above[-1] + 1) / fps


def settle_time(away: np.ndarray, fps: float, near_m: float) -> float | None:
    """Seconds until ``away`` (from :func:`away_from_rest`) stays below ``near_m``; None if it is
    still above it within the hold's last second (the resting place is that second's mean)."""
    return _stays_below(away, near_m, fps)


def still_time(hem: np.ndarray, fps: float, smooth_s: float, still: float) -> float | None:
    """Seconds until the hem's mean speed (m/s; ``hem``: (T, H, 3) after the stop, its positions
    first averaged over ``smooth_s``: :func:`smoothed`) stays below ``still``; None if it is above
    it within the last second."""
    speed = np.linalg.norm(np.diff(smoothed(hem, fps, smooth_s), axis=0), axis=-1).mean(axis=1) * fps
    return _stays_below(speed, still, fps)


def hem_after_stop(vertices: np.ndarray, motion: Motion, stop: int, hem: np.ndarray, args) -> dict:
    """Hem swing while moving and the settling after frame ``stop`` of one run (``vertices``: (T, V, 3))."""
    after = vertices[stop : len(vertices) - round(END_S * motion.fps), hem]
    away = away_from_rest(after, motion.fps, args.smooth)
    speed = np.linalg.norm(np.diff(after, axis=0), axis=-1).mean(axis=1) * motion.fps
    at = {f"{s:g}s": 1000.0 * float(away[min(round(s * motion.fps), len(away) - 1)]) for s in AFTER_S}
    return {
        "hem_swing_cm": 100.0 * hem_swing(vertices[:stop], motion.slice(0, stop), hem),
        "settle_s": settle_time(away, motion.fps, args.near / 1000.0),
        # when the hem's speed (its positions averaged as for ``away``) stays below --still: the
        # swing gone, whatever slow creep of its resting place is left
        "still_s": still_time(after, motion.fps, args.smooth, args.still),
        "away_mm": at,
        "hem_speed_last_s": float(speed[-round(motion.fps) :].mean()),  # m/s, the hold's last second
        # the whole decay, every quarter second (the study's JSON)
        "away_curve_mm": [1000.0 * float(a) for a in away[:: max(1, round(motion.fps / 4))]],
    }


def mean_member_after_stop(
    members: list[np.ndarray], motion: Motion, stop: int, hem: np.ndarray, args
) -> dict:
    """:func:`hem_after_stop` of the members' mean cloth (members: each (T, V, 3)): the settling
    the members share, their chaotic differences averaged out."""
    return hem_after_stop(np.mean(members, axis=0), motion, stop, hem, args)


def _mean(runs: list[dict]) -> dict:
    settles = [r["settle_s"] for r in runs]
    stills = [r["still_s"] for r in runs]
    return {
        "hem_swing_cm": float(np.mean([r["hem_swing_cm"] for r in runs])),
        "settle_s": None if None in settles else float(np.mean(settles)),
        "still_s": None if None in stills else float(np.mean(stills)),
        "settle_s_members": settles,
        "hem_speed_last_s": float(np.mean([r["hem_speed_last_s"] for r in runs])),
        "away_mm": {k: float(np.mean([r["away_mm"][k] for r in runs])) for k in runs[0]["away_mm"]},
        "away_curve_mm": np.mean([r["away_curve_mm"] for r in runs], axis=0).tolist(),
    }


def curve_gap(truth_mm: list[float], model_mm: list[float]) -> float:
    """Mean absolute difference (mm) between two distance-from-rest curves sampled alike."""
    return float(np.abs(np.asarray(model_mm) - np.asarray(truth_mm)).mean())


def _ratio(model, truth) -> float | None:
    return None if model is None or not truth else float(model) / float(truth)


def cloths_of(ds: GarmentDataset, names: list[str]) -> dict[str, Material]:
    """The dataset's recorded cloths by name (its info's materials; named fabrics and sampled ones)."""
    recorded = ds.info.get("materials", {}).get("cloths", {})
    missing = [n for n in names if n not in recorded]
    if missing:
        raise SystemExit(f"{ds.path}: no cloth {missing} (it records {sorted(recorded)})")
    return {n: material_from({"name": n, **recorded[n]}, f"{ds.path}: {n}") for n in names}


def member_settle_ratios(rows: list[dict]) -> list[float] | None:
    """Each truth member's settle time over the other members' (leave one out), both averaged over
    ``rows`` (one cloth's clips): the settle ratios a simulation of the truth scores; None where a
    member does not settle on some clip, or where there is no other member."""
    settles = [r["truth"]["settle_s_members"] for r in rows]
    if any(s is None for clip in settles for s in clip) or min(len(clip) for clip in settles) < 2:
        return None
    m = np.array(settles, float)  # (clips, members)
    others = [np.delete(m, i, 1).mean() for i in range(m.shape[1])]
    return None if min(others) <= 0 else [float(m[:, i].mean() / o) for i, o in enumerate(others)]


def by_cloth(rows: list[dict]) -> dict[str, dict]:
    """Each cloth's rows (one a clip) averaged over the clips: the truth's, the members' mean's and
    the model's settle times (mean; None where any clip's is), their ratios, the members' own
    (:func:`member_settle_ratios`), the hem swings' ratio of means and the curve gaps' mean."""

    def settle(values: list) -> float | None:
        return None if None in values else float(np.mean(values))

    out = {}
    for cloth in dict.fromkeys(r["cloth"] for r in rows):
        mine = [r for r in rows if r["cloth"] == cloth]
        truth = settle([r["truth"]["settle_s"] for r in mine])
        shared = settle([r["truth_mean"]["settle_s"] for r in mine])
        model = settle([r["model"]["settle_s"] for r in mine])
        out[cloth] = {
            "clips": len(mine),
            "settle_s": {"truth": truth, "members_mean": shared, "model": model},
            "settle_ratio": _ratio(model, truth),
            "settle_ratio_to_mean": _ratio(model, shared),
            "member_settle_ratios": member_settle_ratios(mine),
            "hem_swing_ratio": _ratio(
                np.mean([r["model"]["hem_swing_cm"] for r in mine]),
                np.mean([r["truth"]["hem_swing_cm"] for r in mine]),
            ),
            "curve_gap_mm": float(np.mean([r["curve_gap_mm"] for r in mine])),
            "stand_pve_mm": float(np.mean([r["model"]["stand_pve_mm"] for r in mine])),
        }
    return out


def study_clip(
    clip: str, cloths: dict[str, Material], ds: GarmentDataset, animator: Animator, args
) -> list[dict]:
    """One clip stopped and held, in each cloth: the truth's members, their mean and the model."""
    motion = stopping(load_motion(clip), args.seconds, args.hold + END_S)
    stop = motion.num_frames - round((args.hold + END_S) * motion.fps)
    template = ds.template
    hem = template.groups["hem"]
    records = [
        SequenceRecord(
            f"{Path(clip).stem}-stop-{name}",
            np.zeros((motion.num_frames, len(template.vertices), 3), np.float32),
            motion,
            info={"material": cloth.to_dict()},
            material=cloth,
        )
        for name, cloth in cloths.items()
    ]
    ensembles = truth_ensembles(
        template, records, SimSettings.from_dict(ds.info["sim"]), args.members, jobs=args.jobs
    )
    rows = []
    for record, name in zip(records, cloths):
        members = [m.astype(np.float64) for m in ensembles[record.name].members]
        truth = [hem_after_stop(m, motion, stop, hem, args) for m in members]
        truth_mean = mean_member_after_stop(members, motion, stop, hem, args)
        run = animator.animate(
            motion, mode=args.mode, settle=args.settle, material=record.material, allow_outside_material=True
        )
        pred = run.vertices.astype(np.float64)
        model = hem_after_stop(pred, motion, stop, hem, args)
        end = len(pred) - round(END_S * motion.fps)
        # the whole garment over the stand against each member (their mean PVE)
        model["stand_pve_mm"] = float(np.mean([pve_mm(pred[stop:end], m[stop:end]) for m in members]))
        t = _mean(truth)
        rows.append(
            {
                "clip": Path(clip).stem,
                "cloth": name,
                "truth": t,
                "truth_mean": truth_mean,
                "model": model,
                "hem_swing_ratio": _ratio(model["hem_swing_cm"], t["hem_swing_cm"]),
                "settle_ratio": _ratio(model["settle_s"], t["settle_s"]),
                "settle_ratio_to_mean": _ratio(model["settle_s"], truth_mean["settle_s"]),
                "curve_gap_mm": curve_gap(t["away_curve_mm"], model["away_curve_mm"]),
            }
        )
    return rows


def _settle(s: float | None) -> str:
    return "> hold" if s is None else f"{s:.2f}"


def _of(ratio: float | None) -> str:
    return "" if ratio is None else format(ratio, ".2f")


def print_rows(rows: list[dict]) -> None:
    print(
        "| clip | cloth | hem swing cm: truth / model | ratio | settle s: truth (members) / model | ratio | "
        + "settle s: members' mean / model | ratio | "
        + " | ".join(f"away mm {k}: truth / model" for k in rows[0]["model"]["away_mm"])
        + " | still (hem under --still m/s) s: truth / model | hem m/s at the end: truth / model "
        + "| curve gap mm |"
    )
    for r in rows:
        t, m = r["truth"], r["model"]
        members = ", ".join(_settle(s) for s in t["settle_s_members"])
        print(
            f"| {r['clip']} | {r['cloth']} | {t['hem_swing_cm']:.1f} / {m['hem_swing_cm']:.1f} | "
            f"{r['hem_swing_ratio'] or 0:.2f} | "
            f"{_settle(t['settle_s'])} ({members}) / {_settle(m['settle_s'])} | {_of(r['settle_ratio'])} | "
            f"{_settle(r['truth_mean']['settle_s'])} / {_settle(m['settle_s'])} | "
            f"{_of(r['settle_ratio_to_mean'])} | "
            + " | ".join(f"{t['away_mm'][k]:.0f} / {m['away_mm'][k]:.0f}" for k in m["away_mm"])
            + f" | {_settle(t['still_s'])} / {_settle(m['still_s'])}"
            + f" | {t['hem_speed_last_s']:.2f} / {m['hem_speed_last_s']:.2f} | {r['curve_gap_mm']:.1f} |"
        )


def print_by_cloth(summary: dict[str, dict]) -> None:
    print(
        "| cloth | clips | hem swing / truth | settle s: truth / members' mean / model | "
        "over the truth's | a member over the others' | over the members' mean's | curve gap mm | "
        "PVE over the stand mm |"
    )
    for cloth, c in summary.items():
        s, floor = c["settle_s"], c["member_settle_ratios"]
        band = "" if floor is None else f"{min(floor):.2f}-{max(floor):.2f}"
        print(
            f"| {cloth} | {c['clips']} | {_of(c['hem_swing_ratio'])} | "
            f"{_settle(s['truth'])} / {_settle(s['members_mean'])} / {_settle(s['model'])} | "
            f"{_of(c['settle_ratio'])} | {band} | {_of(c['settle_ratio_to_mean'])} | "
            f"{c['curve_gap_mm']:.1f} | {c['stand_pve_mm']:.1f} |"
        )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", required=True, type=Path)
    p.add_argument("--dataset", required=True, type=Path, help="its simulator settings and cloths")
    p.add_argument("--clip", nargs="+", required=True, help="real clips (BVH, glTF, npz), each studied alone")
    p.add_argument("--cloths", nargs="+", required=True, help="cloths the dataset records, by name")
    p.add_argument("--seconds", type=float, default=None, help="of each clip before the stop (all)")
    p.add_argument("--hold", type=float, default=4.0, help="seconds the body then stands")
    p.add_argument("--members", type=int, default=4)
    p.add_argument("--mode", default="auto")
    p.add_argument("--settle", type=float, default=0.0, help="the settling lag, s (0: none)")
    p.add_argument("--near", type=float, default=10.0, help="mm from the resting place counted as settled")
    p.add_argument("--smooth", type=float, default=0.5, help="seconds the hem's positions are averaged over")
    p.add_argument("--still", type=float, default=0.02, help="hem speed (m/s) counted as still")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("-o", "--output", type=Path, default=Path("hrr_work/studies/settle/summary.json"))
    args = p.parse_args(argv)
    ds = GarmentDataset(args.dataset)
    cloths = cloths_of(ds, args.cloths)
    animator = Animator.load(args.model)
    rows = [row for clip in args.clip for row in study_clip(clip, cloths, ds, animator, args)]
    summary = {
        "clips": args.clip,
        "model": args.model,
        "settings": vars(args),
        "rows": rows,
        "by_cloth": by_cloth(rows),
    }
    atomic_write_text(args.output, json.dumps(summary, indent=1, default=str))
    print_rows(rows)
    if len(args.clip) > 1:
        print_by_cloth(summary["by_cloth"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
