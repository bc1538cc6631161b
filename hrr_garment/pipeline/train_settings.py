"""Training settings: :class:`TrainSettings` (every stage's model and training settings, read from
configs/train.yaml, a preset's ``train:`` section, a user's YAML and overrides, old section names
renamed) and :class:`TrainCallback`, which hears what training does."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from ..artifacts.auto_calibration import AutoCalibration
from ..errors import InputError
from ..eval.auto_criterion import AutoSettings
from ..input_files import read_input_text
from ..models.codespace import CodeSpaceSettings
from ..models.direct import DirectSettings
from ..models.fcmae import AutoencoderSettings
from ..models.sampler import SamplerSettings
from ..models.subspace import SubspaceSettings
from ..settings import deep_merge
from ..sim.preset import CONFIG_DIR, Preset
from ..train.autoencoder_settings import AutoencoderTrainSettings
from ..train.codespace_settings import CodeSpaceTrainSettings
from ..train.direct import DirectTrainSettings
from ..train.report import StageReport
from ..train.sampler import SamplerTrainSettings
from ..train.subspace import SubspaceTrainSettings
from .budget import TrainingBudgetWarning

SECTIONS = ("autoencoder", "codespace", "subspace", "direct", "sampler", "auto")  # of the training config
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

    def on_stage_end(self, stage: str, result: StageReport | AutoCalibration | None) -> None:
        """A stage finished: its report (``simulate``: a :class:`SimulatedDataset`, None where the
        dataset was there; ``auto``: the calibration, bundle.json's ``auto``)."""


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
            "expected a mapping with 'autoencoder', 'codespace', 'subspace', 'direct' and/or 'sampler' "
            "sections (each with model/train) and/or an 'auto' section",
        )
    return data


def _read_yaml(path: Path, callback: TrainCallback) -> dict:
    try:
        data = yaml.safe_load(read_input_text(path, what="a training config")) or {}
    except (yaml.YAMLError, RecursionError) as exc:
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
    sampler: SamplerSettings = field(default_factory=SamplerSettings)
    sampler_train: SamplerTrainSettings = field(default_factory=SamplerTrainSettings)
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
            "sampler": (SamplerSettings, SamplerTrainSettings),
        }.items():
            built[section] = _build(model_cls, values.get(section, {}).get("model"), source)
            built[f"{section}_train"] = _build(train_cls, values.get(section, {}).get("train"), source)
        return cls(**built, auto=_build(AutoSettings, values.get("auto"), source))
