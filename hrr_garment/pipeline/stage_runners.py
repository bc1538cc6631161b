"""The stages :func:`~hrr_garment.pipeline.train.train_model` runs, one runner each: the dataset
simulated where missing or out of date, then the autoencoder, code-space, subspace and direct
stages of :mod:`hrr_garment.train`, each with its settings from :class:`TrainSettings`."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..paths import workspace
from ..sim.preset import Preset
from ..train.report import StageReport
from . import simulate as simulation
from .simulate import SimulatedDataset
from .train_settings import TrainCallback, TrainSettings


@dataclass(frozen=True)
class StageContext:
    """What every stage runner is told besides the settings: what to simulate where the dataset is
    missing, whether to show progress, and who hears its messages."""

    garment: str | None
    preset: Preset | None
    progress: bool
    callback: TrainCallback


def _simulate_stage(
    dataset: Path, folder: Path, settings: TrainSettings, ctx: StageContext
) -> SimulatedDataset | None:
    stale = (
        simulation.dataset_out_of_date(dataset, ctx.preset)
        if ctx.garment is not None and ctx.preset is not None
        else None
    )
    if dataset.exists() and stale is None:
        return None
    if ctx.garment is None or ctx.preset is None:
        raise InputError(dataset, "no such dataset")
    if dataset.exists():  # the preset changed since this dataset was made: make what it lacks
        ctx.callback.on_message(
            f"simulate: {dataset} {stale}; making it again (its finished sequences are reused)"
        )
    else:
        ctx.callback.on_message(
            f"simulate: no dataset at {dataset}; simulating the {ctx.preset.name} preset first"
        )
    return simulation.simulate_preset(ctx.garment, ctx.preset, dataset, progress=ctx.progress)


def _autoencoder_stage(
    dataset: Path, folder: Path, settings: TrainSettings, ctx: StageContext
) -> StageReport:
    from ..train.autoencoder import train_autoencoder

    if not dataset.exists():
        hint = (
            f"hrr-simulate --garment {ctx.garment} --preset {ctx.preset.name}"
            if ctx.garment and ctx.preset
            else "hrr-simulate"
        )
        raise InputError(dataset, f"no dataset; make it with: {hint} (or run hrr-train without --stage)")
    return train_autoencoder(
        dataset,
        folder / "autoencoder",
        settings.autoencoder,
        train_config=settings.autoencoder_train,
        cache_dir=workspace() / "cache",
        progress=ctx.progress,
    )


def _codespace_stage(dataset: Path, folder: Path, settings: TrainSettings, ctx: StageContext) -> StageReport:
    from ..train.codespace import run_codespace_stage

    info = {"preset": ctx.preset.name} if ctx.preset is not None else None
    return run_codespace_stage(
        dataset,
        folder,
        settings.codespace,
        train_config=settings.codespace_train,
        cache_dir=workspace() / "cache",
        progress=ctx.progress,
        info=info,
    )


def _part_stage(section: str):
    """The stage that adds the trained part ``section`` (subspace, direct, sampler) to a bundle:
    ``hrr_garment.train.<section>.run_<section>_stage`` (imported when it runs: torch and the
    part's code load only for a stage asked for) with the settings' ``section`` and its training."""

    def run(dataset: Path, folder: Path, settings: TrainSettings, ctx: StageContext) -> StageReport:
        module = importlib.import_module(f"..train.{section}", __package__)
        return getattr(module, f"run_{section}_stage")(
            dataset,
            folder,
            getattr(settings, section),
            train_config=getattr(settings, f"{section}_train"),
            cache_dir=workspace() / "cache",
            progress=ctx.progress,
        )

    return run


STAGE_RUNNERS = {
    "simulate": _simulate_stage,
    "autoencoder": _autoencoder_stage,
    "codespace": _codespace_stage,
    "subspace": _part_stage("subspace"),
    "direct": _part_stage("direct"),
    "sampler": _part_stage("sampler"),
}
