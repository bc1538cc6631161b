"""hrr-train: train a garment model from a dataset, stage by stage.

    hrr-train --garment dress                          # every available stage, quick dataset
    hrr-train --garment dress --stage autoencoder --minutes 10
    hrr-train --dataset my.h5 --stage autoencoder -o hrr_work/models/my

Stages run in order; each keeps its outputs in the model folder (default
hrr_work/models/GARMENT-PRESET/) and resumes from its checkpoint when re-run. Available now:
``autoencoder`` (the FCMAE mesh autoencoder, then every frame encoded to latents). The code space
and retrieval database stages come next.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import yaml

from ..errors import InputError
from ..paths import workspace
from ..sim.plan import CONFIG_DIR
from ._common import run_cli

STAGES = ("autoencoder",)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="hrr-train", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--garment", default=None, help="garment name: finds hrr_work/datasets/GARMENT-PRESET.h5")
    p.add_argument("--preset", default="quick", help="dataset preset to look for (default quick)")
    p.add_argument("--dataset", type=Path, default=None, help="dataset .h5 (instead of --garment/--preset)")
    p.add_argument("--stage", choices=(*STAGES, "all"), default="all")
    p.add_argument("--config", type=Path, default=None, help="YAML with model/train sections (default configs/autoencoder.yaml)")
    p.add_argument("--epochs", type=int, default=None)
    p.add_argument("--minutes", type=float, default=None, help="wall-clock budget for the autoencoder")
    p.add_argument("--threads", type=int, default=None, help="torch CPU threads (default: torch's choice)")
    p.add_argument("-o", "--output", type=Path, default=None, help="model folder (default hrr_work/models/GARMENT-PRESET)")
    p.add_argument("--quiet", action="store_true")
    return p


def _config(path: Path | None) -> dict:
    path = path or CONFIG_DIR / "autoencoder.yaml"
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(path, f"cannot read the training config: {exc}") from None
    if not isinstance(data, dict) or set(data) - {"model", "train"}:
        raise InputError(path, "expected a mapping with 'model' and/or 'train' sections")
    return data


def _main(argv: Sequence[str] | None) -> int:
    args = _parser().parse_args(argv)
    from ..models.fcmae import AutoencoderConfig
    from ..train.autoencoder import TrainConfig, train_autoencoder

    if args.dataset is None:
        if args.garment is None:
            raise InputError("hrr-train", "give --garment NAME (with --preset) or --dataset FILE")
        args.dataset = workspace() / "datasets" / f"{args.garment}-{args.preset}.h5"
        if not args.dataset.exists():
            raise InputError(args.dataset, f"no dataset; make it with: hrr-simulate --garment {args.garment} --preset {args.preset}")
    folder = args.output or workspace() / "models" / args.dataset.stem
    cfg = _config(args.config)
    try:
        model_cfg = AutoencoderConfig.from_dict(cfg.get("model") or {})
        train_values = dict(cfg.get("train") or {})
    except ValueError as exc:
        raise InputError(args.config or "configs/autoencoder.yaml", str(exc)) from None
    for key, value in (("epochs", args.epochs), ("max_minutes", args.minutes), ("threads", args.threads)):
        if value is not None:
            train_values[key] = value
    try:
        train_cfg = TrainConfig.from_dict(train_values)
    except ValueError as exc:
        raise InputError(args.config or "configs/autoencoder.yaml", str(exc)) from None
    for stage in STAGES if args.stage == "all" else (args.stage,):
        if stage == "autoencoder":
            report = train_autoencoder(args.dataset, folder / "autoencoder", model_cfg, train_cfg,
                                       cache_dir=workspace() / "cache", progress=not args.quiet)
            print(f"autoencoder: {report.epochs} epochs (best {report.best_epoch}) in {report.minutes:.1f} min; "
                  f"per-vertex error val {report.val_pve_mm:.2f} mm, test {report.test_pve_mm:.2f} mm, "
                  f"train {report.train_pve_mm:.2f} mm; latent {report.latent_shape[0]} x {report.latent_shape[1]} "
                  f"(levels {' > '.join(str(s) for s in report.sizes)}) -> {report.folder}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return run_cli(_main, argv, "hrr-train")


if __name__ == "__main__":
    sys.exit(main())
