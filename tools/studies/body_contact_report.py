"""Limbs in the body: how many frames of real clips flag self-contact on the mannequin, and on each
performer's body (issue 45's first measure, before any cloth is simulated).

For each clip: the canonical motion on the mannequin's capsules, and the same clip played by its
performer's body (hrr_garment.body.performer.performer_body: the rig's limbs on anny's nearest
shape; motion_on_body) with that body's capsules. A frame is flagged where a limb passes more than
2.5 cm into the body (hrr_garment.body.self_contact, the simulator's own test). Clips whose rigs
measure the same (to the millimetre) share one body: the first such clip's. Prints a Markdown table
per folder and in total; --json one JSON object. Needs the bodies extra.

    python tools/studies/body_contact_report.py hrr_work/mocap/bandai ../shared/data/mocap/cmu
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tqdm import tqdm

from hrr_garment.body.performer import performer_body
from hrr_garment.body.proportions import source_proportions
from hrr_garment.body.retarget import motion_on_body
from hrr_garment.body.self_contact import self_intersecting_frames
from hrr_garment.motion.io import load_motion


def clip_rows(files: list[Path], progress: bool = True) -> list[dict]:
    """One row per clip: its frames, and how many are flagged on the mannequin and on its performer's body."""
    bodies: dict[tuple, object] = {}
    rows = []
    for path in tqdm(files, desc="clips", unit="clip", disable=not progress):
        motion = load_motion(path)
        key = tuple(sorted((k, round(v, 3)) for k, v in source_proportions(path).items()))
        if key not in bodies:
            bodies[key] = performer_body(path)
        performer = bodies[key]
        on_body = motion_on_body(motion, performer.body)
        rows.append(
            {
                "clip": path.name,
                "folder": path.parent.name,
                "frames": motion.num_frames,
                "flagged_mannequin": int(self_intersecting_frames(motion).sum()),
                "flagged_body": int(self_intersecting_frames(on_body, performer.body).sum()),
                "body_stature_m": round(performer.stature, 3),
                "body_rms_mm": round(performer.rms_mm, 1),
            }
        )
    return rows


def summarise(rows: list[dict]) -> dict:
    frames = sum(r["frames"] for r in rows)
    return {
        "clips": len(rows),
        "frames": frames,
        "flagged_mannequin_pct": 100.0 * sum(r["flagged_mannequin"] for r in rows) / max(frames, 1),
        "flagged_body_pct": 100.0 * sum(r["flagged_body"] for r in rows) / max(frames, 1),
        "body_statures_m": sorted({r["body_stature_m"] for r in rows}),
        "body_rms_mm": sorted({r["body_rms_mm"] for r in rows}),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("paths", nargs="+", type=Path, help="BVH / glTF files or folders of them")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    files = sorted(
        f
        for path in args.paths
        for f in ([path] if path.is_file() else [*path.rglob("*.bvh"), *path.rglob("*.glb")])
    )
    rows = clip_rows(files, progress=not args.json)
    groups = {
        folder: summarise([r for r in rows if r["folder"] == folder])
        for folder in sorted({r["folder"] for r in rows})
    }
    total = summarise(rows)
    if args.json:
        print(json.dumps({"folders": groups, "total": total, "clips": rows}))
        return
    print(
        "| folder | clips | frames | flagged, mannequin | flagged, performer body | bodies (stature m) | "
        "measures' RMS mm |"
    )
    print("|---|---:|---:|---:|---:|---|---|")
    for name, g in [*groups.items(), ("total", total)]:
        print(
            f"| {name} | {g['clips']} | {g['frames']} | {g['flagged_mannequin_pct']:.1f} % | "
            f"{g['flagged_body_pct']:.1f} % | {', '.join(f'{s:.2f}' for s in g['body_statures_m'])} | "
            f"{', '.join(f'{s:.1f}' for s in g['body_rms_mm'])} |"
        )


if __name__ == "__main__":
    main()
