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
(the fast decoder for games, distilled from the mesh decoder); ``direct``
(the direct-regression baseline, formerly ``baseline``) only when asked for. Each stage resumes from its checkpoint and
is skipped when its outputs are current. A :class:`TrainCallback` hears each stage's end and
messages; the command line's prints them, a library caller may ignore them.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..errors import InputError
from ..eval.auto_criterion import AutoSettings, repick
from ..eval.auto_mode import (
    calibrate_auto_mode,
    followed_otherwise,
    lacks_default_body,
    lacks_free_cloth,
    lacks_free_folds,
    lacks_swing,
    measure_swing_again,
    swing_unmeasured,
)
from ..io_utils import remove_empty_folders
from ..models.codespace import CodeSpaceSettings
from ..models.direct import DirectSettings
from ..models.fcmae import AutoencoderSettings
from ..models.subspace import SubspaceSettings
from ..paths import workspace
from ..settings import deep_merge
from ..sim.preset import CONFIG_DIR, Preset
from ..train.autoencoder import AutoencoderTrainSettings
from ..train.codespace_training import CodeSpaceTrainSettings
from ..train.direct import DirectTrainSettings
from ..train.report import StageReport
from ..train.subspace import SubspaceTrainSettings, subspace_warning
from . import simulate as simulation
from .budget import BudgetCheck, TrainingBudgetWarning, check_budget
from .simulate import SimulatedDataset

STAGES = (
    "simulate",
    "autoencoder",
    "codespace",
    "subspace",
)  # what "all" runs; the direct stage runs only when asked for
SECTIONS = ("autoencoder", "codespace", "subspace", "direct", "auto")  # of the training config
BUDGETED = ("autoencoder", "codespace")  # stages checked against their epochs and target error (.budget)
# the old names of stages and config sections (deprecated, still read): old -> current
OLD_STAGE_NAMES = {"codebook": "codespace", "baseline": "direct"}


class TrainCallback:
    """Hears what training does; every method but :meth:`on_warning` does nothing unless overridden."""

    def on_message(self, text: str) -> None:
        """A line worth telling a person (a dataset simulated first, a deprecated setting)."""

    def on_warning(self, text: str) -> None:
        """A stage ended short of what its settings aim for: its epochs or its target error
        (:mod:`.budget`), or the fast decoder far from the full one: a
        :class:`~.budget.TrainingBudgetWarning` unless overridden."""
        warnings.warn(text, TrainingBudgetWarning, stacklevel=3)

    def on_stage_end(self, stage: str, result: StageReport | dict | None) -> None:
        """A stage finished: its report (``simulate``: a :class:`SimulatedDataset`, None where the
        dataset was there; ``auto``: the calibration's dict)."""


def _sections(data, source, callback: TrainCallback) -> dict:
    """A training config's sections, checked, old section names (:data:`OLD_STAGE_NAMES`) renamed."""
    for old, new in OLD_STAGE_NAMES.items():
        if isinstance(data, dict) and old in data:
            callback.on_message(f"deprecated: {source}: the config section '{old}' is now called '{new}'")
            if new in data:
                raise InputError(source, f"has both a '{old}' and a '{new}' section; keep '{new}'")
            data = {(new if k == old else k): v for k, v in data.items()}
    if not isinstance(data, dict) or set(data) - set(SECTIONS):
        raise InputError(
            source,
            "expected a mapping with 'autoencoder', 'codespace', 'subspace' and/or 'direct' sections "
            "(each with model/train) and/or an 'auto' section",
        )
    return data


def _read_yaml(path: Path, callback: TrainCallback) -> dict:
    try:
        data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise InputError(path, f"cannot read the training config: {exc}") from None
    return _sections(data, path, callback)


def _build(factory, values: dict, source) -> object:
    try:
        return factory.from_dict(dict(values or {}))
    except ValueError as exc:
        raise InputError(source, str(exc)) from None


@dataclass(frozen=True)
class TrainSettings:
    """Every stage's model and training settings (each a config dataclass of its stage)."""

    autoencoder: AutoencoderSettings = field(default_factory=AutoencoderSettings)
    autoencoder_train: AutoencoderTrainSettings = field(default_factory=AutoencoderTrainSettings)
    codespace: CodeSpaceSettings = field(default_factory=CodeSpaceSettings)
    codespace_train: CodeSpaceTrainSettings = field(default_factory=CodeSpaceTrainSettings)
    subspace: SubspaceSettings = field(default_factory=SubspaceSettings)
    subspace_train: SubspaceTrainSettings = field(default_factory=SubspaceTrainSettings)
    direct: DirectSettings = field(default_factory=DirectSettings)
    direct_train: DirectTrainSettings = field(default_factory=DirectTrainSettings)
    auto: AutoSettings = field(
        default_factory=AutoSettings
    )  # the auto mode's calibration after the code space

    @classmethod
    def load(
        cls,
        preset: Preset | None = None,
        user_config: str | Path | None = None,
        overrides: dict | None = None,
        callback: TrainCallback | None = None,
    ) -> "TrainSettings":
        """configs/train.yaml, then the preset's ``train:`` section, then ``user_config`` (a YAML of
        the same sections), then ``overrides`` (``{"autoencoder": {"train": {"max_minutes": 5}}}``)."""
        callback = callback or TrainCallback()
        values = _read_yaml(CONFIG_DIR / "train.yaml", callback)
        if preset is not None:
            values = deep_merge(
                values, _sections(preset.train or {}, f"the {preset.name} preset's train section", callback)
            )
        if user_config is not None:
            values = deep_merge(values, _read_yaml(Path(user_config), callback))
        values = deep_merge(values, _sections(overrides or {}, "the overrides", callback))
        source = user_config or CONFIG_DIR / "train.yaml"
        built = {}
        for section, (model_cls, train_cls) in {
            "autoencoder": (AutoencoderSettings, AutoencoderTrainSettings),
            "codespace": (CodeSpaceSettings, CodeSpaceTrainSettings),
            "subspace": (SubspaceSettings, SubspaceTrainSettings),
            "direct": (DirectSettings, DirectTrainSettings),
        }.items():
            built[section] = _build(model_cls, values.get(section, {}).get("model"), source)
            built[f"{section}_train"] = _build(train_cls, values.get(section, {}).get("train"), source)
        return cls(**built, auto=_build(AutoSettings, values.get("auto"), source))


