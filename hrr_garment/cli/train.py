"""hrr-train: train a garment model, stage by stage, into one bundle directory.

    hrr-train --garment dress                        # quick preset: simulate if needed, then every stage
    hrr-train --garment dress --preset tiny          # a small model in a few minutes (smoke runs)
    hrr-train --garment dress --stage autoencoder --minutes 10
    hrr-train --dataset my.h5 -o hrr_work/models/my
    hrr-train --garment dress --stage codespace     # one stage

Stages, in order: ``simulate`` (only when the dataset does not exist; as hrr-simulate would),
``autoencoder`` (the FCMAE mesh autoencoder, then every frame encoded to latents), ``codespace``
(motion and garment encoders sharing a Gumbel-Softmax code space, the retrieval database, tau
calibration, the bundle); ``direct`` (only when named: the direct-regression baseline that
``hrr-eval`` compares against, mode ``direct``). Each stage resumes from its checkpoint when re-run and is
skipped when its outputs are current. The bundle lands in hrr_work/models/GARMENT-PRESET/, where
``hrr-animate --garment GARMENT`` finds it.

Settings: configs/train.yaml, then the preset's ``train:`` section, then ``--config FILE`` (same
shape), then flags. The stage ``codebook`` and a config section ``codebook:`` are the old names of
``codespace``: still accepted, with a deprecation message.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

from ..artifacts.typed_manifest import read_manifest
from ..errors import InputError
from ..io_utils import require_writable_place
from ..paths import workspace
from ..pipeline.train import NAMED_STAGES, OLD_STAGE_NAMES, STAGES, TrainCallback, TrainSettings, train_model
from ..sim.preset import load_preset
from ..train.report import StageReport
from ._common import run_cli


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hrr-train", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--garment", default=None, help="garment name: uses hrr_work/datasets/GARMENT-PRESET.h5")
    p.add_argument("--preset", default="quick", help="dataset and training preset (default quick)")
    p.add_argument("--dataset", type=Path, default=None, help="dataset .h5 (instead of --garment/--preset)")
    p.add_argument(
        "--stage",
        choices=(*STAGES, *NAMED_STAGES, "all", *OLD_STAGE_NAMES),
        default="all",
        help="one stage; 'direct' trains the direct-regression baseline for hrr-eval (mode direct), "
        "'sampler' the generative decoder (mode sample); "
        + ", ".join(f"'{old}': deprecated name of '{new}'" for old, new in OLD_STAGE_NAMES.items()),
    )
    p.add_argument(
        "--config", type=Path, default=None, help="YAML overriding configs/train.yaml (same sections)"
    )
    p.add_argument(
        "--minutes",
        type=float,
        default=None,
        help="wall-clock cap on the autoencoder stage (its budget is epochs; a run the cap cuts short warns)",
    )
    p.add_argument(
        "--validation",
        choices=("clips", "windows"),
        default=None,
        help="the code space's validation: the dataset's held-out clips (default) or, as the paper did, "
        "a random tenth of the training clips' windows (docs/evaluation.md, the paper protocol)",
    )
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    p.add_argument(
        "--device",
        default=None,
        help="torch device for the autoencoder stage, e.g. cuda (default cpu; other stages run on the CPU)",
    )
    p.add_argument(
        "-o",
        "--output",
        type=Path,
        default=None,
        help="model folder (default hrr_work/models/GARMENT-PRESET)",
    )
    p.add_argument("--quiet", action="store_true")
    return p


class _Printer(TrainCallback):
    """hrr-train's report of each stage, as it ends."""

    def on_message(self, text: str) -> None:
        print(f"hrr-train: {text}", file=sys.stderr if text.startswith("deprecated") else sys.stdout)

    def on_warning(self, text: str) -> None:
        print(f"hrr-train: warning: {text}", file=sys.stderr)

    def on_stage_end(self, stage: str, result) -> None:
        if stage == "simulate" and result is not None:
            from .build_summary import print_build_report

            print_build_report(result.report, result.mesh)
        elif stage == "autoencoder":
            _print_autoencoder(result)
        elif stage == "codespace":
            _print_codespace(result)
        elif stage == "auto":
            from ..eval.auto_criterion import describe_auto

            print(describe_auto(result))
        elif stage == "subspace":
            m = result.metrics
            print(
                f"subspace (fast decoder): {m['components']} components, {_epochs(result)}; validation "
                f"per-vertex error {m['validation_mm']:.2f} mm (full decoder {m['full_validation_mm']:.2f} "
                "mm; by size: " + ", ".join(f"{k} {v:.2f}" for k, v in m["candidates_mm"].items()) + ")"
            )
        elif stage == "direct":
            print(
                f"direct (the direct-regression baseline): {_epochs(result)}; validation per-vertex error "
                f"{result.metrics['validation_mm']:.2f} mm"
            )
        elif stage == "sampler":
            m = result.metrics
            print(
                f"sampler (the generative decoder): {_epochs(result)}; a seeded draw of the validation "
                f"clips {m['validation_mm']:.2f} mm from their one simulation (the regression's "
                f"{m['regression_validation_mm']:.2f} mm; a sample is judged against an ensemble: hrr-eval)"
            )


