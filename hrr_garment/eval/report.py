"""hrr-eval's outputs: report.json (schema in docs/evaluation.md), report.md (its tables:
:mod:`.report_tables`), and PNG plots.

The comparative goals it reports are :mod:`.goals`'.

report.json's ``format_version`` moves whenever a field arrives or changes meaning. Nothing in the
package reads a report back; the versions, for readers of old reports: 2 truth ensembles
(``ensemble`` per mode and at the top level); 3 ``library`` and ``paper``; 4 the gate signal
(``gate`` beside each ``tau``, the model's calibrated ``gates``); 5 ``sharpness`` in each tau-sweep
point; 6 the model's ``auto`` mode and its ``auto_calibration``; 7 the detail mode's look
(``settings.detail``: strength, base); 8 the library's ``source_simulation`` reference; 9
``settings`` as the run's record writes it (out.h5's attributes: ``gate``, ``tau``, ``push_out``
(``collision`` before), and ``detail_base`` / ``detail_strength`` where the detail mode ran, in place of
``settings.detail``), and ``retrieval_usage`` counts only windows retrieved as simulated (the
residual and detail modes, which add a match's detail to the regression, report 0); 10
``unseen_bodies`` (the unseen-bodies protocol, :mod:`.unseen_bodies`); 11 ``default`` at the top
level and in ``real_motion`` and ``library``: the default output's (auto's) lead row and its bars
(:mod:`.bars`), auto evaluated as a mode of its own; 12 ``holdouts`` and ``dataset.holdouts``
(:mod:`.holdouts`), ``settings.causal`` and the ``dataset_simulation`` reference row; 13 the cloth
inside the body the viewer sees (:mod:`.visible_inside`), the headline plausibility figure:
``inside_visible_before_pct``, ``inside_visible_before_worst_pct``, ``inside_visible_pct`` and
``inside_visible_worst_pct`` in each mode's and sequence's ``metrics`` and ``ensemble`` (null where the
visible body is unknown), ``truth_inside_visible_pct`` and ``truth_inside_visible_worst_pct`` in
``ensemble``, each sequence's ``visible_body`` and each mode's ``visible_bodies`` (and at the top level:
how many sequences were measured against a mesh, the capsules or nothing known); ``penetration_pct``
(the capsules) unchanged; 14 ``push_limited_pct`` in each mode's and sequence's ``metrics`` and
``ensemble``: the frames on which the push-out's strain limit moved an edge (null where no push-out ran);
15 ``cross_source`` (the cross-source protocol, :mod:`.cross_source`) and ``model.motion_licence`` (where
its training motion comes from and whether it may ship: :mod:`hrr_garment.motion.licences`); 16
``unseen_materials`` (the unseen-materials protocol, :mod:`.unseen_bodies` with cloths for bodies),
``cloths`` and ``dataset.cloths`` (the test clips grouped by their cloth, as ``holdouts`` groups them).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..inference.resolved_run import recorded
from ..io_utils import atomic_write_text, strict_json
from .bars import HELD_OUT_BARS, LIBRARY_BARS, default_output, markdown_lead
from .cross_source import markdown_table as cross_source_table
from .evaluate import TauPoint
from .goals import goals
from .holdouts import holdout_section, markdown_cloths, markdown_holdouts
from .mode_results import ModeResult
from .report_tables import ensemble_table, goal_table, mode_table, simulated_section, sweep_table
from .unseen_bodies import markdown_table

DATASET_SIMULATION = "dataset simulation"  # the reference row: the dataset's own frames against the ensemble
REPORT_VERSION = 16  # report.json's "format_version": see the module docstring


def frame_entropies(modes: dict[str, ModeResult]) -> np.ndarray:
    """Per-frame entropies of the first mode that has them (the direct baseline has none)."""
    for result in modes.values():
        h = np.concatenate([s.entropy for s in result.sequences]) if result.sequences else np.zeros(0)
        if len(h) and np.isfinite(h).all():
            return h
    return np.zeros(0)


def entropy_summary(modes: dict[str, ModeResult], bins: int = 20) -> dict:
    """Per-frame motion-code entropy over the evaluated sequences (the same for every mode)."""
    h = frame_entropies(modes)
    counts, edges = np.histogram(h, bins=bins)
    return {
        "mean": float(h.mean()) if len(h) else math.nan,
        "quantiles": {str(q): float(np.quantile(h, q)) for q in (0.05, 0.25, 0.5, 0.75, 0.95)}
        if len(h)
        else {},
        "histogram": {"edges": edges.tolist(), "counts": counts.tolist()},
    }


def build_report(
    *,
    model: dict,
    dataset: dict,
    settings: dict,
    modes: dict[str, ModeResult],
    sweep: list[TauPoint] | None,
    seconds: float,
    ensemble: dict | None = None,
    protocols: dict | None = None,
) -> dict:
    """The report.json contents (schema: docs/evaluation.md); ``protocols``: the sections of the
    protocols beyond the split that ran (``real_motion``, ``library``, ``paper``, ``unseen_bodies``;
    None where not); ``dataset["holdouts"]``, where given: each sequence's hold-out
    (:func:`~.holdouts.holdout_of`), which the ``holdouts`` section pools by."""
    protocols = dict(protocols or {})
    for name, bars in (("real_motion", HELD_OUT_BARS), ("library", LIBRARY_BARS)):
        if protocols.get(name):
            protocols[name] = {**protocols[name], "default": default_output(protocols[name]["modes"], bars)}
    entries = {m: r.to_dict() for m, r in modes.items()}
    return {
        "format_version": REPORT_VERSION,
        "model": model,
        "dataset": dataset,
        "settings": settings,
        "ensemble": ensemble or {"members": 0},
        "default": default_output(entries, HELD_OUT_BARS),
        "modes": entries,
        # what "inside seen" was measured against, the same for every mode (:mod:`.visible_inside`)
        "visible_bodies": next(iter(entries.values()))["visible_bodies"] if entries else {},
        "goals": goals(modes, sweep),
        "tau_sweep": [vars(p) for p in sweep] if sweep else [],
        "entropy": entropy_summary(modes),
        "holdouts": holdout_section(entries, dataset["holdouts"]) if dataset.get("holdouts") else None,
        # the clips grouped by their cloth where they are in several (a model across cloths)
        "cloths": holdout_section(entries, dataset["cloths"]) if dataset.get("cloths") else None,
        "real_motion": protocols.get("real_motion"),
        "library": protocols.get("library"),
        "paper": protocols.get("paper"),
        "unseen_bodies": protocols.get("unseen_bodies"),
        "unseen_materials": protocols.get("unseen_materials"),
        "cross_source": protocols.get("cross_source"),
        "dataset_simulation": protocols.get("dataset_simulation"),
        "seconds": seconds,
    }


def _unseen_tables(report: dict) -> list[str]:
    """report.md's tables of the unseen-bodies and unseen-materials protocols, where they ran."""
    out = []
    unseen = report.get("unseen_bodies")
    if unseen:
        out += [
            "",
            "## Unseen bodies (each beside a specialist trained on it alone)",
            "",
            "The default mode (auto) of this model and of each body's specialist on the test clips of a "
            "dataset simulated on that body, against its own truth ensembles; penetration against that "
            "body's capsules, before the push-out; sharpness and hem swing over the truth's.",
            "",
            *markdown_table(unseen),
        ]
    cloths = report.get("unseen_materials")
    if cloths:
        out += [
            "",
            "## Unseen cloths (each beside a specialist trained in it alone)",
            "",
            "The default mode (auto) of this model, animating each clip in the dataset's cloth, and of "
            "each cloth's specialist on the test clips of a dataset simulated in that cloth, against its "
            "own truth ensembles; sharpness and hem swing over the truth's.",
            "",
            *markdown_table(cloths, kind="cloth"),
        ]
    return out


