"""bundle.json: the manifest that makes a folder a model bundle (:mod:`.bundle`), and its checks.

It records the format version, the garment, the calibrated settings (gate, tau, residual weight,
auto mode) and the sha256 of every other file with a content hash over them. :func:`read_meta`
refuses a manifest that is malformed, edited by hand or out of step with its files, and says which
and why; there is no off switch.

Versions: :data:`FORMAT_VERSION` moves whenever a field arrives or changes meaning, and
:func:`migrate_manifest` upgrades an older manifest to the current one in memory, one step per
version, so that everything after it reads every field as the current version defines it.

- 1: garments in world coordinates (not readable: retrain).
- 2: garments in the pelvis-following body frame (:mod:`hrr_garment.motion.frame`); optional
  fields that later arrived one by one (``gate``, ``gates``, ``residual``, ``auto`` and its detail
  look, ``folds``, the code space's motion memory and regression code).
- 3: every calibrated field present with its value: ``gate``, ``gates`` (each other signal's
  calibrated tau), ``validation`` (the code space's: "clips" or the paper's "windows"), ``auto.detail_base`` and ``auto.detail_strength`` wherever ``auto`` is, and the
  code space's ``memory_seconds``, ``resonator_hz`` and ``regression_code``. ``auto`` is absent
  until training calibrates it (``auto`` then runs the hybrid), ``residual`` where the database
  has no motion windows, ``folds``, ``direct`` and ``subspace`` (the fast decoder, which arrived later as an optional
  part) where the bundle has no such part.
- 4: ``manifest_hash``, a hash over bundle.json's own content (everything but itself): the
  content hash covers the files, and a hand-edited garment name, tau or scale went unseen. A
  version-3 manifest has none; it gets one when it is next written.
- 5: ``folds.encoding``, how the fold store holds its frames (``"nf4"`` for new stores, with
  ``folds.vertices``); a version-4 store is ``"int8"``.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

from ..errors import InputError
from ..io_utils import strict_json
from .folds import DETAIL_STRENGTH
from .gate_signals import GATE_SIGNALS

FORMAT_VERSION = 5  # see the module docstring
OLDEST_READABLE = 2  # version 1 kept garments in world coordinates: no step upgrades its networks
NETWORKS = ("motion_encoder", "garment_encoder", "decoder", "quantizer")
FOLDS_FILE = "folds.safetensors"  # the detail mode's simulated folds (.folds)
SUBSPACE_FILE = "subspace.safetensors"  # the run-time decoder sized for games (models/subspace.py)
AUTO_CHOICES = (
    "hybrid",
    "residual",
    "detail",
)  # what mode ``auto`` may stand for (eval/auto_mode.py chooses)
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
    """Every file :func:`.bundle.load_bundle` opens for this bundle: each must be listed with its hash."""
    names = {
        "autoencoder.safetensors",
        "stats.safetensors",
        "database.safetensors",
        "template.safetensors",
        *[f"{n}.safetensors" for n in NETWORKS],
    }
    optional = {"direct": "direct.safetensors", "folds": FOLDS_FILE, "subspace": SUBSPACE_FILE}
    return names | {file for part, file in optional.items() if part in meta}


def check_manifest(folder: Path, meta: object) -> dict:
    """bundle.json's structure, file list and content hash; the integrity check has no off switch."""
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
    garment, tau = meta.get("garment"), meta.get("tau")
    if not isinstance(garment, str) or not garment:
        raise BundleError(folder, f"bundle.json 'garment' must be a name, got {garment!r}")
    if isinstance(tau, bool) or not isinstance(tau, (int, float)) or not math.isfinite(tau) or tau < 0:
        raise BundleError(folder, f"bundle.json 'tau' must be a finite number >= 0, got {tau!r}")
    if meta.get("gate") not in GATE_SIGNALS:
        raise BundleError(
            folder, f"bundle.json 'gate' must be one of {', '.join(GATE_SIGNALS)}, got {meta.get('gate')!r}"
        )
    residual = meta.get("residual", {"weight": 0.0})
    weight = residual.get("weight") if isinstance(residual, dict) else None
    if (
        isinstance(weight, bool)
        or not isinstance(weight, (int, float))
        or not math.isfinite(weight)
        or weight < 0
    ):
        raise BundleError(
            folder, f"bundle.json 'residual' must hold a finite 'weight' >= 0, got {residual!r}"
        )
    if meta.get("validation") not in ("clips", "windows"):
        raise BundleError(
            folder, f"bundle.json 'validation' must be clips or windows, got {meta.get('validation')!r}"
        )
    gates = meta.get("gates")
    if not isinstance(gates, dict) or not all(
        k in GATE_SIGNALS and isinstance(v, dict) for k, v in gates.items()
    ):
        raise BundleError(
            folder, f"bundle.json 'gates' must map gate signals to their calibration, got {gates!r}"
        )
    auto = meta.get("auto", UNCALIBRATED_AUTO)
    if not isinstance(auto, dict) or auto.get("mode") not in AUTO_CHOICES:
        raise BundleError(
            folder, f"bundle.json 'auto' must hold a 'mode' of {', '.join(AUTO_CHOICES)}, got {auto!r}"
        )
    if auto.get("detail_base") not in DETAIL_BASES:
        raise BundleError(
            folder,
            f"bundle.json 'auto' 'detail_base' must be one of {', '.join(DETAIL_BASES)}, "
            f"got {auto.get('detail_base')!r}",
        )
    strength = auto.get("detail_strength")
    if not valid_detail_strength(strength):
        raise BundleError(
            folder,
            f"bundle.json 'auto' 'detail_strength' must be a number in (0, {MAX_DETAIL_STRENGTH:g}], "
            f"got {strength!r}",
        )
    for key in ("residual_free_mm", "folds_free_mm"):  # the residual's and the folds' free-cloth ramps
        ramp = auto.get(key)
        if ramp is not None and not (
            isinstance(ramp, list)
            and len(ramp) == 2
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in ramp)
            and math.isfinite(ramp[0])
            and math.isfinite(ramp[1])
            and ramp[0] < ramp[1]
        ):
            raise BundleError(
                folder, f"bundle.json 'auto' {key!r} must be null or [lo, hi] mm with lo < hi, got {ramp!r}"
            )
    for section in ("autoencoder", "codespace", "database"):
        if not isinstance(meta.get(section), dict):
            raise BundleError(folder, f"bundle.json lacks its {section!r} section")
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


def read_meta(folder: str | Path, trust: bool = True) -> dict:
    """``bundle.json`` after the version, manifest and file-hash checks and (``trust``) the
    signature policy (:mod:`.signature`; hrr-sign itself checks signatures its own way)."""
    folder = Path(folder)
    path = folder / "bundle.json"
    if not folder.is_dir():
        raise BundleError(folder, "no such model directory (train one with hrr-train)")
    if not path.is_file():
        raise BundleError(folder, "no bundle.json: not a model bundle, or its training did not finish")
    from .signature import check_signature  # signature.py raises this module's BundleError

    try:
        raw = path.read_bytes()
        meta = json.loads(raw.decode("utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BundleError(folder, f"bundle.json is unreadable ({exc})") from None
    meta = check_manifest(folder, migrate_manifest(folder, meta))
    for name, digest in meta["files"].items():
        if not (folder / name).is_file():
            raise BundleError(folder, f"{name} is missing")
        if sha256(folder / name) != digest:
            raise BundleError(folder, f"{name} does not match its recorded hash (corrupt or truncated file)")
    if trust:
        check_signature(folder, raw)  # the bytes just checked: a signature over what was read
    return meta
