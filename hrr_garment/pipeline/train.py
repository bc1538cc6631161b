"""Training a garment model end to end: :class:`TrainSettings` and :func:`train_model`.

    from hrr_garment.pipeline.train import TrainSettings, train_model
    from hrr_garment.sim.preset import load_preset

    preset = load_preset("tiny")
    settings = TrainSettings.load(preset)                       # configs/train.yaml, then the preset's
    result = train_model("hrr_work/datasets/skirt-tiny.h5", "hrr_work/models/skirt-tiny", settings,
                         garment="skirt", preset=preset)        # simulates first where the dataset is missing
    result.auto                                                 # what the auto mode was calibrated to run

The stages, in order: ``simulate`` (only where the dataset does not exist, or lacks sequences its
preset has gained), ``autoencoder`` (the FCMAE mesh autoencoder, then every frame encoded),
``codespace`` (the shared code space, the retrieval database, the gate's and the residual mode's
calibration, the bundle), then the auto mode's calibration on the validation clips, ``subspace``
(the fast decoder for games, distilled from the mesh decoder); ``direct`` (the direct-regression
baseline, formerly ``baseline``) only when asked for. Each stage resumes from its checkpoint and is
skipped when its outputs are current. A :class:`TrainCallback` hears each stage's end and
messages; the command line's prints them, a library caller may ignore them.

The settings and the callback are in :mod:`~hrr_garment.pipeline.train_settings`, each stage's
runner in :mod:`~hrr_garment.pipeline.stage_runners`, the auto mode's calibration in
:mod:`~hrr_garment.pipeline.auto_stage`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from ..artifacts.auto_calibration import AutoCalibration
from ..io_utils import remove_empty_folders
from ..sim.preset import Preset
from ..train.report import StageReport
from ..train.subspace_size import subspace_warning
from .auto_stage import calibrate_auto
from .budget import BudgetCheck, check_budget
from .stage_runners import STAGE_RUNNERS, StageContext
from .train_settings import OLD_STAGE_NAMES, TrainCallback, TrainSettings

STAGES = (
    "simulate",
    "autoencoder",
    "codespace",
    "subspace",
)  # what "all" runs
NAMED_STAGES = ("direct", "sampler")  # run only when asked for: the baseline, the generative decoder
BUDGETED = ("autoencoder", "codespace")  # stages checked against their epochs and target error (.budget)


@dataclass
class TrainResult:
    """What :func:`train_model` did: each stage's report, the auto calibration, seconds per stage."""

    folder: Path
    reports: dict[str, StageReport] = field(default_factory=dict)
    auto: AutoCalibration | None = None  # bundle.json's "auto" after the code-space stage
    budgets: dict[str, BudgetCheck] = field(
        default_factory=dict
    )  # the autoencoder's and code space's epochs and errors
    seconds: dict[str, float] = field(default_factory=dict)


def train_model(
    dataset: str | Path,
    folder: str | Path,
    settings: TrainSettings,
    *,
    stages: tuple[str, ...] = STAGES,
    garment: str | None = None,
    preset: Preset | None = None,
    progress: bool = True,
    callback: TrainCallback | None = None,
) -> TrainResult:
    """Run ``stages`` (see the module docstring) on ``dataset`` into the bundle folder ``folder``.
    ``garment`` and ``preset``: what the ``simulate`` stage builds where the dataset is missing
    (without a garment it is the user's dataset, and must exist)."""
    dataset, folder = Path(dataset), Path(folder)
    callback = callback or TrainCallback()
    stages = tuple(OLD_STAGE_NAMES.get(s, s) for s in stages)
    unknown = [s for s in stages if s not in (*STAGES, *NAMED_STAGES)]
    if unknown:
        raise ValueError(f"unknown stage(s) {unknown}; the stages are {', '.join((*STAGES, *NAMED_STAGES))}")
    result = TrainResult(folder)
    try:
        if dataset.exists() and {"autoencoder", "codespace"} & set(stages):
            from ..data.dataset import GarmentDataset
            from ..train.codespace_inputs import check_splits

            check_splits(
                GarmentDataset(dataset)
            )  # a dataset the code space cannot use fails before any training
        for stage in stages:
            t0 = time.perf_counter()
            report = STAGE_RUNNERS[stage](
                dataset,
                folder,
                settings,
                StageContext(garment=garment, preset=preset, progress=progress, callback=callback),
            )
            if isinstance(report, StageReport):
                result.reports[stage] = report
                if stage == "subspace" and (text := subspace_warning(report.metrics)):
                    callback.on_warning(text)
                if stage in BUDGETED:
                    result.budgets[stage] = check_budget(report, getattr(settings, f"{stage}_train"))
                    for text in result.budgets[stage].warnings():
                        callback.on_warning(text)
            callback.on_stage_end(stage, report)
            if stage in ("codespace", "sampler"):  # a new candidate of auto's: the sample mode
                result.auto = calibrate_auto(folder, dataset, progress, config=settings.auto)
                callback.on_stage_end("auto", result.auto)
            result.seconds[stage] = time.perf_counter() - t0
    except BaseException:
        remove_empty_folders(
            folder
        )  # what a failed run made and never filled; finished stages stay for resuming
        raise
    return result
