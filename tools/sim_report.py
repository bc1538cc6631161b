"""Simulation quality of a built dataset, per motion content: what hrr-simulate kept and rejected.

For every simulated sequence of the dataset (mirrored copies left out: they repeat their source)
it recomputes, from the stored frames and motions, edge strain and penetration, and flags frames
where the motion's own limbs pass through the body (hrr_garment.body.self_contact), each sequence
on the body it was simulated on (the mannequin, or the dataset's bodies), and adds a table per body
when the dataset has bodies. Rows group
sequences by content: the ``content`` field of the preset's file-name pattern (Bandai-Namco:
walk, run, bow, ...), the procedural kind, or the file's name. Prints a Markdown table and, with
--json, one JSON object.

    python tools/sim_report.py hrr_work/datasets/dress-real-quick.h5
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from hrr_garment.body.self_contact import self_intersecting_frames
from hrr_garment.data.dataset import GarmentDataset
from hrr_garment.sim.quality import body_signed_distance, edge_strain, penetration_fraction
from hrr_garment.sim.sources import DEFAULT_NAME_PATTERN


def content_of(name: str, info: dict) -> str:
    if info.get("kind", "file") != "file":
        return info["kind"]
    stem = Path(info.get("path", name)).stem
    match = re.fullmatch(DEFAULT_NAME_PATTERN, stem)
    return match.group("content") if match else stem


def _empty_row() -> dict:
    return {
        "clips": 0,
        "rejected": 0,
        "frames": 0,
        "strain": [],
        "pen_max": 0.0,
        "pen_max_clean": 0.0,
        "flagged": 0,
    }


def report(path: Path) -> dict:
    ds = GarmentDataset(path)
    edges = ds.template.edges()
    rows: dict[str, dict] = {}
    by_body: dict[str, dict] = {}
    for name in ds.names:
        rec = ds.sequence(name)
        if "mirror_of" in rec.info:
            continue
        row = rows.setdefault(content_of(name, rec.info), _empty_row())
        body = ds.bodies[rec.body_name].body  # the body it was simulated on, with the garment's rest on it
        strain = edge_strain(rec.garment, ds.rest(name), edges)
        pen = penetration_fraction(body_signed_distance(rec.garment, rec.motion, body))
        flagged = self_intersecting_frames(rec.motion, body)
        per_body = by_body.setdefault(
            rec.body_name,
            {
                "clips": 0,
                "frames": 0,
                "flagged": 0,
                "strain": [],
                "stature_m": ds.bodies[rec.body_name].record.stature,
            },
        )
        per_body["clips"] += 1
        per_body["frames"] += len(rec.garment)
        per_body["flagged"] += int(flagged.sum())
        per_body["strain"].append(strain.ravel())
        row["clips"] += 1
        row["frames"] += len(rec.garment)
        row["strain"].append(strain.ravel())
        row["pen_max"] = max(row["pen_max"], float(pen.max()))
        row["pen_max_clean"] = max(
            row["pen_max_clean"], float(pen[~flagged].max()) if (~flagged).any() else 0.0
        )
        row["flagged"] += int(flagged.sum())
    for name in ds.info.get("summary", {}).get("rejects", {}):
        rows.setdefault(content_of(name, {"path": name}), _empty_row())["rejected"] += 1
    table = {}
    pooled = []
    for content, row in sorted(rows.items()):
        strain = np.concatenate(row.pop("strain")) if row["strain"] else np.zeros(1)
        pooled.append(strain)
        table[content] = {
            **row,
            "strain_p99": float(np.percentile(strain, 99)),
            "strain_max": float(strain.max()),
        }
    pooled_strain = np.concatenate(pooled)
    total = {k: sum(r[k] for r in table.values()) for k in ("clips", "rejected", "frames", "flagged")}
    total.update(
        strain_p99=float(np.percentile(pooled_strain, 99)),
        strain_max=float(pooled_strain.max()),
        pen_max=max(r["pen_max"] for r in table.values()),
        pen_max_clean=max(r["pen_max_clean"] for r in table.values()),
        kept_fraction=total["clips"] / max(1, total["clips"] + total["rejected"]),
        flagged_fraction=total["flagged"] / max(1, total["frames"]),
    )
    bodies = {
        name: {
            **{k: v for k, v in row.items() if k != "strain"},
            "strain_p99": float(np.percentile(np.concatenate(row["strain"]), 99)),
        }
        for name, row in sorted(by_body.items())
    }
    return {
        "dataset": str(path),
        "vertices": ds.template.num_vertices,
        "by_content": table,
        "total": total,
        "by_body": bodies,
    }


def markdown(result: dict) -> str:
    lines = [
        "| content | clips | rejected | frames | strain p99 | strain max | worst-frame penetration | "
        "outside flagged frames | flagged frames |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for content, r in [*result["by_content"].items(), ("**all**", result["total"])]:
        lines.append(
            f"| {content} | {r['clips']} | {r['rejected']} | {r['frames']} | {r['strain_p99']:.3f} | "
            f"{r['strain_max']:.2f} | {100 * r['pen_max']:.2f} % | {100 * r['pen_max_clean']:.2f} % | "
            f"{r['flagged']} |"
        )
    if len(result["by_body"]) > 1 or set(result["by_body"]) != {"mannequin"}:
        lines += [
            "",
            "| body | stature | clips | frames | strain p99 | flagged frames |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        lines += [
            f"| {name} | {r['stature_m']:.2f} m | {r['clips']} | {r['frames']} | {r['strain_p99']:.3f} | "
            f"{100 * r['flagged'] / max(1, r['frames']):.1f} % |"
            for name, r in result["by_body"].items()
        ]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("dataset", type=Path)
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    args = parser.parse_args()
    result = report(args.dataset)
    print(json.dumps(result, indent=1) if args.json else markdown(result))
    if not args.json:
        t = result["total"]
        print(
            f"\n{result['dataset']}: {result['vertices']} vertices; {100 * t['kept_fraction']:.1f} % of "
            f"clips kept; {100 * t['flagged_fraction']:.1f} % of frames flagged (a limb more than 2.5 cm in "
            "the body)"
        )


if __name__ == "__main__":
    main()
