"""hrr-eval: compare a model's modes on held-out sequences against simulated ground truth.

    hrr-eval --garment dress                              # workspace model, its dataset's test split
    hrr-eval --model hrr_work/models/dress-full --split test --tau-sweep 0,0.2,0.4,0.6,0.8,1.0 \\
             --motions ../shared/data/mocap/cmu/*.bvh -o hrr_work/eval/dress-full
    hrr-eval --garment dress --split train --exclude-own-sequence --modes retrieval,naive-nn

Writes REPORT_DIR/report.json (schema: docs/evaluation.md), report.md and PNG plots (error over time
per mode, entropy histogram with tau, tau curve). Each evaluated sequence of a simulated dataset is
also simulated ``--ensemble K`` more times with tiny perturbations (cached under the workspace):
report.md leads with every mode's error relative to that ensemble's spread (PVE / floor) and its
plausibility relative to the truths (needs the ``sim`` extra; ``--ensemble 0`` skips it). ``--motions`` simulates the ground truth of real
motion files with the dataset's simulator settings (cached under the workspace; needs the ``sim``
extra) and evaluates on them as well. ``--library N`` (default 8) plays N of the model's training clips
again as a game would, re-timed, entered part-way and blended into each other, simulates their
ground truth and reports them as the library protocol, with its own tau sweep and goals. Modes: hybrid, regression, retrieval, naive-nn, and direct
when the model has the direct-regression baseline (``hrr-train --stage direct``).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..artifacts.gate_signals import GATE_SIGNALS
from ..artifacts.manifest_section import thawed
from ..errors import InputError
from ..eval.evaluate import EvaluationSettings, evaluate_modes, tau_sweep
from ..eval.terminal import report_lines
from ..inference.modes import Mode
from ..paths import workspace
from ._common import (
    add_decoder_option,
    add_detail_options,
    add_fps_option,
    add_push_option,
    detail_look,
    run_cli,
    run_settings_of,
)

ALL_MODES = tuple(m.value for m in Mode)


def _floats(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from None
    if not values or any(v < 0 or not math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"taus must be finite and >= 0, got {text!r}")
    return sorted(set(values))


def _modes(text: str) -> list[str]:
    modes = [m.strip() for m in text.split(",") if m.strip()]
    unknown = [m for m in modes if m not in ALL_MODES]
    if unknown or not modes:
        raise argparse.ArgumentTypeError(f"unknown mode(s) {unknown}; choose from {', '.join(ALL_MODES)}")
    return modes


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-eval", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "--garment", default=None, help="the workspace model of this garment (full if present, else quick)"
    )
    p.add_argument("--model", type=Path, default=None, help="model bundle directory (instead of --garment)")
    p.add_argument(
        "--dataset", type=Path, default=None, help="dataset .h5 (default: the one the model was trained on)"
    )
    p.add_argument("--split", default="test", choices=("train", "val", "test"))
    p.add_argument(
        "--sequences",
        type=int,
        default=None,
        metavar="N",
        help="evaluate N sequences of the split, evenly spaced in name order (default: all)",
    )
    p.add_argument(
        "--modes",
        type=_modes,
        default=None,
        help="comma-separated (default: hybrid,regression,retrieval,residual,detail,naive-nn; residual where calibrated, detail where the model has folds, direct where trained)",
    )
    p.add_argument(
        "--gate",
        default=None,
        choices=GATE_SIGNALS,
        help="the hybrid's gate signal: motion-code entropy (the paper's), the match's code similarity or "
        "its motion distance (default: the model's calibrated choice); the sweeps run on it",
    )
    p.add_argument(
        "--tau", type=float, default=None, help="the gate's threshold (default: the one calibrated for it)"
    )
    add_detail_options(p)
    p.add_argument(
        "--exclude-own-sequence",
        action="store_true",
        help="keep each sequence's own windows out of retrieval (matters for --split train)",
    )
    p.add_argument(
        "--tau-sweep",
        type=_floats,
        default=None,
        help="comma-separated taus (default: 0, the gate signal's deciles and above its maximum)",
    )
    p.add_argument("--no-sweep", action="store_true", help="skip the tau sweep")
    p.add_argument("--motions", nargs="+", default=None, help="real motion files to simulate and evaluate on")
    p.add_argument(
        "--library",
        type=int,
        default=8,
        metavar="N",
        help="library protocol: N plays of the model's training clips re-timed, entered part-way and "
        "blended into each other, simulated and evaluated (default 8; 0: skip)",
    )
    p.add_argument("--library-seed", type=int, default=0, help="seed of the library plays (default 0)")
    p.add_argument(
        "--unseen-body",
        action="append",
        default=None,
        metavar="DATASET[=SPECIALIST]",
        help="the unseen-bodies protocol (repeat per body): the test clips of a dataset simulated on one body "
        "the model never saw (hrr-simulate --body), against their own truth ensembles, beside the "
        "specialist model trained on that dataset alone (docs/evaluation.md)",
    )
    p.add_argument(
        "--paper",
        type=Path,
        default=None,
        metavar="DIR",
        help="the paper protocol: a model of the same dataset trained with hrr-train --validation windows, "
        "evaluated on the same sequences, its ratios beside the paper's",
    )
    add_fps_option(p)
    p.add_argument(
        "--ensemble",
        type=int,
        default=4,
        metavar="K",
        help="perturbed simulations per sequence for the ensemble ground truth (default 4; 0: none)",
    )
    p.add_argument(
        "--jobs", type=int, default=None, help="processes simulating the ensemble (default: one per core)"
    )
    p.add_argument(
        "--no-push-out",
        "--no-collision",  # its old name, still read
        dest="no_push_out",
        action="store_true",
        help="evaluate without the collision push-out",
    )
    p.add_argument(
        "--causal",
        action="store_true",
        help="run every mode causally, as a stream or a crowd does (no future frames): what a game shows",
    )
    add_decoder_option(p)
    add_push_option(p)
    p.add_argument("--no-plots", action="store_true")
    p.add_argument(
        "-o", "--output", type=Path, default=None, help="report folder (default: hrr_work/eval/MODEL)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    return p


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..eval.plots import write_plots
    from ..eval.report import write_report

    t0 = time.perf_counter()
    job = _job(args)
    report = _evaluate(job, args)
    out = args.output or workspace() / "eval" / job.model_dir.name
    plots = (
        []
        if args.no_plots
        else write_plots(
            Path(out), job.results, job.sweep, tau=report["settings"]["tau"], gate=report["settings"]["gate"]
        )
    )
    report["seconds"] = time.perf_counter() - t0
    json_path, md_path = write_report(out, report, plots)
    print("\n".join(report_lines(report)))
    print(
        f"wrote {json_path}, {md_path}"
        + (f" and {len(plots)} plots" if plots else "")
        + f" in {report['seconds']:.0f} s"
    )
    return 0


@dataclass
class _Job:
    """One hrr-eval run: the model, its dataset's records and the settings, all checked before any work."""

    model_dir: Path
    animator: object
    ds: object
    names: list[str]
    records: list
    settings: EvaluationSettings
    results: dict | None = None
    sweep: list | None = None


