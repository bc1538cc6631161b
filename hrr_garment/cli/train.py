"""hrr-train: train a garment model, stage by stage, into one bundle directory.

    hrr-train --garment dress                        # quick preset: simulate if needed, then every stage
    hrr-train --garment dress --preset tiny          # a small model in a few minutes (smoke runs)
    hrr-train --garment dress --stage autoencoder --minutes 10
    hrr-train --dataset my.h5 -o hrr_work/models/my
    hrr-train --garment dress --stage codespace     # one stage

Stages, in order: ``simulate`` (only when the dataset does not exist; as hrr-simulate would),
``autoencoder`` (the FCMAE mesh autoencoder, then every frame encoded to latents), ``codespace``
(motion and garment encoders sharing a Gumbel-Softmax code space, the retrieval database, tau
calibration, the bundle); ``baseline`` (only when named: the direct-regression baseline that
``hrr-eval`` compares against, mode ``direct``). Each stage resumes from its checkpoint when re-run and is skipped when
its outputs are current. The bundle lands in hrr_work/models/GARMENT-PRESET/, where
``hrr-animate --garment GARMENT`` finds it.

Settings: configs/train.yaml, then the preset's ``train:`` section, then ``--config FILE`` (same
shape), then flags. The stage ``codebook`` and a config section ``codebook:`` are the old names of
``codespace``: still accepted, with a deprecation message.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

import yaml

from ..errors import InputError
from ..io_utils import remove_empty_folders
from ..paths import workspace
from ..sim.plan import CONFIG_DIR, load_preset
from ..train.report import StageReport
from ._common import run_cli

STAGES = ("simulate", "autoencoder", "codespace")  # "all"; the baseline stage runs only when asked for
SECTIONS = ("autoencoder", "codespace", "baseline")  # of the training config
OLD_CODESPACE_NAME = "codebook"  # the old name of the stage and of its config section (deprecated)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="hrr-train", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--garment", default=None, help="garment name: uses hrr_work/datasets/GARMENT-PRESET.h5")
    p.add_argument("--preset", default="quick", help="dataset and training preset (default quick)")
    p.add_argument("--dataset", type=Path, default=None, help="dataset .h5 (instead of --garment/--preset)")
    p.add_argument("--stage", choices=(*STAGES, "baseline", "all", OLD_CODESPACE_NAME), default="all",
                   help="one stage; 'baseline' trains the direct-regression baseline for hrr-eval "
                        f"('{OLD_CODESPACE_NAME}': deprecated name of 'codespace')")
    p.add_argument("--config", type=Path, default=None, help="YAML overriding configs/train.yaml (same sections)")
    p.add_argument("--minutes", type=float, default=None, help="wall-clock budget for the autoencoder stage")
    p.add_argument("--validation", choices=("clips", "windows"), default=None,
                   help="the code space's validation: the dataset's held-out clips (default) or, as the paper did, "
                        "a random tenth of the training clips' windows (docs/results.md, the paper protocol)")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    p.add_argument("--device", default=None,
                   help="torch device for the autoencoder stage, e.g. cuda (default cpu; other stages run on the CPU)")
    p.add_argument("-o", "--output", type=Path, default=None, help="model folder (default hrr_work/models/GARMENT-PRESET)")
    p.add_argument("--quiet", action="store_true")
    return p


def _merge(base: dict, override: dict) -> dict:
    out = dict(base)
    for key, value in (override or {}).items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(out.get(key), dict) else value
    return out


def _read_yaml(path: Path) -> dict:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(path, f"cannot read the training config: {exc}") from None
    return _sections(data, path)


def _sections(data, source) -> dict:
    """A training config's sections, checked, the code space's old section name renamed."""
    if isinstance(data, dict) and OLD_CODESPACE_NAME in data:
        _deprecated(f"{source}: the config section '{OLD_CODESPACE_NAME}' is now called 'codespace'")
        if "codespace" in data:
            raise InputError(source, f"has both a '{OLD_CODESPACE_NAME}' and a 'codespace' section; keep 'codespace'")
        data = {("codespace" if k == OLD_CODESPACE_NAME else k): v for k, v in data.items()}
    if not isinstance(data, dict) or set(data) - set(SECTIONS):
        raise InputError(source, "expected a mapping with 'autoencoder', 'codespace' and/or 'baseline' sections "
                                 "(each with model/train)")
    return data


def settings(preset_train: dict, user: Path | None, preset_name: str = "preset") -> dict:
    """The training settings: configs/train.yaml, then the preset's, then the user's file."""
    cfg = _merge(_read_yaml(CONFIG_DIR / "train.yaml"), _sections(preset_train or {}, f"the {preset_name} preset's train section"))
    return _merge(cfg, _read_yaml(user)) if user else cfg


def _deprecated(message: str) -> None:
    print(f"hrr-train: deprecated: {message}", file=sys.stderr)


def _build(factory, values: dict, source) -> object:
    try:
        return factory.from_dict(dict(values or {}))
    except ValueError as exc:
        raise InputError(source, str(exc)) from None


def _simulate(garment: str, preset, out: Path, quiet: bool) -> None:
    from ..export.preview import write_dataset_preview
    from ..garment.templates import make_garment
    from ..sim.build import BuildOptions, build_dataset
    from ..sim.plan import build_options, plan_sequences
    from ..sim.simulator import SimConfig
    from .simulate import print_report

    mesh = make_garment(garment, preset.vertices)
    specs = plan_sequences(preset)
    options = build_options(preset, specs)
    options["info"]["garment_vertices"] = mesh.num_vertices
    report = build_dataset(mesh, specs, SimConfig.from_dict(preset.sim), out=out,
                           options=BuildOptions(progress=not quiet, preview=write_dataset_preview, **options))
    print_report(report, mesh)


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..models.codespace import CodeSpaceConfig
    from ..models.direct import DirectConfig
    from ..models.fcmae import AutoencoderConfig
    from ..train.autoencoder import TrainConfig
    from ..train.baseline import DirectTrainConfig
    from ..train.codespace_training import CodeSpaceTrainConfig

    if args.stage == OLD_CODESPACE_NAME:
        _deprecated(f"--stage {OLD_CODESPACE_NAME} is now --stage codespace")
        args.stage = "codespace"

    preset = load_preset(args.preset)
    if args.dataset is None:
        if args.garment is None:
            raise InputError("hrr-train", "give --garment NAME (with --preset) or --dataset FILE")
        args.dataset = workspace() / "datasets" / f"{args.garment}-{preset.name}.h5"
    folder = args.output or workspace() / "models" / args.dataset.stem
    cfg = settings(preset.train, args.config, preset.name)
    source = args.config or CONFIG_DIR / "train.yaml"
    ae_model = _build(AutoencoderConfig, cfg["autoencoder"].get("model"), source)
    ae_train_values = dict(cfg["autoencoder"].get("train") or {})
    for key, value in (("max_minutes", args.minutes), ("threads", args.threads), ("device", args.device)):
        if value is not None:
            ae_train_values[key] = value
    ae_train = _build(TrainConfig, ae_train_values, source)
    cs_model = _build(CodeSpaceConfig, cfg["codespace"].get("model"), source)
    cs_train_values = dict(cfg["codespace"].get("train") or {})
    if args.validation is not None:
        cs_train_values["validation"] = args.validation
    cs_train = _build(CodeSpaceTrainConfig, cs_train_values, source)
    direct_model = _build(DirectConfig, cfg["baseline"].get("model"), source)
    direct_train = _build(DirectTrainConfig, cfg["baseline"].get("train"), source)
    if args.threads:
        import torch

        torch.set_num_threads(args.threads)

    try:
        return _run_stages(args, preset, folder, (ae_model, ae_train), (cs_model, cs_train), (direct_model, direct_train))
    except BaseException:
        remove_empty_folders(folder)  # what a failed run made and never filled; finished stages stay for resuming
        raise


def _missing_sequences(dataset: Path, preset) -> list[str]:
    """The preset's sequences that an existing dataset of its own clips does not hold: a workspace
    made with an earlier, smaller version of the preset. None where there is no dataset yet, or
    where it holds other clips (``hrr-simulate --motions``, or a different preset): that one is the
    user's choice."""
    if not dataset.exists():
        return []
    from ..data.dataset import GarmentDataset
    from ..sim.plan import plan_sequences

    ds = GarmentDataset(dataset)
    planned = [spec.name for spec in plan_sequences(preset)]
    if ds.info.get("preset") != preset.name or ds.info.get("motions") or not set(ds.names) <= set(planned):
        return []
    return [name for name in planned if name not in set(ds.names)]