def _detail_clause(settings: dict) -> str:
    """ "; detail mode: folds x0.8 on the regression" where the detail mode ran; "; causal (as
    streamed)" where the modes ran causally."""
    causal = "; causal (as streamed: no future frames)" if settings.get("causal") else ""
    if "detail_strength" not in settings:
        return causal
    return f"; detail mode: folds x{settings['detail_strength']:g} on the {settings['detail_base']}" + causal


def markdown(report: dict, plots: list[str]) -> str:
    """report.md: the report's tables, with the plots."""
    model, data, settings = report["model"], report["dataset"], report["settings"]
    out = [
        f"# Evaluation: {model['garment']} ({Path(model['folder']).name})",
        "",
        f"Model `{model['folder']}` (hash {model['hash']}, calibrated gate {model.get('gate', 'entropy')} < "
        f"{model['tau']:.3f}; the default mode, auto, runs {model.get('auto', 'hybrid')}); dataset "
        f"`{data['path']}`, split **{data['split']}**: {len(data['sequences'])} sequences, {data['frames']} "
        f"frames. Collision push-out {'on' if recorded(settings, 'push_out') else 'off'}; own sequence "
        f"excluded from retrieval: {'yes' if settings['exclude_own_sequence'] else 'no'}; hybrid gate "
        f"{settings['gate']} < "
        f"{settings['tau']:.3f}" + _detail_clause(settings) + ". "
        f"Run time {report['seconds']:.0f} s.",
        "",
        *(
            [f"Motion licence: {model['motion_licence']['statement']}", ""]
            if model.get("motion_licence")
            else []
        ),
    ]
    runs = model.get("auto", "hybrid")
    out += markdown_lead(report.get("default"), runs)
    reference = report.get("dataset_simulation")
    lead = ensemble_table(
        {**report["modes"], **({DATASET_SIMULATION: reference} if reference else {})},
        report.get("ensemble", {}),
    )
    if lead:
        out += ["## Against the simulator's own chaos (ensemble ground truth)", "", *lead, ""]
        if reference:
            out += [
                f"*{DATASET_SIMULATION}*: the dataset's own frames of each clip (what the model trained or "
                "was validated on) scored as a prediction: about 1 x the floor where they are a simulation "
                "like the members.",
                "",
            ]
    out += markdown_holdouts(report.get("holdouts"))
    out += markdown_cloths(report.get("cloths"))
    out += ["## Modes (against the dataset's single simulation)", ""]
    out += mode_table(report["modes"])
    out += ["", "## Goals (the paper's shape; PVE ratios)", "", *goal_table(report["goals"])]
    if report["tau_sweep"]:
        out += [
            "",
            f"## Tau sweep (hybrid, gate {settings.get('gate', 'entropy')})",
            "",
            *sweep_table(report["tau_sweep"]),
        ]
    e = report["entropy"]
    if e["quantiles"]:
        q = e["quantiles"]
        out += [
            "",
            f"Motion-code entropy per frame (nats): mean {e['mean']:.3f}, median {q['0.5']:.3f}, "
            f"5-95 % {q['0.05']:.3f} .. {q['0.95']:.3f}.",
        ]
    real = report.get("real_motion")
    if real:
        out += [
            "",
            f"## Real motion ({', '.join(real['files'])})",
            "",
            *markdown_lead(real.get("default"), runs),
            *simulated_section(real),
        ]
    paper = report.get("paper")
    if paper:
        out += [
            "",
            "## Paper protocol (code space validated on a tenth of its training clips' windows)",
            "",
            f"Model `{paper['model']}` (hash {paper['hash']}, calibrated gate {paper.get('gate', 'entropy')} "
            f"< {paper['tau']:.3f}) on the same sequences. The paper reserved 3-5 test clips and split the "
            "rest 9:1 into training and validation (by window): tau is calibrated on windows of the "
            "training clips.",
            "",
        ]
        lead = ensemble_table(paper["modes"], report.get("ensemble", {}))
        out += [*lead, ""] if lead else []
        out += mode_table(paper["modes"])
        out += ["", "| PVE ratio | ours | the paper |", "|---|---:|---:|"]
        for name, g in paper["goals"].items():
            if "ratio" in g:
                low, high = paper["paper_ratios"].get(name, (None, None))
                out.append(
                    f"| {name.replace('_', ' ')} | {g['ratio']:.3f} | "
                    + ("" if low is None else f"{low:.2f}-{high:.2f}")
                    + " |"
                )
    library = report.get("library")
    if library:
        out += [
            "",
            "## Library protocol (the training clips played again)",
            "",
            "Clips of the model's database re-timed by 0.9-1.1, entered part-way and cross-faded into each "
            f"other over 0.3-0.5 s (seed {library['seed']}), as a game's animation system plays its library:",
            "",
        ]
        out += [f"- `{name}`: {description}" for name, description in library["plays"].items()]
        out += [
            "",
            *markdown_lead(library.get("default"), runs),
            *simulated_section(library),
            "",
            "Goals on this protocol:",
            "",
            *goal_table(library["goals"]),
        ]
        if library["tau_sweep"]:
            out += ["", *sweep_table(library["tau_sweep"])]
    out += _unseen_tables(report)
    cross = report.get("cross_source")
    if cross:
        out += [
            "",
            "## Other motion sources (each beside the model trained on it)",
            "",
            "The default mode (auto) of this model and of the reference on the test clips of a dataset "
            "whose motion comes from another source, against their own truth ensembles (clips the model "
            "trained on left out); over own split: this model's PVE / floor over its own test split's.",
            "",
            *cross_source_table(cross),
        ]
    if plots:
        out += ["", "## Plots", ""] + [f"![{Path(p).stem}]({Path(p).name})" for p in plots]
    out += ["", "Metric definitions: docs/evaluation.md."]
    return "\n".join(out) + "\n"


def write_report(folder: str | Path, report: dict, plots: list[str]) -> tuple[Path, Path]:
    """Write report.json and report.md into ``folder``; returns their paths."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write_text(folder / "report.json", strict_json(report, indent=1))
    atomic_write_text(folder / "report.md", markdown(report, plots))
    return folder / "report.json", folder / "report.md"