def _job(args) -> _Job:
    """The model, the dataset's records and the evaluation settings, each checked (before minutes of work)."""
    import numpy as np

    from ..data.dataset import DatasetError, GarmentDataset
    from ..inference.animator import Animator, find_model

    if (args.garment is None) == (args.model is None):
        raise InputError("hrr-eval", "give exactly one of --garment NAME or --model DIR")
    for f in args.motions or []:  # before minutes of evaluation, not after them
        if not Path(f).is_file():
            raise InputError(
                f,
                "no such motion file"
                + (
                    " (a pattern the shell did not expand: leave it unquoted)"
                    if any(c in f for c in "*?[")
                    else ""
                ),
            )
    model_dir = find_model(args.model or args.garment)
    animator = Animator.load(model_dir)
    bundle = animator.bundle
    dataset = args.dataset or Path(bundle.manifest.dataset or "")
    if not str(dataset) or not dataset.is_file():
        raise InputError(
            model_dir, f"its training dataset {str(dataset) or '(unrecorded)'} is not there; give --dataset"
        )
    ds = GarmentDataset(dataset)
    if ds.garment != bundle.garment or ds.template.num_vertices != bundle.template.num_vertices:
        raise DatasetError(
            dataset,
            f"is a {ds.garment} dataset with {ds.template.num_vertices} vertices; the model in "
            f"{model_dir} is for {bundle.garment} with {bundle.template.num_vertices}",
        )
    names = ds.splits.get(args.split, [])
    if not names:
        raise DatasetError(dataset, f"has no {args.split!r} sequences")
    if args.sequences is not None:
        if args.sequences < 1:
            raise InputError("hrr-eval", f"--sequences must be at least 1, got {args.sequences}")
        names = [
            names[i]
            for i in sorted(
                {int(round(i)) for i in np.linspace(0, len(names) - 1, min(args.sequences, len(names)))}
            )
        ]
    modes = args.modes or [m for m in ALL_MODES if m != Mode.AUTO and animator.supports(m)]
    if Mode.AUTO not in modes:  # the default output leads every protocol, held to its bars (eval/bars.py)
        modes = [Mode.AUTO.value, *modes]
    if Mode.DIRECT in modes and not animator.has_direct:
        raise InputError(
            model_dir, "has no direct-regression baseline: train it with hrr-train --stage direct"
        )
    look = detail_look(args)
    if look.chosen and Mode.DETAIL not in modes:
        raise InputError(
            "hrr-eval", "--detail-strength and --detail-base set the detail mode, which --modes leaves out"
        )
    if args.library < 0:
        raise InputError("hrr-eval", f"--library takes 0 (none) or a number of plays, got {args.library}")
    if args.ensemble == 1 or args.ensemble < 0:
        raise InputError("hrr-eval", f"--ensemble takes 0 (none) or at least 2 members, got {args.ensemble}")
    run = run_settings_of(args, "hrr-eval", push_out=not args.no_push_out, detail=look, causal=args.causal)
    settings = EvaluationSettings(
        tuple(modes),
        run,
        exclude_own_sequence=args.exclude_own_sequence,
        members=args.ensemble,
        jobs=args.jobs,
        progress=not args.quiet,
    )
    for mode in modes:  # each mode's settings against the model (a residual without its calibration...), now
        animator.resolve(settings.run_for(mode))
    return _Job(model_dir, animator, ds, names, [ds.sequence(n) for n in names], settings)