def _run_stages(args, preset, folder: Path, autoencoder: tuple, codespace: tuple, baseline: tuple) -> int:
    from ..train.autoencoder import train_autoencoder
    from ..train.baseline import run_baseline_stage
    from ..train.codespace import run_codespace_stage

    (ae_model, ae_train), (cs_model, cs_train), (direct_model, direct_train) = autoencoder, codespace, baseline
    times: dict[str, float] = {}
    stages = STAGES if args.stage == "all" else (args.stage,)
    if args.dataset.exists() and {"autoencoder", "codespace"} & set(stages):
        from ..data.dataset import GarmentDataset
        from ..train.codespace import check_splits

        check_splits(GarmentDataset(args.dataset))  # a dataset the code space cannot use fails before any training
    for stage in stages:
        t0 = time.perf_counter()
        if stage == "simulate":
            missing = _missing_sequences(args.dataset, preset) if args.garment is not None else []
            if args.dataset.exists() and not missing:
                continue
            if args.garment is None:
                raise InputError(args.dataset, "no such dataset")
            if args.dataset.exists():  # the preset grew since this dataset was made: add what it lacks
                print(f"simulate: {args.dataset} lacks {len(missing)} of the {preset.name} preset's sequences "
                      f"(e.g. {missing[0]}); simulating them (its own are reused)")
            else:
                print(f"simulate: no dataset at {args.dataset}; simulating the {preset.name} preset first")
            _simulate(args.garment, preset, args.dataset, args.quiet)
        elif stage == "autoencoder":
            if not args.dataset.exists():
                hint = f"hrr-simulate --garment {args.garment} --preset {preset.name}" if args.garment else "hrr-simulate"
                raise InputError(args.dataset, f"no dataset; make it with: {hint} (or run hrr-train without --stage)")
            r = train_autoencoder(args.dataset, folder / "autoencoder", ae_model, ae_train, cache_dir=workspace() / "cache",
                                  progress=not args.quiet)
            _print_autoencoder(r)
        elif stage == "codespace":
            r = run_codespace_stage(args.dataset, folder, cs_model, cs_train, cache_dir=workspace() / "cache",
                                    progress=not args.quiet, info={"preset": preset.name})
            _print_codespace(r, folder)
            _auto_mode(folder, args.dataset, not args.quiet)
        elif stage == "baseline":
            r = run_baseline_stage(args.dataset, folder, direct_model, direct_train, cache_dir=workspace() / "cache",
                                   progress=not args.quiet)
            print(f"baseline (direct regression): {_epochs(r)}; validation per-vertex error "
                  f"{r.metrics['validation_mm']:.2f} mm")
        times[stage] = time.perf_counter() - t0
    print("time per stage: " + ", ".join(f"{k} {v / 60:.1f} min" for k, v in times.items()))
    return 0


