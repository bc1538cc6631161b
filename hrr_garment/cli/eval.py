"""hrr-eval: compare a model's modes on held-out sequences against simulated ground truth.

    hrr-eval --garment dress                              # workspace model, its dataset's test split
    hrr-eval --model hrr_work/models/dress-full --split test --tau-sweep 0,0.2,0.4,0.6,0.8,1.0 \\
             --motions ../shared/data/mocap/cmu/*.bvh -o hrr_work/eval/dress-full
    hrr-eval --garment dress --split train --exclude-own-sequence --modes retrieval,naive-nn

Writes REPORT_DIR/report.json (schema: docs/evaluation.md), report.md and PNG plots (error over time
per mode, entropy histogram with tau, tau curve). Each evaluated sequence of a simulated dataset is
also simulated ``--ensemble K`` more times with tiny perturbations (cached under the workspace):
report.md leads with every mode's error relative to that ensemble's spread (PVE / floor) and its
plausibility relative to the truths (needs the ``sim`` extra; ``--ensemble 0`` skips it). ``--motions``
simulates the ground truth of real motion files with the dataset's simulator settings (cached under the
workspace; needs the ``sim`` extra) and evaluates on them as well. ``--library N`` (default 8) plays N of the
model's training clips again as a game would, re-timed, entered part-way and blended into each other,
simulates their ground truth and reports them as the library protocol, with its own tau sweep and goals.
Modes: hybrid, regression, retrieval, naive-nn, and direct when the model has the direct-regression baseline
(``hrr-train --stage direct``).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Sequence

from ..artifacts.gate_signals import GATE_SIGNALS
from ..eval.terminal import report_lines
from ..io_utils import require_writable_place
from ..paths import workspace
from ._common import (
    add_decoder_option,
    add_detail_options,
    add_fps_option,
    add_no_push_out_option,
    add_push_option,
    add_sample_options,
    run_cli,
)
from .eval_job import ALL_MODES, checked_job
from .eval_run import run_protocols


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
        help="comma-separated (default: hybrid,regression,retrieval,residual,detail,naive-nn; residual where "
        "calibrated, detail where the model has folds, direct where trained)",
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
        help="the unseen-bodies protocol (repeat per body): the test clips of a dataset simulated on one "
        "body the model never saw (hrr-simulate --body), against their own truth ensembles, beside the "
        "specialist model trained on that dataset alone (docs/evaluation.md)",
    )
    p.add_argument(
        "--unseen-material",
        action="append",
        default=None,
        metavar="DATASET[=SPECIALIST]",
        help="the unseen-materials protocol (repeat per cloth): the test clips of a dataset simulated in "
        "one cloth the model never trained in (hrr-simulate --material), against their own truth "
        "ensembles, beside the specialist model trained in that cloth alone (docs/evaluation.md)",
    )
    p.add_argument(
        "--other-source",
        action="append",
        default=None,
        metavar="DATASET[=MODEL]",
        help="the cross-source protocol (repeat per dataset): the test clips of a dataset of motion from "
        "another source than the model's (another lab and rig), against their own truth ensembles, "
        "beside the model trained on that dataset; pooled and per clip (docs/evaluation.md)",
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
    add_no_push_out_option(p, help="evaluate without the collision push-out")
    p.add_argument(
        "--causal",
        action="store_true",
        help="run every mode causally, as a stream or a crowd does (no future frames): what a game shows",
    )
    add_decoder_option(p)
    add_push_option(p)
    add_sample_options(p)
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
    job = checked_job(args)
    out = args.output or workspace() / "eval" / job.model_dir.name
    require_writable_place(out)  # before the protocols' minutes, not after them
    report = run_protocols(job, args)
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


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-eval``; returns the exit status."""
    return run_cli(_main, argv, "hrr-eval")


if __name__ == "__main__":
    sys.exit(main())
