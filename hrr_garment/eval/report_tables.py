"""report.md's tables: the modes' metrics, the modes against the truth ensemble, the goals, the tau
sweep, and a protocol section whose ground truth hrr-eval simulated (:func:`~.report.markdown`
assembles them). Plausibility leads with the cloth inside the body the viewer sees
(:mod:`.visible_inside`), before and after the push-out; the capsules' figure follows it."""

from __future__ import annotations

import math

from .bars import cell
from .library import SOURCE_SIMULATION
from .visible_inside import CAPSULES, MESH, UNKNOWN

TABLE_METRICS = (
    ("pve_mm", "PVE mm", 2),
    ("rmse_mm", "RMSE mm", 2),
    ("sted", "STED", 4),
    ("chamfer_cm", "CD cm", 3),
    ("inside_visible_before_pct", "inside seen before push-out %", 2),
    ("inside_visible_pct", "inside seen %", 2),
    ("inside_visible_worst_pct", "worst frame %", 2),
    ("penetration_pct", "in capsules %", 2),
    ("push_limited_pct", "strain limit moved %", 1),
    ("curvature_error_cm", "E_curv cm", 1),
    ("strain_p99", "strain p99", 3),
    ("stretch_energy_ratio", "stretch E ratio", 2),
    ("bending_energy_ratio", "bend E ratio", 2),
    ("jitter_mm", "jitter mm", 2),
    ("retrieval_usage", "retrieval", 3),
)
ENSEMBLE_METRICS = (
    ("pve_floor_ratio", "PVE / floor", 2),
    ("pve_members_mm", "PVE to members mm", 2),
    ("pve_ensemble_mean_mm", "PVE to mean mm", 2),
    ("energy_score_mm", "energy score mm", 2),
    ("inside_visible_before_pct", "inside seen before push-out %", 2),
    ("inside_visible_before_worst_pct", "worst frame %", 2),
    ("inside_visible_pct", "inside seen after %", 2),
    ("penetration_before_worst_pct", "capsules before push-out, worst frame %", 2),
    ("push_limited_pct", "strain limit moved %", 1),
    ("strain_p99", "strain p99", 3),
    ("strain_max", "strain max", 2),
    ("jitter_ratio", "jitter ratio", 2),
    ("acceleration_ratio", "accel. ratio", 2),
    ("bending_energy_ratio", "sharpness (bend E ratio)", 2),
    ("hem_swing_ratio", "hem swing ratio", 2),
    ("draw_spread_ratio", "draws apart / floor", 2),
)


SEEN = {k for k, _, _ in (*TABLE_METRICS, *ENSEMBLE_METRICS) if k.startswith("inside_visible")}


def seen_cell(row: dict, key: str, digits: int) -> str:
    """``row[key]`` as a table's cell: "unknown" for a figure inside the visible body that is there but
    not a number (that body unknown), n/a for any other missing value (a report older than the figure)."""
    value = row.get(key)
    missing = value is None or (isinstance(value, float) and not math.isfinite(value))
    return "unknown" if key in SEEN and key in row and missing else cell(value, digits)


def visible_note(modes: dict) -> list[str]:
    """The sentence under a table saying what "inside seen" was measured against, from the modes'
    ``visible_bodies`` (the same for every mode); none for a report written before them."""
    kinds = next((e.get("visible_bodies") for e in modes.values() if e.get("visible_bodies")), None)
    if not kinds:
        return []
    said = {
        MESH: "the body's skinned mesh, posed by linear blend skinning",
        CAPSULES: "its capsules, which are the visible body of a body with no mesh of its own (the "
        "mannequin): there the figure is the capsule figure",
        UNKNOWN: "unknown: a character fitted to a mesh that its body.json does not carry, or anny not "
        "installed; see the capsule column instead",
    }
    parts = [f"{said[k]} ({n} clip{'s' if n > 1 else ''})" for k, n in kinds.items() if k in said]
    return [
        "",
        "*inside seen*: garment vertices more than 5 mm inside the body the viewer sees, by the winding "
        "number, every frame (mean over frames; worst frame), measured against " + "; ".join(parts) + ". "
        "*in capsules*: inside the capsules the push-out works against, at any depth.",
    ]


def mode_table(modes: dict) -> list[str]:
    """One row of :data:`TABLE_METRICS` per mode, and what "inside seen" was measured against."""
    lines = [
        "| mode | " + " | ".join(label for _, label, _ in TABLE_METRICS) + " |",
        "|---|" + "---:|" * len(TABLE_METRICS),
    ]
    for mode, entry in modes.items():
        m = entry["metrics"]
        lines.append(f"| {mode} | " + " | ".join(seen_cell(m, k, d) for k, _, d in TABLE_METRICS) + " |")
    return lines + visible_note(modes)