def _auto_mode(folder: Path, dataset: Path, progress: bool) -> None:
    """Calibrate the mode ``auto`` runs (:mod:`hrr_garment.eval.auto_mode`) on the validation clips,
    once per bundle (a model trained before it gets it on its next ``--stage codespace``)."""
    from ..artifacts.bundle import read_meta
    from ..artifacts.bundle_writer import update_bundle_meta
    from ..eval.auto_mode import calibrate_auto_mode, describe_auto

    auto = read_meta(folder).get("auto")  # reading it hashes every file: once
    if auto is None:
        from ..data.dataset import GarmentDataset
        from ..inference.animator import Animator

        ds = GarmentDataset(dataset)
        records = [ds.sequence(n) for n in ds.splits.get("val", [])]
        auto = calibrate_auto_mode(Animator.load(folder), records, progress=progress)
        update_bundle_meta(folder, {"auto": auto})
    print(describe_auto(auto))


def _epochs(r: StageReport) -> str:
    return f"{r.epochs} epochs (best {r.best_epoch}) in {r.minutes:.1f} min{' (reused)' if r.reused else ''}"


def _print_autoencoder(r: StageReport) -> None:
    m = r.metrics
    print(f"autoencoder: {_epochs(r)}; per-vertex error val {m['val_pve_mm']:.2f} mm, test {m['test_pve_mm']:.2f} mm, "
          f"train {m['train_pve_mm']:.2f} mm; latent {m['latent_shape'][0]} x {m['latent_shape'][1]} "
          f"(levels {' > '.join(str(s) for s in m['sizes'])})")


def _print_codespace(report: StageReport, folder: Path) -> None:
    r = report.metrics
    v = r["validation_mm"]
    size = sum(p.stat().st_size for p in folder.glob("*.safetensors")) / 1e6
    print(f"code space: {report.epochs} epochs (curriculum switch at "
          f"{r['training']['switched_at']}){' (reused)' if report.reused else ''}; code agreement {r['code_agreement']:.2f} "
          f"(chance {r['chance_agreement']:.2f}); database {r['windows']['train']} windows, "
          f"{r['database_codes']['distinct_codes']} distinct codes, {r['database_codes']['dead_classes']} of "
          f"{r['database_codes']['classes']} classes dead, perplexity {r['database_codes']['perplexity']:.2f}")
    print(f"validation per-vertex error (window level): hybrid {v['hybrid']:.2f} mm, regression-only "
          f"{v['regression']:.2f} mm, retrieval-only {v['retrieval']:.2f} mm (autoencoder floor {v['autoencoder']:.2f} mm); "
          f"gate {r.get('gate', 'entropy')} < tau {r['tau']:.3f}, retrieval usage {100 * v['retrieval_usage']:.0f} %")
    if "gates" in r:  # reports from before the match gates have only the entropy's
        print("gates calibrated on validation: " + "; ".join(
            f"{g} < {c['tau']:.3f}: {c['validation_mm']:.2f} mm, {100 * c['retrieval_usage']:.0f} % retrieval"
            for g, c in r["gates"].items()))
    if r.get("residual"):  # the residual mode's weight (reports before it, or databases without motion: none)
        print(f"residual mode: weight {r['residual']['weight']:g}, {r['residual']['validation_mm']:.2f} mm ("
              + ", ".join(f"{w}: {e:.2f}" for w, e in r["residual"]["errors_mm"].items()) + ")")
    print(f"bundle: {folder} ({size:.1f} MB)")


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-train``; returns the exit status."""
    return run_cli(_main, argv, "hrr-train")


if __name__ == "__main__":
    sys.exit(main())