@dataclass
class TrainResult:
    """What :func:`train_model` did: each stage's report, the auto calibration, seconds per stage."""

    folder: Path
    reports: dict[str, StageReport] = field(default_factory=dict)
    auto: dict | None = None  # bundle.json's "auto" after the code-space stage
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
    unknown = [s for s in stages if s not in (*STAGES, "direct")]
    if unknown:
        raise ValueError(f"unknown stage(s) {unknown}; the stages are {', '.join((*STAGES, 'direct'))}")
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
            report = _STAGE_RUNNERS[stage](
                dataset, folder, settings, _Context(garment, preset, progress, callback)
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
            if stage == "codespace":
                result.auto = calibrate_auto(folder, dataset, progress, settings.auto)
                callback.on_stage_end("auto", result.auto)
            result.seconds[stage] = time.perf_counter() - t0
    except BaseException:
        remove_empty_folders(
            folder
        )  # what a failed run made and never filled; finished stages stay for resuming
        raise
    return result


@dataclass(frozen=True)
class _Context:
    garment: str | None
    preset: Preset | None
    progress: bool
    callback: TrainCallback


def _simulate_stage(
    dataset: Path, folder: Path, settings: TrainSettings, ctx: _Context
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


def _autoencoder_stage(dataset: Path, folder: Path, settings: TrainSettings, ctx: _Context) -> StageReport:
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


def _codespace_stage(dataset: Path, folder: Path, settings: TrainSettings, ctx: _Context) -> StageReport:
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


def _subspace_stage(dataset: Path, folder: Path, settings: TrainSettings, ctx: _Context) -> StageReport:
    from ..train.subspace import run_subspace_stage

    return run_subspace_stage(
        dataset,
        folder,
        settings.subspace,
        train_config=settings.subspace_train,
        cache_dir=workspace() / "cache",
        progress=ctx.progress,
    )


def _direct_stage(dataset: Path, folder: Path, settings: TrainSettings, ctx: _Context) -> StageReport:
    from ..train.direct import run_direct_stage

    return run_direct_stage(
        dataset,
        folder,
        settings.direct,
        train_config=settings.direct_train,
        cache_dir=workspace() / "cache",
        progress=ctx.progress,
    )


_STAGE_RUNNERS = {
    "simulate": _simulate_stage,
    "autoencoder": _autoencoder_stage,
    "codespace": _codespace_stage,
    "subspace": _subspace_stage,
    "direct": _direct_stage,
}


def calibrate_auto(
    folder: str | Path, dataset: str | Path, progress: bool = True, config: AutoSettings = AutoSettings()
) -> dict:
    """The mode ``auto`` runs (:mod:`hrr_garment.eval.auto_mode`), calibrated on the dataset's
    validation clips once per bundle and recorded in bundle.json with every candidate's numbers;
    the recorded one where it was, picked again from its numbers where ``config``'s allowance differs
    from the one it was picked under (the swing gains of a first pick that moved measured first)."""
    from ..artifacts.auto_calibration import AutoCalibration
    from ..artifacts.typed_manifest import read_manifest, update_manifest
    from ..inference.animator import Animator

    manifest = read_manifest(folder)  # reading it hashes every file: once
    recorded = manifest.auto
    # calibrated again where recorded before the candidates carried their cloth inside the body (the
    # criterion counts it), the residual or the folds on free cloth, the default body's clips apart,
    # the folds followed in time (as the detail mode now runs) or the swing's gain; picked again
    # where only an allowance moved
    if (
        recorded is None
        or any("penetration_pct" not in c for c in (recorded.candidates or {}).values())
        or lacks_swing(recorded)
        or lacks_free_cloth(recorded, manifest.residual)
        or lacks_default_body(recorded, manifest.bodies)
        or (manifest.folds is not None and (followed_otherwise(recorded) or lacks_free_folds(recorded)))
    ):
        auto = calibrate_auto_mode(
            Animator.load(folder), _validation_records(dataset), config, progress=progress
        )
    elif any(getattr(recorded, key) != value for key, value in config.limits().items()):
        auto = (
            measure_swing_again(
                Animator.load(folder),
                _validation_records(dataset),
                auto=recorded.to_dict(),
                config=config,
                progress=progress,
            )
            if swing_unmeasured(recorded, config)
            else repick(recorded.to_dict(), config)
        )
    else:
        return recorded.to_dict()
    update_manifest(folder, auto=AutoCalibration.from_report(auto, "auto"))
    return auto


def _validation_records(dataset: str | Path) -> list:
    """The dataset's validation sequences (what the auto mode is calibrated on)."""
    from ..data.dataset import GarmentDataset

    ds = GarmentDataset(dataset)
    return [ds.sequence(n) for n in ds.splits.get("val", [])]
