"""The sections of bundle.json, typed (:mod:`.manifest_section`): the networks' settings, the
retrieval database, the gates' calibration, the residual's weight, the fold store, the optional
parts (the fast decoder, the baseline), the bodies trained on. The auto calibration's section is in
:mod:`.auto_calibration`; the whole manifest in :mod:`.typed_manifest`.

Each field is named as its JSON key and checked where read; a model's settings (``config``) stay
the JSON object the model's own ``from_dict`` reads (:func:`~.bundle_loader.load_bundle` checks them, as it
builds the networks), so that they are written back exactly as read.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from .manifest_section import (
    ManifestFieldError,
    Section,
    mapping,
    number,
    text,
    whole,
    whole_list,
)


@dataclass(frozen=True, kw_only=True)
class AutoencoderEntry(Section):
    """``autoencoder``: the mesh autoencoder's settings, vertex scale and sampling hierarchy's sizes."""

    config: Mapping[str, Any]
    scale: float
    sizes: tuple[int, ...] | None = None

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            "config": mapping(data.get("config"), f"{where}.config"),
            "scale": data.get("scale"),  # its range is the network's business (load_bundle checks it)
            "sizes": whole_list(data.get("sizes"), f"{where}.sizes", optional=True),
        }


@dataclass(frozen=True, kw_only=True)
class CodeSpaceEntry(Section):
    """``codespace``: the code space's settings, its motion features and the latent's shape."""

    config: Mapping[str, Any]
    features: int
    latent_shape: tuple[int, ...]

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            "config": mapping(data.get("config"), f"{where}.config"),
            "features": whole(data.get("features"), f"{where}.features"),
            "latent_shape": whole_list(data.get("latent_shape"), f"{where}.latent_shape"),
        }


@dataclass(frozen=True, kw_only=True)
class DatabaseEntry(Section):
    """``database``: the retrieval database's sequences (by name), code classes and windows."""

    names: tuple[str, ...]
    classes: int
    windows: int | None = None

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        names = data.get("names")
        if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
            raise ManifestFieldError(f"{where + '.names'!r} must be a list of names, got {names!r}")
        return {
            "names": tuple(names),
            "classes": whole(data.get("classes"), f"{where}.classes"),
            "windows": whole(data.get("windows"), f"{where}.windows", optional=True),
        }


@dataclass(frozen=True, kw_only=True)
class GateCalibration(Section):
    """One entry of ``gates``: a gate signal's calibrated tau and its validation numbers (all
    absent where that signal was not calibrated)."""

    tau: float | None = None
    validation_mm: float | None = None
    retrieval_usage: float | None = None

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            "tau": number(data.get("tau"), f"{where}.tau", low=0, optional=True),
            "validation_mm": number(data.get("validation_mm"), f"{where}.validation_mm", optional=True),
            "retrieval_usage": number(data.get("retrieval_usage"), f"{where}.retrieval_usage", optional=True),
        }


@dataclass(frozen=True, kw_only=True)
class ResidualEntry(Section):
    """``residual``: the residual mode's calibrated weight (:mod:`.residual`) and its calibration."""

    weight: float
    validation_mm: float | None = None
    allowance: float | None = None
    errors_mm: Mapping[str, float] | None = None

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        try:
            weight = number(data.get("weight"), f"{where}.weight", low=0)
        except ManifestFieldError:
            raise ManifestFieldError(
                f"'residual' must hold a finite 'weight' >= 0, got {dict(data)!r}"
            ) from None
        return {
            "weight": weight,
            "validation_mm": number(data.get("validation_mm"), f"{where}.validation_mm", optional=True),
            "allowance": number(data.get("allowance"), f"{where}.allowance", optional=True),
            "errors_mm": mapping(data.get("errors_mm"), f"{where}.errors_mm", optional=True),
        }


@dataclass(frozen=True, kw_only=True)
class FoldsEntry(Section):
    """``folds``: how the fold store (:mod:`.folds`) was built and holds its frames."""

    passes: int
    encoding: str
    frames: int | None = None
    vertices: int | None = None

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {  # the values' ranges are the fold store's business (load_folds checks them)
            "passes": data.get("passes"),
            "encoding": text(data.get("encoding"), f"{where}.encoding"),
            "frames": whole(data.get("frames"), f"{where}.frames", optional=True),
            "vertices": data.get("vertices"),
        }


@dataclass(frozen=True, kw_only=True)
class PartEntry(Section):
    """``subspace`` (the fast decoder) or ``direct`` (the baseline): an optional trained part, the
    key of the settings and data it was trained with (a stage with the same key is reused), its
    settings and training report."""

    key: str | None = None
    config: Mapping[str, Any]
    train: Mapping[str, Any] | None = None
    epochs: int | None = None
    best_epoch: int | None = None
    validation_mm: float | None = None
    minutes: float | None = None

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            "key": text(data.get("key"), f"{where}.key", optional=True),
            "config": mapping(data.get("config"), f"{where}.config"),
            "train": mapping(data.get("train"), f"{where}.train", optional=True),
            "epochs": whole(data.get("epochs"), f"{where}.epochs", optional=True),
            "best_epoch": whole(data.get("best_epoch"), f"{where}.best_epoch", optional=True),
            "validation_mm": number(data.get("validation_mm"), f"{where}.validation_mm", optional=True),
            "minutes": number(data.get("minutes"), f"{where}.minutes", optional=True),
        }


@dataclass(frozen=True, kw_only=True)
class SubspaceEntry(PartEntry):
    """``subspace``: the fast decoder (:mod:`hrr_garment.models.subspace`), its component count
    and the validation errors it was chosen on (the full decoder's, each candidate count's)."""

    components: int
    full_validation_mm: float | None = None
    candidates_mm: Mapping[str, float] | None = None  # component count (as text): validation mm

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            **super()._typed(data, where),
            "components": data.get("components"),  # checked as the fast decoder is built
            "full_validation_mm": number(
                data.get("full_validation_mm"), f"{where}.full_validation_mm", optional=True
            ),
            "candidates_mm": mapping(data.get("candidates_mm"), f"{where}.candidates_mm", optional=True),
        }


@dataclass(frozen=True, kw_only=True)
class BodiesEntry(Section):
    """``bodies``: the range of the bodies trained on, the default body (null: the mannequin) and
    the body the garment was modelled on (null: the mannequin), as body files write them
    (:class:`~.bundle.Bundle` reads them)."""

    range: Mapping[str, Any] | None = None
    default: Mapping[str, Any] | None = None
    made_for: Mapping[str, Any] | None = None
    NULLABLE = frozenset({"default", "made_for"})

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            "range": mapping(data.get("range"), f"{where}.range", optional=True),
            "default": mapping(data.get("default"), f"{where}.default", optional=True),
            "made_for": mapping(data.get("made_for"), f"{where}.made_for", optional=True),
        }

    @property
    def count(self) -> int:
        """How many bodies the model was trained on (1 where the range does not say)."""
        return int((self.range or {}).get("bodies", 1))


@dataclass(frozen=True, kw_only=True)
class MaterialsEntry(Section):
    """``materials``: the range of the cloths trained in and the cloth animated when given none
    (:class:`~.bundle.Bundle` reads them; absent for a model from before cloths were recorded)."""

    range: Mapping[str, Any]
    default: Mapping[str, Any]

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        return {
            "range": mapping(data.get("range"), f"{where}.range"),
            "default": mapping(data.get("default"), f"{where}.default"),
        }
