"""The test split taken apart by what each clip holds out (issue 50): a dataset split by style
holds out whole styles of contents the model has trained on; one that also holds out contents
(a preset's ``also_hold_out``) tests motion the model has never seen a take of. A pooled PVE / floor
hides the difference, so report.json and report.md give each hold-out's pooled ratio, its worst
clip, and every clip's ratio.

A test clip belongs to the first ``also_hold_out`` field whose group of it has no member in the
training split (the content it shows was never trained on), else to the dataset's ``split_by``
field when its name has one (a held-out style), else to ``clip`` (a procedural or unnamed clip
held out on its own). Mirrored copies belong with their source.
"""

from __future__ import annotations

from ..data.splits import mirror_source
from .ensemble_metrics import ensemble_ratios
from .mode_results import combine

ONE_CLIP = "clip"  # the hold-out of clips held out on their own (no group field in their name)


def holdout_of(info: dict, splits: dict[str, list[str]], names: list[str]) -> dict[str, str]:
    """Test sequence ``names`` -> the hold-out each belongs to (module docstring), from a dataset's
    ``info`` (its ``split_by``, ``groups`` and ``also_hold_out``) and its ``splits``."""
    trained = {mirror_source(n) for n in splits.get("train", [])}
    also = info.get("also_hold_out") or {}
    unseen = {}
    for field, held in also.items():  # the groups of this field that never train
        groups = held.get("groups", {})
        seen = {groups[n] for n in trained if n in groups}
        unseen[field] = {n for n, g in groups.items() if g not in seen}
    primary, groups = info.get("split_by"), info.get("groups") or {}
    out = {}
    for name in names:
        source = mirror_source(name)
        field = next((f for f in also if source in unseen[f]), None)
        if field is None:
            group = groups.get(source, source)
            field = primary if primary and group.startswith(f"{primary}=") else ONE_CLIP
        out[name] = field
    return out


def holdout_section(modes: dict, holdouts: dict[str, str]) -> dict | None:
    """report.json's ``holdouts``: per hold-out and mode (report.json mode entries ``modes``) the
    pooled ensemble ratios, the clip count and frames, and the worst clip by PVE / floor; and each
    clip's hold-out and PVE / floor per mode. None without truth ensembles or with one hold-out."""
    order = ("style", "content", "source")  # the split's own hold-out first, the clips alone last
    kinds = sorted(
        set(holdouts.values()), key=lambda k: (k == ONE_CLIP, order.index(k) if k in order else len(order), k)
    )
    if len(kinds) < 2:
        return None
    summary: dict[str, dict] = {}
    clips: dict[str, dict] = {n: {"holdout": h} for n, h in holdouts.items()}
    for mode, entry in modes.items():
        sequences = entry.get("sequences", {})
        for kind in kinds:
            rows = [(n, s) for n, s in sequences.items() if holdouts.get(n) == kind and s.get("ensemble")]
            if not rows:
                continue
            combined = combine([s["ensemble"] for _, s in rows], [s["frames"] for _, s in rows])
            worst = max(rows, key=lambda r: r[1]["ensemble"]["pve_floor_ratio"])
            summary.setdefault(kind, {})[mode] = {
                **ensemble_ratios(combined),
                "sequences": len(rows),
                "frames": int(sum(s["frames"] for _, s in rows)),
                "worst": {"sequence": worst[0], "pve_floor_ratio": worst[1]["ensemble"]["pve_floor_ratio"]},
            }
            for n, s in rows:
                clips[n][mode] = s["ensemble"]["pve_floor_ratio"]
    if not summary:
        return None
    return {"by_holdout": summary, "sequences": clips}


def markdown_holdouts(section: dict | None, field_label: dict[str, str] | None = None) -> list[str]:
    """report.md's hold-out tables: each hold-out's pooled PVE / floor, its ratio to the held-out
    styles' (the split's own hold-out), the worst clip, then every clip."""
    if not section:
        return []
    labels = {
        "style": "held-out styles",
        "content": "held-out contents",
        "source": "held-out sources",
        ONE_CLIP: "clips held out alone",
        **(field_label or {}),
    }
    summary = section["by_holdout"]
    modes = sorted({m for kind in summary.values() for m in kind}, key=lambda m: (m != "auto", m))
    lines = [
        "## Hold-outs (the test split by what each clip holds out)",
        "",
        "| hold-out | mode | clips | frames | PVE / floor | x the held-out styles' "
        "| worst clip (PVE / floor) |",
        "|---|---|---:|---:|---:|---:|---|",
    ]
    for kind, by_mode in summary.items():
        for mode in modes:
            row = by_mode.get(mode)
            if row is None:
                continue
            base = summary.get("style", {}).get(mode, {}).get("pve_floor_ratio")
            against = f"{row['pve_floor_ratio'] / base:.3f}" if base else "n/a"
            lines.append(
                f"| {labels.get(kind, kind)} | {mode} | {row['sequences']} | {row['frames']} | "
                f"{row['pve_floor_ratio']:.2f} | {against} | {row['worst']['sequence']} "
                f"({row['worst']['pve_floor_ratio']:.2f}) |"
            )
    lines += [
        "",
        "| clip | hold-out | " + " | ".join(f"{m} PVE / floor" for m in modes) + " |",
        "|---|---|" + "---:|" * len(modes),
    ]
    for name, clip in sorted(section["sequences"].items(), key=lambda kv: (kv[1]["holdout"], kv[0])):
        cells = " | ".join("n/a" if m not in clip else f"{clip[m]:.2f}" for m in modes)
        lines.append(f"| {name} | {labels.get(clip['holdout'], clip['holdout'])} | {cells} |")
    return [*lines, ""]


def markdown_cloths(section: dict | None) -> list[str]:
    """report.md's table of the test split by cloth (a :func:`holdout_section` grouped by each
    clip's cloth): each cloth's pooled PVE / floor against its own clips' floor, its sharpness and
    hem swing over the truth's, and its worst clip."""
    if not section:
        return []
    summary = section["by_holdout"]
    modes = sorted({m for cloth in summary.values() for m in cloth}, key=lambda m: (m != "auto", m))
    lines = [
        "## By cloth (each against its own clips' truth ensembles)",
        "",
        "| cloth | mode | clips | frames | PVE / floor | sharpness | hem swing | worst clip (PVE / floor) |",
        "|---|---|---:|---:|---:|---:|---:|---|",
    ]
    for cloth, by_mode in summary.items():
        for mode in modes:
            row = by_mode.get(mode)
            if row is None:
                continue
            cells = [
                f"{row[k]:.2f}" if k in row else "n/a" for k in ("bending_energy_ratio", "hem_swing_ratio")
            ]
            lines.append(
                f"| {cloth} | {mode} | {row['sequences']} | {row['frames']} | {row['pve_floor_ratio']:.2f} | "
                f"{' | '.join(cells)} | {row['worst']['sequence']} ({row['worst']['pve_floor_ratio']:.2f}) |"
            )
    return [*lines, ""]
