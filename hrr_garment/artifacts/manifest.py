"""bundle.json: the manifest that makes a folder a model bundle (:mod:`.bundle`), and its checks.

It records the format version, the garment, the calibrated settings (gate, tau, residual weight,
auto mode) and the sha256 of every other file with a content hash over them. This module holds its
format: the versions, the upgrade of older ones, the hashes and the file list's check.
:func:`~.typed_manifest.read_manifest` reads it as the typed, frozen
:class:`~.typed_manifest.Manifest` the package uses, and refuses a manifest that is malformed,
edited by hand or out of step with its files, and says which and why; there is no off switch.

Versions: :data:`FORMAT_VERSION` moves whenever a field arrives or changes meaning, and
:func:`migrate_manifest` upgrades an older manifest to the current one in memory, one step per
version, so that everything after it reads every field as the current version defines it.

- 1: garments in world coordinates (not readable: retrain).
- 2: garments in the pelvis-following body frame (:mod:`hrr_garment.motion.frame`); optional
  fields that later arrived one by one (``gate``, ``gates``, ``residual``, ``auto`` and its detail
  look, ``folds``, the code space's motion memory and regression code).
- 3: every calibrated field present with its value: ``gate``, ``gates`` (each other signal's
  calibrated tau), ``validation`` (the code space's: "clips" or the paper's "windows"), ``auto.detail_base``
  and ``auto.detail_strength`` wherever ``auto`` is, and the code space's ``memory_seconds``, ``resonator_hz``
  and ``regression_code``. ``auto`` is absent until training calibrates it (``auto`` then runs the hybrid),
  ``residual`` where the database has no motion windows, ``folds``, ``direct``, ``sampler`` and
  ``subspace`` (the fast decoder, which arrived later as an optional part) where the bundle has no
  such part.
- 4: ``manifest_hash``, a hash over bundle.json's own content (everything but itself): the
  content hash covers the files, and a hand-edited garment name, tau or scale went unseen. A
  version-3 manifest has none; it gets one when it is next written.
- 5: ``folds.encoding``, how the fold store holds its frames (``"nf4"`` for new stores, with
  ``folds.vertices``); a version-4 store is ``"int8"``.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..errors import InputError
from ..io_utils import strict_json
from .folds import DETAIL_STRENGTH

FORMAT_VERSION = 5  # see the module docstring
OLDEST_READABLE = 2  # version 1 kept garments in world coordinates: no step upgrades its networks
NETWORKS = ("motion_encoder", "garment_encoder", "decoder", "quantizer")
FOLDS_FILE = "folds.safetensors"  # the detail mode's simulated folds (.folds)
SUBSPACE_FILE = "subspace.safetensors"  # the run-time decoder sized for games (models/subspace.py)
AUTO_CHOICES = (
    "hybrid",
    "residual",
    "detail",
    "sample",
)  # what mode ``auto`` may stand for (eval/auto_mode.py chooses), the cheaper first
DETAIL_BASES = (
    "regression",
    "residual",
)  # what the detail mode's folds may ride on (eval/auto_mode.py chooses)
#: what ``auto`` stands for until training calibrates it: the hybrid, with the default detail look
UNCALIBRATED_AUTO = {"mode": "hybrid", "detail_base": "regression", "detail_strength": DETAIL_STRENGTH}
MAX_DETAIL_STRENGTH = (
    2.0  # the detail mode's folds at most twice the simulated ones (eval/auto_mode.py chooses)
)


def valid_detail_strength(value: object) -> bool:
    """Whether ``value`` is a strength the detail mode's folds may run at: a number in (0, max]."""
    return (
        not isinstance(value, bool) and isinstance(value, (int, float)) and 0 < value <= MAX_DETAIL_STRENGTH
    )


class BundleError(InputError):
    """A model directory that is missing, incomplete, corrupt, of another version or garment."""


def sha256(path: Path) -> str:
    """The file's sha256, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def manifest_hash(meta: dict) -> str:
    """16 hex digits over bundle.json's content but ``manifest_hash`` itself, in canonical JSON."""
    body = {k: v for k, v in meta.items() if k != "manifest_hash"}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]


def with_manifest_hash(meta: dict) -> dict:
    """``meta`` as bundle.json is written: at the current version, its manifest hash recorded
    over its JSON form (what a reader will parse)."""
    meta = json.loads(strict_json({**meta, "format_version": FORMAT_VERSION}))
    return {**meta, "manifest_hash": manifest_hash(meta)}


