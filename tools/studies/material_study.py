"""Study: what each named fabric does to a garment on a real clip, in numbers (docs/materials.md).

Every fabric (hrr_garment/garment/fabrics.py) simulates the garment on one clip whose body then
stops dead and stands (its last frame held), ``--members`` times with the ensemble's perturbations
(hrr_garment/eval/ensemble.py: density one part in 10,000 either way, the settle one frame longer
or shorter). Per fabric:

- ``strain_p99``: edge length over rest length, p99 over every edge, frame and member (the gate
  every dataset is held to: 1.15); ``attempts``: the most attempts a member needed;
- ``hem_swing_cm``: the hem's swing while the body moves (hrr_garment.sim.quality.hem_swing);
- ``settle_s``: after the body stops, when the hem's mean speed falls below ``--still`` (m/s) for
  good, mean over members (None: not within the hold); ``hem_speed_1s`` / ``hem_speed_end``: the
  hem's mean speed (m/s) one second after the stop and at the end of the hold, and
  ``hem_still_amplitude_mm``: how far the hem still moves about its mean over the hold's last second;
- ``floor_mm``: the chaos floor, the mean distance between two members while the body moves
  (hrr_garment.eval.ensemble_metrics.mean_pairwise_mm, the one hrr-eval's PVE / floor divides by);
- ``drop_cm``: how far the hem hangs below the default cloth's, standing at the end.

Members are kept under ``--work`` (one file each, keyed by fabric, member and clip) so a rerun
simulates only what is missing.

    python tools/studies/material_study.py --clip hrr_work/mocap/clips-25866116/cmu-01-09/07_01.bvh \\
        --seconds 6 --hold 3 --members 4 --jobs 2
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from hrr_garment.eval.ensemble import member_config
from hrr_garment.eval.ensemble_metrics import mean_pairwise_mm
from hrr_garment.garment.fabrics import FABRICS
from hrr_garment.garment.templates import make_garment
from hrr_garment.io_utils import atomic_path, atomic_write_text
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.motion import Motion
from hrr_garment.sim.quality import edge_strain, hem_swing
from hrr_garment.sim.simulator import SimSettings, SimulationExploded, simulate_garment

sys.path.insert(0, str(Path(__file__).resolve().parent))
from settle_study import stopping  # noqa: E402


def settle_time(hem: np.ndarray, start: int, fps: float, still: float) -> float | None:
    """Seconds after frame ``start`` until the hem's mean speed (``hem``: (T, H, 3)) stays below
    ``still`` m/s; None when it never does."""
    speed = np.linalg.norm(np.diff(hem[start:], axis=0), axis=-1).mean(axis=1) * fps
    moving = np.flatnonzero(speed >= still)
    if not len(moving):
        return 0.0
    if moving[-1] == len(speed) - 1:
        return None
    return float(moving[-1] + 1) / fps


def _simulate(
    garment_name: str, clip: str, seconds: float, hold: float, fabric: str, k: int, out: str, solver: dict
):
    motion = stopping(load_motion(clip), seconds, hold)
    garment = make_garment(garment_name)
    config, what = member_config(SimSettings(material=FABRICS[fabric], **solver), k, motion.fps)
    try:
        result = simulate_garment(garment, motion, config)
    except SimulationExploded as exc:
        return fabric, k, f"exploded: {exc}"
    with atomic_path(Path(out)) as tmp:
        with open(tmp, "wb") as f:
            np.savez(f, vertices=result.vertices.astype(np.float32), attempts=result.attempts, what=what)
    return fabric, k, None


def _member_path(work: Path, args, fabric: str, k: int) -> Path:
    clip = str(Path(args.clip).resolve())
    key = json.dumps(
        [args.garment, clip, args.seconds, args.hold, FABRICS[fabric].to_dict(), k, _solver(args)]
    )
    return work / f"{fabric}-{k}-{hashlib.sha1(key.encode()).hexdigest()[:10]}.npz"


def _after_the_stop(hem: np.ndarray, start: int, fps: float) -> dict:
    """Members' mean hem speed a second after frame ``start`` and at the end, and the hem's motion
    about its mean over the last second (``hem``: (K, T, H, 3))."""
    speed = np.linalg.norm(np.diff(hem[:, start:], axis=1), axis=-1).mean(axis=(0, 2)) * fps
    last = hem[:, -int(fps) :]
    amplitude = np.linalg.norm(last - last.mean(axis=1, keepdims=True), axis=-1).mean()
    return {
        "hem_speed_1s": float(speed[min(int(fps), len(speed) - 1)]),
        "hem_speed_end": float(speed[-1]),
        "hem_still_amplitude_mm": 1000.0 * float(amplitude),
    }


def _solver(args) -> dict:
    """The simulator settings the study varies (the rest are the project's; the substeps and the
    cloth's viscosity only where given, so that earlier members keep their files)."""
    given = {"substeps": args.substeps, "cloth_viscosity": args.cloth_viscosity}
    return {"air_drag": args.air_drag, "iterations": args.iterations} | {
        k: v for k, v in given.items() if v is not None
    }


def _fabric_row(args, fabric: str, files: list[Path], motion: Motion, garment) -> dict:
    members = [np.load(f) for f in files if f.exists()]
    if len(members) < 2:
        return {"fabric": fabric, "members": len(members)}
    verts = np.stack([m["vertices"] for m in members]).astype(np.float64)
    hem = garment.groups["hem"]
    stop = int(round(args.seconds * motion.fps))
    moving = motion.slice(0, stop)
    edges = garment.edges()
    settles = [settle_time(v[:, hem], stop - 1, motion.fps, args.still) for v in verts]
    return {
        "fabric": fabric,
        "members": len(members),
        "attempts": int(max(int(m["attempts"]) for m in members)),
        "strain_p99": float(
            np.percentile(
                np.concatenate([edge_strain(v, garment.vertices, edges).ravel() for v in verts]), 99
            )
        ),
        "hem_swing_cm": 100.0 * float(np.mean([hem_swing(v[:stop], moving, hem) for v in verts])),
        "settle_s": None if any(s is None for s in settles) else float(np.mean(settles)),
        **_after_the_stop(verts[:, :, hem], stop - 1, motion.fps),
        "floor_mm": mean_pairwise_mm(verts[:, :stop]),
        "hem_height_m": float(verts[:, -1][:, hem, 1].mean()),
    }


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--clip", required=True, help="a real clip (BVH, glTF, npz)")
    p.add_argument("--garment", default="dress")
    p.add_argument("--seconds", type=float, default=6.0, help="of the clip, before the body stops")
    p.add_argument("--hold", type=float, default=3.0, help="seconds the body then stands")
    p.add_argument("--members", type=int, default=4)
    p.add_argument("--fabrics", nargs="+", default=list(FABRICS), choices=list(FABRICS))
    p.add_argument("--still", type=float, default=0.02, help="hem speed (m/s) counted as settled")
    p.add_argument("--air-drag", type=float, default=1.2, help="the air's drag coefficient (0: none)")
    p.add_argument("--iterations", type=int, default=SimSettings.iterations, help="solver iterations")
    p.add_argument("--substeps", type=int, default=None, help="solver substeps a frame (the project's)")
    p.add_argument(
        "--cloth-viscosity", type=float, default=None, help="the cloth's internal friction, m^2/s (none)"
    )
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--work", type=Path, default=Path("hrr_work/studies/materials"))
    p.add_argument(
        "-o", "--output", type=Path, default=None, help="JSON of the rows (default WORK/summary.json)"
    )
    args = p.parse_args(argv)
    args.work.mkdir(parents=True, exist_ok=True)
    files = {f: [_member_path(args.work, args, f, k) for k in range(args.members)] for f in args.fabrics}
    todo = [(f, k) for f in args.fabrics for k in range(args.members) if not files[f][k].exists()]
    failures = {}
    with ProcessPoolExecutor(args.jobs) as pool:
        jobs = [
            pool.submit(
                _simulate,
                args.garment,
                args.clip,
                args.seconds,
                args.hold,
                f,
                k,
                str(files[f][k]),
                _solver(args),
            )
            for f, k in todo
        ]
        for job in tqdm(as_completed(jobs), total=len(jobs), desc="members", unit="sim"):
            fabric, k, failure = job.result()
            if failure:
                failures[f"{fabric}-{k}"] = failure
    motion = stopping(load_motion(args.clip), args.seconds, args.hold)
    garment = make_garment(args.garment)
    rows = [_fabric_row(args, f, files[f], motion, garment) for f in args.fabrics]
    default = next((r.get("hem_height_m") for r in rows if r["fabric"] == "default"), None)
    for r in rows:  # how far below the default cloth's hem each one hangs
        r["drop_cm"] = (
            None if default is None or "hem_height_m" not in r else 100.0 * (default - r["hem_height_m"])
        )
    out = args.output or args.work / "summary.json"
    record = {"clip": args.clip, "solver": _solver(args), "rows": rows, "failures": failures}
    atomic_write_text(out, json.dumps(record, indent=1))
    head = ("fabric", "density kg/m^2", "bend N m", "strain p99", "hem swing cm", "settle s")
    tail = ("hem m/s 1 s / 3 s after", "still moving mm", "floor mm", "hem below default cm")
    print("| " + " | ".join((*head, *tail)) + " |")
    print("|---" * (len(head) + len(tail)) + "|")
    for r in rows:
        m = FABRICS[r["fabric"]]
        if "floor_mm" not in r:
            blanks = " |" * 6
            print(f"| {r['fabric']} | {m.density:.3f} | {m.bend:.2g} | ({r['members']} members) |{blanks}")
            continue
        settle = "> hold" if r["settle_s"] is None else f"{r['settle_s']:.2f}"
        drop = "" if r["drop_cm"] is None else f"{r['drop_cm']:.1f}"
        print(
            f"| {r['fabric']} | {m.density:.3f} | {m.bend:.2g} | {r['strain_p99']:.3f} | "
            f"{r['hem_swing_cm']:.1f} | {settle} | {r['hem_speed_1s']:.2f} / {r['hem_speed_end']:.2f} | "
            f"{r['hem_still_amplitude_mm']:.0f} | {r['floor_mm']:.1f} | {drop} |"
        )
    for name, why in failures.items():
        print(f"{name}: {why}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