def _evaluate(job: _Job, args) -> dict:
    """Every protocol asked for, into report.json's dictionary."""
    from ..eval.evaluate import evaluate_vertices
    from ..eval.holdouts import holdout_of
    from ..eval.protocols import (
        LibraryPlays,
        default_taus,
        ensemble_summary,
        library_section,
        paper_section,
        real_motion_section,
        truth_ensembles_of,
    )
    from ..eval.report import DATASET_SIMULATION, build_report

    animator, records, settings = job.animator, job.records, job.settings
    bundle = animator.bundle
    ensembles = truth_ensembles_of(
        job.ds, records, settings.members, jobs=settings.jobs, progress=settings.progress
    )
    print(
        f"evaluating {job.model_dir} on {len(records)} {args.split} sequences of {job.ds.path} "
        f"({sum(len(r.garment) for r in records)} frames): {', '.join(settings.modes)}"
    )
    job.results = evaluate_modes(animator, records, settings, ensembles=ensembles)
    # the dataset's own frames scored as a prediction: a member like the others, or not (mirrored
    # clips were not: docs/dataset.md)
    reference = (
        evaluate_vertices(
            DATASET_SIMULATION,
            {r.name: r.garment for r in records},
            records,
            template=bundle.template,
            ensembles=ensembles,
        ).to_dict()
        if ensembles
        else None
    )
    if not args.no_sweep:
        job.sweep = tau_sweep(
            animator,
            records,
            args.tau_sweep or default_taus(animator, records, settings.run),
            settings=settings,
        )
    real = (
        real_motion_section(animator, job.ds, args.motions, settings=settings, source_fps=args.fps)
        if args.motions
        else None
    )
    paper = (
        paper_section(args.paper, bundle, records, settings=settings, ensembles=ensembles)
        if args.paper
        else None
    )
    unseen = None
    if args.unseen_body:
        from ..eval.unseen_bodies import UnseenBody, unseen_bodies_section

        unseen = unseen_bodies_section(
            animator, [UnseenBody.parse(t) for t in args.unseen_body], settings, sequences=args.sequences
        )
    library = None
    if args.library:
        plays = LibraryPlays(args.library, args.library_seed, args.tau_sweep, sweep=not args.no_sweep)
        library = library_section(animator, job.ds, plays, settings=settings)
    return build_report(
        model={
            "folder": str(job.model_dir),
            "garment": bundle.garment,
            "hash": bundle.content_hash,
            "gate": bundle.gate,
            "tau": bundle.tau,
            "gates": thawed(bundle.manifest.gates),
            "auto": bundle.auto_mode,
            "auto_calibration": thawed(bundle.manifest.auto),
            "vertices": bundle.template.num_vertices,
            "preset": bundle.manifest.preset,
        },
        dataset={
            "path": str(job.ds.path),
            "split": args.split,
            "sequences": job.names,
            "frames": int(sum(len(r.garment) for r in records)),
            "holdouts": holdout_of(job.ds.info, job.ds.splits, job.names) if args.split != "train" else None,
        },
        settings=evaluation_record(animator, settings),
        ensemble=ensemble_summary(ensembles, records, settings.members),
        modes=job.results,
        sweep=job.sweep,
        protocols={
            "real_motion": real,
            "library": library,
            "paper": paper,
            "unseen_bodies": unseen,
            "dataset_simulation": reference,
        },
        seconds=0.0,
    )


def evaluation_record(animator, settings: EvaluationSettings) -> dict:
    """report.json's ``settings``: the modes, the hybrid's resolved run (gate, tau, push-out) and,
    where the detail mode runs, its resolved look, as out.h5 records them."""
    record = {
        k: v for k, v in animator.resolve(settings.run_for(Mode.HYBRID)).record().items() if k != "mode"
    }
    if Mode.DETAIL in settings.modes:
        detail = animator.resolve(settings.run_for(Mode.DETAIL)).record()
        record.update(detail_base=detail["detail_base"], detail_strength=detail["detail_strength"])
    return {"modes": list(settings.modes), "exclude_own_sequence": settings.exclude_own_sequence, **record}


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-eval``; returns the exit status."""
    return run_cli(_main, argv, "hrr-eval")


if __name__ == "__main__":
    sys.exit(main())