def content_hash(files: dict[str, str]) -> str:
    """16 hex digits over the file list (name -> sha256): one name for the model's contents."""
    return hashlib.sha256(json.dumps(files, sort_keys=True).encode()).hexdigest()[:16]


def required_files(meta: dict) -> set[str]:
    """Every file :func:`.bundle_loader.load_bundle` opens for this bundle: each must be listed with its
    hash."""
    names = {
        "autoencoder.safetensors",
        "stats.safetensors",
        "database.safetensors",
        "template.safetensors",
        *[f"{n}.safetensors" for n in NETWORKS],
    }
    optional = {
        "direct": "direct.safetensors",
        "sampler": "sampler.safetensors",
        "folds": FOLDS_FILE,
        "subspace": SUBSPACE_FILE,
    }
    return names | {file for part, file in optional.items() if part in meta}


def check_file_list(folder: Path, meta: object) -> dict:
    """bundle.json's file list and content hash (the integrity check has no off switch); its other
    fields are checked as it is typed (:mod:`.typed_manifest`)."""
    if not isinstance(meta, dict):
        raise BundleError(folder, f"bundle.json holds a {type(meta).__name__}, not an object")
    files = meta.get("files")
    if not isinstance(files, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in files.items()
    ):
        raise BundleError(
            folder,
            "bundle.json has no valid 'files' list (file name -> sha256): refusing an unverifiable model",
        )
    unlisted = sorted(required_files(meta) - set(files))
    if unlisted:
        raise BundleError(
            folder, f"bundle.json does not list {unlisted} with their hashes: refusing an unverifiable model"
        )
    for name in files:
        if name != Path(name).name or name in ("", ".", "..") or "\\" in name:
            raise BundleError(
                folder, f"bundle.json lists {name!r}: bundle files must lie directly in the bundle folder"
            )
    if meta.get("content_hash") != content_hash(files):
        raise BundleError(
            folder,
            f"content_hash {meta.get('content_hash')!r} does not match the file list "
            f"({content_hash(files)}): bundle.json was edited",
        )
    return meta


def migrate_manifest(folder: Path, meta: object) -> dict:
    """``meta`` upgraded to :data:`FORMAT_VERSION`, one step per version (the module docstring
    says what each brought); a BundleError for a version this hrr_garment cannot read."""
    version = meta.get("format_version") if isinstance(meta, dict) else None
    if (
        isinstance(version, bool)
        or not isinstance(version, int)
        or not OLDEST_READABLE <= version <= FORMAT_VERSION
    ):
        hint = (
            "upgrade hrr_garment"
            if isinstance(version, int) and version > FORMAT_VERSION
            else "retrain with hrr-train"
        )
        raise BundleError(
            folder,
            f"bundle format_version {version!r}; this hrr_garment reads {OLDEST_READABLE} to "
            f"{FORMAT_VERSION} ({hint})",
        )
    if version >= 4 and meta.get("manifest_hash") != manifest_hash(meta):
        raise BundleError(
            folder,
            f"bundle.json was edited after it was written (its manifest hash "
            f"{meta.get('manifest_hash')!r} does not match its content): restore it or retrain",
        )
    if version == 2:
        meta = _from_version_2(meta)
    if meta["format_version"] == 3:  # version 4 only added the manifest's own hash
        meta = {**meta, "format_version": 4}
    if meta["format_version"] == 4:  # version 5 named the fold store's encoding; before, always int8
        meta = {**meta, "format_version": 5}
        if isinstance(meta.get("folds"), dict):
            meta["folds"] = {"encoding": "int8", **meta["folds"]}
    return meta


def _from_version_2(meta: dict) -> dict:
    """Version 2 -> 3: the values a field took where a version-2 bundle left it out."""
    meta = {
        **meta,
        "format_version": 3,
        "gate": meta.get("gate", "entropy"),
        "gates": meta.get("gates", {}),
        "validation": meta.get("validation", "clips"),
    }
    if isinstance(meta.get("auto"), dict):
        meta["auto"] = {**UNCALIBRATED_AUTO, **meta["auto"]}
    codespace = meta.get("codespace")
    if isinstance(codespace, dict) and isinstance(codespace.get("config"), dict):
        config = {
            "memory_seconds": [],
            "resonator_hz": [],
            "regression_code": "argmax",
            **codespace["config"],
        }
        meta["codespace"] = {**codespace, "config": config}
    return meta