def ensemble_table(modes: dict, ensemble: dict) -> list[str]:
    """One row per mode against the truth ensemble, the truths' own values in the last row."""
    rows = {
        mode: {
            **entry["ensemble"],
            "strain_p99": entry["metrics"]["strain_p99"],
            "strain_max": entry["metrics"]["strain_max"],
        }
        for mode, entry in modes.items()
        if entry.get("ensemble")
    }
    if not rows:
        return []
    any_row = next(iter(rows.values()))
    truth = {
        "pve_floor_ratio": 1.0,
        "pve_members_mm": any_row["floor_mm"],
        "penetration_before_worst_pct": any_row.get("truth_penetration_worst_pct"),
        "strain_p99": any_row.get("truth_strain_p99"),
        "strain_max": any_row.get("truth_strain_max"),
        **{k: 1.0 for k, _, _ in ENSEMBLE_METRICS if k.endswith("_ratio")},
    }
    if "truth_inside_visible_pct" in any_row:  # a simulation has no push-out: before and after alike
        truth["inside_visible_before_pct"] = truth["inside_visible_pct"] = any_row["truth_inside_visible_pct"]
        truth["inside_visible_before_worst_pct"] = any_row["truth_inside_visible_worst_pct"]
    lines = [
        f"Against {ensemble['members']} perturbed simulations of each of {ensemble['sequences']} sequences "
        f"({', '.join(ensemble['perturbations'])}); floor = mean PVE between two of them, "
        f"{any_row['floor_mm']:.2f} mm. PVE / floor is 1 for a prediction as good as a fresh simulation and "
        "about 0.71 for the perfect mean; ratios are the prediction's value over the truths'.",
        "",
        "| mode | " + " | ".join(label for _, label, _ in ENSEMBLE_METRICS) + " |",
        "|---|" + "---:|" * len(ENSEMBLE_METRICS),
    ]
    for mode, m in [*rows.items(), ("simulation (truths)", truth)]:
        lines.append(f"| {mode} | " + " | ".join(seen_cell(m, k, d) for k, _, d in ENSEMBLE_METRICS) + " |")
    return lines + visible_note(modes)


def goal_table(goals: dict) -> list[str]:
    """One row per goal: its ratio, its target and whether it is met."""
    lines = ["| goal | ratio | target | met |", "|---|---:|---:|---|"]
    for name, g in goals.items():
        if name == "interior_tau_optimum":
            lines.append(
                f"| interior tau optimum | best tau {g['best_tau']:.3f} ({g['best_pve_mm']:.2f} mm, "
                f"retrieval {100 * g['retrieval_usage']:.0f} %) | interior | {'yes' if g['met'] else 'no'} |"
            )
        else:
            target = "" if g["target"] is None else f"<= {g['target']}"
            met = "" if g["met"] is None else ("yes" if g["met"] else "no")
            lines.append(f"| {name.replace('_', ' ')} | {g['ratio']:.3f} | {target} | {met} |")
    return lines


def sweep_table(points: list[dict]) -> list[str]:
    """One row per tau of the sweep: PVE, retrieval usage and sharpness."""
    return [
        "| tau | PVE mm | retrieval usage | sharpness (bend E ratio) |",
        "|---:|---:|---:|---:|",
        *[
            f"| {p['tau']:.3f} | {p['pve_mm']:.2f} | {100 * p['retrieval_usage']:.1f} % | "
            f"{p.get('sharpness', math.nan):.2f} |"
            for p in points
        ],
    ]


def simulated_section(section: dict) -> list[str]:
    """A section whose ground truth hrr-eval simulated (real motion, library plays): where, what
    was rejected, the ensemble table and the mode table."""
    out = [
        f"Ground truth simulated with the dataset's settings into `{section['dataset']}`; "
        f"{len(section['sequences'])} sequences, {section['frames']} frames.",
        "",
    ]
    for name, reason in section.get("rejected", {}).items():  # no ground truth: not in the table
        out += [f"- Not evaluated: `{name}`, its simulation was rejected ({reason})."]
    if section.get("rejected"):
        out += [""]
    modes, note = section["modes"], []
    if section.get("source_simulation"):  # the library plays' reference row
        modes = {**modes, SOURCE_SIMULATION: section["source_simulation"]}
        note = [
            "",
            f"*{SOURCE_SIMULATION}*: the dataset's own simulation of the frames each play shows (re-timed "
            "frames interpolated, blends cross-faded), played along: what retrieval gives if it finds the "
            "right clip at the right moment every frame, its ceiling on this protocol.",
        ]
    lead = ensemble_table(modes, section.get("ensemble", {}))
    return out + ([*lead, ""] if lead else []) + mode_table(modes) + note
