"""Capsules or the body the viewer sees as the cloth's collider: which holds penetration, strain and
speed.

For each body (parametric shapes, and fitted characters' body.json files) and real clip, the same
garment (the dress carried onto the body) is simulated twice at the real-quick settings: against
the body's fitted capsules, and against its skinned mesh in pieces that ride with the capsules'
bones and are reshaped every frame (hrr_garment.body.mesh_collider). Both results are measured
against the body the viewer sees, the skinned mesh (the share of cloth vertices inside it, by
winding number, every frame), and against the capsules, with the pooled edge strain p99 and the
solver's seconds per simulated frame. The two runs of a clip follow each other in one worker, in
alternating order, so that the time ratio compares like with like. A clip a collider cannot
simulate is counted as rejected. Needs the sim and bodies extras.

    python tools/studies/collider_study.py hrr_work/mocap/bandai --clips 8 --jobs 2 \
        --characters hero.json
"""

from __future__ import annotations

import argparse
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

SHAPES = {
    "average": {},
    "heavy": {"weight": 0.9, "gender": 0.0},
    "tall-slim": {"height": 0.85, "weight": 0.15, "gender": 1.0},
    "short-muscular": {"height": 0.1, "muscle": 0.9, "weight": 0.6, "gender": 0.0},
}
COLLIDERS = ("capsules", "skinned")
STRAIN_BAR = 1.15  # issue 82's strain p99 bar: the regions' shares count the edges over it


def run_pair(job: tuple[str, dict, str, int, int]) -> list[dict]:
    """Both colliders on one body and clip, in the order ``job[3]`` picks (0: capsules first)."""
    order = COLLIDERS if job[3] % 2 == 0 else COLLIDERS[::-1]
    return [run_one((*job[:3], collider, job[4])) for collider in order]


def run_one(job: tuple[str, dict | str, str, str, int]) -> dict:
    """One body (a parametric shape, or a body.json file such as ``hrr-body fit`` writes) on one clip
    with one collider."""
    from hrr_garment.body.body_file import read_body, record_of
    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.body.mesh_collider import skinned_pieces
    from hrr_garment.body.parametric import BodyShape, parametric_body
    from hrr_garment.body.retarget import motion_on_body
    from hrr_garment.garment.dressing import DressedBody, dress
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.motion.io import load_motion
    from hrr_garment.sim.config import SimSettings
    from hrr_garment.sim.mesh_queries import mesh_signed_distances
    from hrr_garment.sim.preset import load_preset
    from hrr_garment.sim.quality import body_signed_distance, edge_strain, penetration_fraction
    from hrr_garment.sim.simulator import SimulationExploded, simulate_garment

    body_name, source, clip, collider, max_frames = job
    record = read_body(source) if isinstance(source, str) else record_of(parametric_body(BodyShape(**source)))
    dressed: DressedBody = dress(body_name, record, make_garment("dress", 1000), made_for=DEFAULT_BODY)[0]
    body, visible = dressed.body, dressed.visible
    if visible is None:
        raise SystemExit(f"{body_name}: the body has no mesh of its own to compare with its capsules")
    motion = motion_on_body(load_motion(clip), body)
    motion = motion.slice(0, min(motion.num_frames, max_frames))
    config = SimSettings.from_dict(load_preset("real-quick").sim)
    row = {"body": body_name, "clip": Path(clip).stem, "collider": collider, "frames": motion.num_frames}
    t0 = time.perf_counter()
    try:
        result = simulate_garment(
            dressed.garment,
            motion,
            config,
            body=body,
            collider=skinned_pieces(body, visible) if collider == "skinned" else None,
        )
    except SimulationExploded as exc:
        return {**row, "rejected": str(exc)[:200]}
    verts = result.vertices
    posed = visible.pose(motion.global_rotations, motion.joint_positions)
    in_mesh = (mesh_signed_distances(verts, posed, visible.faces) < 0.0).mean(1)
    in_capsules = penetration_fraction(body_signed_distance(verts, motion, body), depth=0.0)
    strain = edge_strain(verts, dressed.garment.vertices, dressed.garment.edges())
    regions = strain_regions(dressed.garment, strain)
    return {
        **row,
        "rejected": None,
        "inside_mesh_mean": float(in_mesh.mean()),
        "inside_mesh_max": float(in_mesh.max()),
        "inside_capsules_mean": float(in_capsules.mean()),
        "strain_p99": float(np.percentile(strain, 99)),
        **regions,
        "seconds_per_frame": result.step_seconds / result.simulated_frames,
        "attempts": result.attempts,
        "wall_s": time.perf_counter() - t0,
    }


