"""hrr-eval's protocols: every one the options ask for (the held-out split, its tau sweep, real
motions, the paper's, unseen bodies, other motion sources, the library), run on the checked job
into report.json's dictionary."""

from __future__ import annotations

from ..artifacts.manifest_section import thawed
from ..eval.evaluate import EvaluationSettings, evaluate_modes, tau_sweep
from ..inference.modes import Mode
from .eval_job import EvalJob


def run_protocols(job: EvalJob, args) -> dict:
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
        from ..eval.unseen_bodies import DatasetAndModel, unseen_bodies_section

        unseen = unseen_bodies_section(
            animator, [DatasetAndModel.parse(t) for t in args.unseen_body], settings, sequences=args.sequences
        )
    cloths = None
    if args.unseen_material:
        from ..eval.unseen_bodies import DatasetAndModel, unseen_bodies_section

        items = [DatasetAndModel.parse(t) for t in args.unseen_material]
        cloths = unseen_bodies_section(animator, items, settings, sequences=args.sequences, kind="cloth")
    cross = None
    if args.other_source:
        from ..eval.cross_source import captured_ratio, cross_source_section, with_own_split
        from ..eval.unseen_bodies import DatasetAndModel

        auto = job.results.get(Mode.AUTO.value)
        own = captured_ratio(auto, records) if auto is not None and args.split == "test" else None
        items = [DatasetAndModel.parse(t) for t in args.other_source]
        cross = with_own_split(cross_source_section(animator, items, settings, sequences=args.sequences), own)
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
            "motion_licence": bundle.manifest.licences.to_dict(),
        },
        dataset={
            "path": str(job.ds.path),
            "split": args.split,
            "sequences": job.names,
            "frames": int(sum(len(r.garment) for r in records)),
            "holdouts": holdout_of(job.ds.info, job.ds.splits, job.names) if args.split != "train" else None,
            "cloths": cloths_of(job.ds, job.names),
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
            "unseen_materials": cloths,
            "cross_source": cross,
            "dataset_simulation": reference,
        },
        seconds=0.0,
    )


def cloths_of(ds, names: list[str]) -> dict[str, str] | None:
    """Each evaluated clip's cloth, where they are in more than one (report.json's ``cloths`` pools
    by it); None otherwise."""
    cloths = {n: ds.material_of(n).name for n in names}
    return cloths if len(set(cloths.values())) > 1 else None


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
