"""hrr-eval's job: the model, its dataset's records and the evaluation settings, each checked
against the options before minutes of work."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..eval.evaluate import EvaluationSettings
from ..inference.modes import Mode
from ._common import detail_look, run_settings_of

ALL_MODES = tuple(m.value for m in Mode)


@dataclass
class EvalJob:
    """One hrr-eval run: the model, its dataset's records and the settings, all checked before any work."""

    model_dir: Path
    animator: object
    ds: object
    names: list[str]
    records: list
    settings: EvaluationSettings
    results: dict | None = None
    sweep: list | None = None


def checked_job(args) -> EvalJob:
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
    return EvalJob(model_dir, animator, ds, names, [ds.sequence(n) for n in names], settings)