def strain_regions(garment, strain: np.ndarray) -> dict:
    """The share of edge-frames over :data:`STRAIN_BAR` in three regions of the garment: the edges
    touching a pinned vertex (the straps), the rest of the top 30 % by rest height (the bodice),
    and the rest (the skirt)."""
    edges, y = garment.edges(), garment.vertices[:, 1]
    pinned = np.zeros(len(y), bool)
    pinned[garment.attached] = True
    pins = pinned[edges].any(1)
    bodice = ~pins & (y[edges].min(1) > np.percentile(y, 70))
    over = strain > STRAIN_BAR
    return {
        f"over_{name}": float(over[:, mask].mean()) if mask.any() else 0.0
        for name, mask in (("pins", pins), ("bodice", bodice), ("skirt", ~pins & ~bodice))
    }


def pick_clips(folder: Path, count: int) -> list[str]:
    """``count`` clips of different contents, spread evenly over the folder's sorted files."""
    files = sorted(folder.rglob("*.bvh"))
    by_content: dict[str, Path] = {}
    for f in files:
        by_content.setdefault(f.stem.split("_")[1] if f.stem.count("_") >= 3 else f.stem, f)
    chosen = list(by_content.values())
    step = max(1, len(chosen) // count)
    return [str(p) for p in chosen[::step][:count]]


def summarise(rows: list[dict]) -> dict:
    out = {}
    for collider in COLLIDERS:
        mine = [r for r in rows if r["collider"] == collider]
        kept = [r for r in mine if not r["rejected"]]
        out[collider] = {
            "runs": len(mine),
            "rejected": len(mine) - len(kept),
            **{
                k: float(np.mean([r[k] for r in kept])) if kept else None
                for k in (
                    "inside_mesh_mean",
                    "inside_mesh_max",
                    "inside_capsules_mean",
                    "strain_p99",
                    "seconds_per_frame",
                    "over_pins",
                    "over_bodice",
                    "over_skirt",
                )
            },
        }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", type=Path, help="a folder of BVH clips (e.g. the unpacked Bandai-Namco library)")
    p.add_argument("--clips", type=int, default=8)
    p.add_argument("--bodies", nargs="*", default=list(SHAPES), choices=list(SHAPES))
    p.add_argument(
        "--characters",
        nargs="*",
        type=Path,
        default=[],
        help="body.json files of fitted characters (hrr-body fit)",
    )
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument(
        "--max-frames", type=int, default=360, help="simulate at most this many frames of each clip (12 s)"
    )
    p.add_argument("--json", type=Path, default=None, help="also write every run's row here")
    args = p.parse_args()
    sources = {**{b: SHAPES[b] for b in args.bodies}, **{c.stem: str(c) for c in args.characters}}
    pairs = [
        (b, source, clip) for b, source in sources.items() for clip in pick_clips(args.folder, args.clips)
    ]
    jobs = [(*pair, k, args.max_frames) for k, pair in enumerate(pairs)]
    from tqdm import tqdm

    with ProcessPoolExecutor(args.jobs) as pool:
        rows = [r for pair in tqdm(pool.map(run_pair, jobs), total=len(jobs), desc="clips") for r in pair]
    summary = summarise(rows)
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))
    print(
        "| collider | runs | rejected | cloth inside the mesh, mean / worst frame | inside the capsules | "
        "strain p99 | solver s/frame |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|")
    for name, s in summary.items():
        if s["inside_mesh_mean"] is None:
            print(f"| {name} | {s['runs']} | {s['rejected']} | - | - | - | - |")
            continue
        print(
            f"| {name} | {s['runs']} | {s['rejected']} | {100 * s['inside_mesh_mean']:.2f} % / "
            f"{100 * s['inside_mesh_max']:.1f} % | {100 * s['inside_capsules_mean']:.2f} % | "
            f"{s['strain_p99']:.3f} | {1000 * s['seconds_per_frame']:.1f} ms |"
        )
    print(f"solver time, skinned / capsules (median over clips both kept): {time_ratio(rows):.2f} x")
    print(f"edge-frames over {STRAIN_BAR} x rest, by region (straps: edges touching a pinned vertex):")
    for name, s in summary.items():
        if s["over_pins"] is not None:
            shares = ", ".join(f"{k} {100 * s[f'over_{k}']:.1f} %" for k in ("pins", "bodice", "skirt"))
            print(f"  {name}: {shares}")


def time_ratio(rows: list[dict]) -> float:
    """The median over body and clip of the skinned collider's solver seconds a frame over the
    capsules' (the two runs of a pair ran back to back in one worker)."""
    pairs: dict[tuple, dict] = {}
    for r in rows:
        if not r["rejected"]:
            pairs.setdefault((r["body"], r["clip"]), {})[r["collider"]] = r["seconds_per_frame"]
    ratios = [p["skinned"] / p["capsules"] for p in pairs.values() if len(p) == 2]
    return float(np.median(ratios)) if ratios else float("nan")


if __name__ == "__main__":
    main()
