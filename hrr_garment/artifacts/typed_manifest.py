"""bundle.json as a typed, frozen :class:`Manifest`: how the package reads a bundle's manifest.

:func:`read_manifest` reads bundle.json, upgrades an older format in one place
(:func:`~.manifest.migrate_manifest`), checks its file list and hashes (:func:`~.manifest.check_file_list`)
and the signature policy, and types it, every section checked (a :class:`~.manifest.BundleError`
naming the folder and the field that is off). Writers make a new manifest with
:func:`dataclasses.replace` (a calibration recorded, a part added) and :func:`write_manifest` writes
it at the current version with its manifest hash; the on-disk format is bundle.json's as before, and
a manifest read and written unchanged is the same JSON (:mod:`.manifest_section`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..io_utils import atomic_write_text, strict_json
from ..motion.licences import MotionLicences
from .auto_calibration import UNCALIBRATED, AutoCalibration
from .gate_signals import GATE_SIGNALS
from .manifest import BundleError, check_file_list, migrate_manifest, sha256, with_manifest_hash
from .manifest_entries import (
    AutoencoderEntry,
    BodiesEntry,
    CodeSpaceEntry,
    DatabaseEntry,
    FoldsEntry,
    GateCalibration,
    MaterialsEntry,
    PartEntry,
    ResidualEntry,
    SubspaceEntry,
)
from .manifest_section import ManifestFieldError, Section, mapping, number, text, whole
from .signature import check_signature


@dataclass(frozen=True, kw_only=True)
class Manifest(Section):
    """bundle.json, typed: the format version, the garment, the networks' settings, the gate and
    its tau, the database, the file list and its hashes, the calibrations and the optional parts
    (None where the bundle has none); keys it does not type kept in ``extra``."""

    format_version: int
    garment: str
    created: str | None = None
    autoencoder: AutoencoderEntry
    codespace: CodeSpaceEntry
    tau: float
    gate: str
    gates: Mapping[str, GateCalibration]  # each gate signal calibrated (all but the model's own gate)
    database: DatabaseEntry
    files: Mapping[str, str]  # file name -> sha256
    content_hash: str
    dataset: str | None = None  # the dataset trained on
    window: int | None = None
    validation_mm: Mapping[str, Any] | None = None  # the code-space stage's validation report
    residual: ResidualEntry | None = None
    encoding: Mapping[str, Any] | None = None  # the encoder's refinement settings (train/calibrate.py)
    validation: str  # "clips" or the paper's "windows"
    preset: str | None = None
    folds: FoldsEntry | None = None
    manifest_hash: str | None = None  # absent before version 4 (written when next written)
    auto: AutoCalibration | None = None
    subspace: SubspaceEntry | None = None  # the fast decoder
    direct: PartEntry | None = None  # the direct-regression baseline
    sampler: PartEntry | None = None  # the generative decoder (mode sample)
    bodies: BodiesEntry | None = None  # absent for a model from before bodies
    materials: MaterialsEntry | None = None  # absent for a model from before cloths were recorded
    # the motion sources of the clips it learned from and their terms (motion/licences.py); absent
    # for a model from before they were recorded
    motion: Mapping[str, Any] | None = None
    NULLABLE = frozenset(
        {
            "created",
            "dataset",
            "window",
            "validation_mm",
            "encoding",
            "preset",
            "bodies",
            "materials",
            "motion",
        }
    )

    @classmethod
    def _typed(cls, data: Mapping[str, Any], where: str) -> dict[str, Any]:
        garment, gate, gates = data.get("garment"), data.get("gate"), data.get("gates")
        if not isinstance(garment, str) or not garment:
            raise ManifestFieldError(f"'garment' must be a name, got {garment!r}")
        if gate not in GATE_SIGNALS:
            raise ManifestFieldError(f"'gate' must be one of {', '.join(GATE_SIGNALS)}, got {gate!r}")
        if not isinstance(gates, Mapping) or not all(
            k in GATE_SIGNALS and isinstance(v, Mapping) for k, v in gates.items()
        ):
            raise ManifestFieldError(f"'gates' must map gate signals to their calibration, got {gates!r}")
        if data.get("validation") not in ("clips", "windows"):
            raise ManifestFieldError(f"'validation' must be clips or windows, got {data.get('validation')!r}")
        for section in ("autoencoder", "codespace", "database"):
            if not isinstance(data.get(section), Mapping):
                raise ManifestFieldError(f"lacks its {section!r} section")
        return {
            "format_version": whole(data.get("format_version"), "format_version"),
            "garment": garment,
            "created": text(data.get("created"), "created", optional=True),
            "autoencoder": AutoencoderEntry.parse(data["autoencoder"], "autoencoder"),
            "codespace": CodeSpaceEntry.parse(data["codespace"], "codespace"),
            "tau": number(data.get("tau"), "tau", low=0),
            "gate": gate,
            "gates": {k: GateCalibration.parse(v, f"gates.{k}") for k, v in gates.items()},
            "database": DatabaseEntry.parse(data["database"], "database"),
            "files": mapping(data.get("files"), "files"),
            "content_hash": text(data.get("content_hash"), "content_hash"),
            "dataset": text(data.get("dataset"), "dataset", optional=True),
            "window": whole(data.get("window"), "window", optional=True),
            "validation_mm": mapping(data.get("validation_mm"), "validation_mm", optional=True),
            "residual": _optional(ResidualEntry, data, "residual"),
            "encoding": mapping(data.get("encoding"), "encoding", optional=True),
            "validation": data["validation"],
            "preset": text(data.get("preset"), "preset", optional=True),
            "folds": _optional(FoldsEntry, data, "folds"),
            "manifest_hash": text(data.get("manifest_hash"), "manifest_hash", optional=True),
            "auto": _optional(AutoCalibration, data, "auto"),
            "subspace": _optional(SubspaceEntry, data, "subspace"),
            "direct": _optional(PartEntry, data, "direct"),
            "sampler": _optional(PartEntry, data, "sampler"),
            "bodies": None if data.get("bodies") is None else BodiesEntry.parse(data["bodies"], "bodies"),
            "materials": None
            if data.get("materials") is None
            else MaterialsEntry.parse(data["materials"], "materials"),
            "motion": mapping(data.get("motion"), "motion", optional=True),
        }

    @property
    def auto_or_uncalibrated(self) -> AutoCalibration:
        """``auto``: what the auto calibration chose, or, before it ran, the hybrid with the default
        detail look (:data:`~.auto_calibration.UNCALIBRATED`)."""
        return self.auto if self.auto is not None else UNCALIBRATED

    @property
    def licences(self) -> MotionLicences:
        """Where the model's training motion comes from and whether it may ship commercially (its
        commercial use unknown for a model from before this was recorded)."""
        if self.motion is None:
            return MotionLicences({}, {}, unrecorded=1)
        try:
            return MotionLicences.from_dict(self.motion)
        except (KeyError, TypeError, ValueError, AttributeError):
            return MotionLicences({}, {}, unrecorded=1)

    @property
    def default_body_is_mannequin(self) -> bool:
        """Whether the model's default body is the mannequin (a model across bodies, or from before
        them), not the one body it was trained on."""
        return self.bodies is None or self.bodies.default is None


def _optional(section: type[Section], data: Mapping[str, Any], key: str) -> Section | None:
    """The optional section ``key``, typed, or None where absent."""
    return section.parse(data[key], key) if key in data else None


def parse_manifest(folder: Path, meta: object) -> Manifest:
    """``meta`` (bundle.json's JSON, at the current version) typed, or a BundleError naming ``folder``
    and the field that is off."""
    try:
        return Manifest.parse(meta, "bundle.json")
    except ManifestFieldError as exc:
        raise BundleError(folder, f"bundle.json {exc}") from None


def read_manifest(folder: str | Path, trust: bool = True) -> Manifest:
    """``folder``'s bundle.json, typed, after the version, manifest and file-hash checks and
    (``trust``) the signature policy (:mod:`.signature`; hrr-sign checks signatures its own way)."""
    folder = Path(folder)
    path = folder / "bundle.json"
    if not folder.is_dir():
        raise BundleError(folder, "no such model directory (train one with hrr-train)")
    if not path.is_file():
        raise BundleError(folder, "no bundle.json: not a model bundle, or its training did not finish")
    try:
        raw = path.read_bytes()
        meta = json.loads(raw.decode("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise BundleError(folder, f"bundle.json is unreadable ({exc})") from None
    manifest = parse_manifest(folder, check_file_list(folder, migrate_manifest(folder, meta)))
    for name, digest in manifest.files.items():
        if not (folder / name).is_file():
            raise BundleError(folder, f"{name} is missing")
        if sha256(folder / name) != digest:
            raise BundleError(folder, f"{name} does not match its recorded hash (corrupt or truncated file)")
    if trust:
        check_signature(folder, raw)  # the bytes just checked: a signature over what was read
    return manifest


def write_manifest(folder: Path, manifest: Manifest) -> Path:
    """Write ``manifest`` as ``folder``'s bundle.json (atomically), at the current version with its
    manifest hash; returns its path."""
    atomic_write_text(folder / "bundle.json", strict_json(with_manifest_hash(manifest.to_dict()), indent=2))
    return folder / "bundle.json"


def update_manifest(folder: str | Path, **changes: Any) -> None:
    """Replace fields of ``folder``'s manifest (``auto=...``, ``residual=...``: typed sections; None
    drops an optional one) and write it again, atomically (the files are unchanged)."""
    folder = Path(folder)
    write_manifest(folder, replace(read_manifest(folder), **changes))
