"""hrr-eval's summary on the terminal: the lines it prints from a report (report.json's content)."""

from __future__ import annotations

import math

from .bars import summary_line


def report_lines(report: dict) -> list[str]:
    """The report's summary as hrr-eval prints it: the default output's bars, each mode's errors and
    cloth inside the body the viewer sees (before -> after the push-out; then the capsules'), each
    hold-out, the goals, and the paper and library protocols where they ran."""
    out = [line for line in [summary_line(report.get("default"))] if line]
    for mode, entry in report["modes"].items():
        m = entry["metrics"]
        e = entry.get("ensemble") or {}
        floor = (
            f"  PVE/floor {e['pve_floor_ratio']:.2f} (floor {e['floor_mm']:.1f} mm)"
            if "pve_floor_ratio" in e
            else ""
        )
        out.append(
            f"  {mode:10s} PVE {m['pve_mm']:7.2f} mm  RMSE {m['rmse_mm']:7.2f} mm  STED {m['sted']:.4f}  "
            f"CD {m['chamfer_cm']:.3f} cm  {_inside_seen(m)}  in capsules {m['penetration_pct']:.2f} %  "
            f"retrieval {100 * m['retrieval_usage']:.0f} %" + floor
        )
    for kind, by_mode in ((report.get("holdouts") or {}).get("by_holdout") or {}).items():
        out.append(
            f"  {kind} hold-out: "
            + "; ".join(
                f"{mode} PVE/floor {row['pve_floor_ratio']:.2f} over {row['sequences']} clips (worst "
                f"{row['worst']['sequence']} {row['worst']['pve_floor_ratio']:.2f})"
                for mode, row in by_mode.items()
            )
        )
    out += _goal_lines(report["goals"])
    paper = report.get("paper")
    if paper:
        out.append(f"paper protocol ({paper['model']}, tau {paper['tau']:.3f}):")
        for name, g in paper["goals"].items():
            low, high = paper["paper_ratios"].get(name, (None, None))
            beside = f" (paper {low:.2f}-{high:.2f})" if low is not None else ""
            out.append(f"  {name}: {g['ratio']:.3f}{beside}")
    library = report.get("library")
    if library:
        out.append(f"library protocol ({len(library['sequences'])} plays):")
        out += [line for line in [summary_line(library.get("default"))] if line]
        for mode, entry in library["modes"].items():
            e = entry.get("ensemble") or {}
            floor = f"  PVE/floor {e['pve_floor_ratio']:.2f}" if "pve_floor_ratio" in e else ""
            out.append(
                f"  {mode:10s} PVE {entry['metrics']['pve_mm']:7.2f} mm  retrieval "
                f"{100 * entry['metrics']['retrieval_usage']:.0f} %" + floor
            )
        out += _goal_lines(library["goals"])
    return out


def _inside_seen(m: dict) -> str:
    """The cloth inside the body the viewer sees, before -> after the push-out (worst frame), or why not."""
    if "inside_visible_pct" not in m:  # a report older than the figure
        return ""
    before, after, worst = (
        m.get(k) for k in ("inside_visible_before_pct", "inside_visible_pct", "inside_visible_worst_pct")
    )
    if after is None or not math.isfinite(after):
        return "inside seen: unknown (no visible mesh)"
    return f"inside seen {before:.2f} -> {after:.2f} % (worst {worst:.2f} %)"


def _goal_lines(goals: dict) -> list[str]:
    out = []
    for name, g in goals.items():
        if "ratio" in g:
            status = "" if g["met"] is None else (" met" if g["met"] else " NOT met")
            out.append(
                f"  {name}: {g['ratio']:.3f}" + (f" (target <= {g['target']}){status}" if g["target"] else "")
            )
        else:
            out.append(f"  tau optimum at {g['best_tau']:.3f}: {'interior' if g['met'] else 'NOT interior'}")
    return out