def _overrides(args) -> dict:
    """The flags that override the training config's values, in its sections' shape."""
    ae = {
        k: v
        for k, v in (("max_minutes", args.minutes), ("threads", args.threads), ("device", args.device))
        if v is not None
    }
    cs = {"validation": args.validation} if args.validation is not None else {}
    return {"autoencoder": {"train": ae}, "codespace": {"train": cs}}


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    printer = _Printer()
    if args.stage in OLD_STAGE_NAMES:
        printer.on_message(f"deprecated: --stage {args.stage} is now --stage {OLD_STAGE_NAMES[args.stage]}")
        args.stage = OLD_STAGE_NAMES[args.stage]
    preset = load_preset(args.preset)
    if args.dataset is None:
        if args.garment is None:
            raise InputError("hrr-train", "give --garment NAME (with --preset) or --dataset FILE")
        args.dataset = workspace() / "datasets" / f"{args.garment}-{preset.name}.h5"
    folder = args.output or workspace() / "models" / args.dataset.stem
    require_writable_place(folder)
    settings = TrainSettings.load(preset, args.config, _overrides(args), printer)
    if args.threads:
        import torch

        torch.set_num_threads(args.threads)
    result = train_model(
        args.dataset,
        folder,
        settings,
        stages=STAGES if args.stage == "all" else (args.stage,),
        garment=args.garment,
        preset=preset,
        progress=not args.quiet,
        callback=printer,
    )
    print(f"bundle: {folder}")
    if (Path(folder) / "bundle.json").is_file():  # not before the code-space stage wrote it
        print(f"motion licence: {read_manifest(folder).licences.statement}")
    print("time per stage: " + ", ".join(f"{k} {v / 60:.1f} min" for k, v in result.seconds.items()))
    for check in result.budgets.values():
        print(f"budget: {check.summary()}")
    return 0


def _epochs(r: StageReport) -> str:
    return f"{r.epochs} epochs (best {r.best_epoch}) in {r.minutes:.1f} min{' (reused)' if r.reused else ''}"


def _print_autoencoder(r: StageReport) -> None:
    m = r.metrics
    print(
        f"autoencoder: {_epochs(r)}; per-vertex error val {m['val_pve_mm']:.2f} mm, test "
        f"{m['test_pve_mm']:.2f} mm, train {m['train_pve_mm']:.2f} mm; latent {m['latent_shape'][0]} x "
        f"{m['latent_shape'][1]} (levels {' > '.join(str(s) for s in m['sizes'])})"
    )


def _print_codespace(report: StageReport) -> None:
    r = report.metrics
    v = r["validation_mm"]
    folder = report.folder.parent
    size = sum(p.stat().st_size for p in folder.glob("*.safetensors")) / 1e6
    print(
        f"code space: {report.epochs} epochs (curriculum switch at "
        f"{r['training']['switched_at']}){' (reused)' if report.reused else ''}; code agreement "
        f"{r['code_agreement']:.2f} (chance {r['chance_agreement']:.2f}); database {r['windows']['train']} "
        f"windows, {r['database_codes']['distinct_codes']} distinct codes, "
        f"{r['database_codes']['dead_classes']} of {r['database_codes']['classes']} classes dead, perplexity "
        f"{r['database_codes']['perplexity']:.2f}"
    )
    print(
        f"validation per-vertex error (window level): hybrid {v['hybrid']:.2f} mm, regression-only "
        f"{v['regression']:.2f} mm, retrieval-only {v['retrieval']:.2f} mm (autoencoder floor "
        f"{v['autoencoder']:.2f} mm); gate {r.get('gate', 'entropy')} < tau {r['tau']:.3f}, retrieval usage "
        f"{100 * v['retrieval_usage']:.0f} %"
    )
    if "gates" in r:  # reports from before the match gates have only the entropy's
        print(
            "gates calibrated on validation: "
            + "; ".join(
                f"{g} < {c['tau']:.3f}: {c['validation_mm']:.2f} mm, "
                f"{100 * c['retrieval_usage']:.0f} % retrieval"
                for g, c in r["gates"].items()
            )
        )
    if r.get("residual"):  # the residual mode's weight (reports before it, or databases without motion: none)
        print(
            f"residual mode: weight {r['residual']['weight']:g}, {r['residual']['validation_mm']:.2f} mm ("
            + ", ".join(f"{w}: {e:.2f}" for w, e in r["residual"]["errors_mm"].items())
            + ")"
        )
    print(f"bundle files: {size:.1f} MB")


def main(argv: Sequence[str] | None = None) -> int:
    """``hrr-train``; returns the exit status."""
    return run_cli(_main, argv, "hrr-train")


if __name__ == "__main__":
    sys.exit(main())
