"""bundle.json: the manifest that makes a folder a model bundle (:mod:`.bundle`), and its checks.

It records the format version, the garment, the calibrated settings (gate, tau, residual weight,
auto mode) and the sha256 of every other file with a content hash over them. :func:`read_meta`
refuses a manifest that is of another version, malformed, edited by hand or out of step with its
files, and says which and why; there is no off switch.
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

from ..errors import InputError
from .gate_signals import GATE_SIGNALS

FORMAT_VERSION = 2  # 2: garments in the pelvis-following body frame (motion/frame.py)
NETWORKS = ("motion_encoder", "garment_encoder", "decoder", "quantizer")
FOLDS_FILE = "folds.safetensors"  # the detail mode's simulated folds (.folds), in bundles since 2026-11-25
AUTO_CHOICES = ("hybrid", "residual", "detail")  # what mode ``auto`` may stand for (eval/auto_mode.py chooses)
DETAIL_BASES = ("regression", "residual")  # what the detail mode's folds may ride on (eval/auto_mode.py chooses)
MAX_DETAIL_STRENGTH = 2.0  # the detail mode's folds at most twice the simulated ones (eval/auto_mode.py chooses)


def valid_detail_strength(value: object) -> bool:
    """Whether ``value`` is a strength the detail mode's folds may run at: a number in (0, max]."""
    return not isinstance(value, bool) and isinstance(value, (int, float)) and 0 < value <= MAX_DETAIL_STRENGTH


class BundleError(InputError):
    """A model directory that is missing, incomplete, corrupt, of another version or garment."""


def sha256(path: Path) -> str:
    """The file's sha256, hex."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def content_hash(files: dict[str, str]) -> str:
    """16 hex digits over the file list (name -> sha256): one name for the model's contents."""
    return hashlib.sha256(json.dumps(files, sort_keys=True).encode()).hexdigest()[:16]


def required_files(meta: dict) -> set[str]:
    """Every file :func:`.bundle.load_bundle` opens for this bundle: each must be listed with its hash."""
    names = {"autoencoder.safetensors", "stats.safetensors", "database.safetensors", "template.safetensors",
             *[f"{n}.safetensors" for n in NETWORKS]}
    return names | ({"direct.safetensors"} if "direct" in meta else set()) | ({FOLDS_FILE} if "folds" in meta else set())


def check_manifest(folder: Path, meta: object) -> dict:
    """bundle.json's structure, file list and content hash; the integrity check has no off switch."""
    if not isinstance(meta, dict):
        raise BundleError(folder, f"bundle.json holds a {type(meta).__name__}, not an object")
    files = meta.get("files")
    if not isinstance(files, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in files.items()):
        raise BundleError(folder, "bundle.json has no valid 'files' list (file name -> sha256): refusing an unverifiable model")
    unlisted = sorted(required_files(meta) - set(files))
    if unlisted:
        raise BundleError(folder, f"bundle.json does not list {unlisted} with their hashes: refusing an unverifiable model")
    for name in files:
        if name != Path(name).name or name in ("", ".", "..") or "\\" in name:
            raise BundleError(folder, f"bundle.json lists {name!r}: bundle files must lie directly in the bundle folder")
    if meta.get("content_hash") != content_hash(files):
        raise BundleError(folder, f"content_hash {meta.get('content_hash')!r} does not match the file list "
                                  f"({content_hash(files)}): bundle.json was edited")
    garment, tau = meta.get("garment"), meta.get("tau")
    if not isinstance(garment, str) or not garment:
        raise BundleError(folder, f"bundle.json 'garment' must be a name, got {garment!r}")
    if isinstance(tau, bool) or not isinstance(tau, (int, float)) or not math.isfinite(tau) or tau < 0:
        raise BundleError(folder, f"bundle.json 'tau' must be a finite number >= 0, got {tau!r}")
    if meta.get("gate", "entropy") not in GATE_SIGNALS:
        raise BundleError(folder, f"bundle.json 'gate' must be one of {', '.join(GATE_SIGNALS)}, got {meta.get('gate')!r}")
    residual = meta.get("residual", {"weight": 0.0})
    weight = residual.get("weight") if isinstance(residual, dict) else None
    if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not math.isfinite(weight) or weight < 0:
        raise BundleError(folder, f"bundle.json 'residual' must hold a finite 'weight' >= 0, got {residual!r}")
    auto = meta.get("auto", {"mode": "hybrid"})
    if not isinstance(auto, dict) or auto.get("mode") not in AUTO_CHOICES:
        raise BundleError(folder, f"bundle.json 'auto' must hold a 'mode' of {', '.join(AUTO_CHOICES)}, got {auto!r}")
    if auto.get("detail_base", "regression") not in DETAIL_BASES:
        raise BundleError(folder, f"bundle.json 'auto' 'detail_base' must be one of {', '.join(DETAIL_BASES)}, "
                                  f"got {auto.get('detail_base')!r}")
    strength = auto.get("detail_strength", 1.0)
    if not valid_detail_strength(strength):
        raise BundleError(folder, f"bundle.json 'auto' 'detail_strength' must be a number in (0, {MAX_DETAIL_STRENGTH:g}], "
                                  f"got {strength!r}")
    for section in ("autoencoder", "codespace", "database"):
        if not isinstance(meta.get(section), dict):
            raise BundleError(folder, f"bundle.json lacks its {section!r} section")
    return meta


def read_meta(folder: str | Path) -> dict:
    """``bundle.json`` after the version, manifest and file-hash checks."""
    folder = Path(folder)
    path = folder / "bundle.json"
    if not folder.is_dir():
        raise BundleError(folder, "no such model directory (train one with hrr-train)")
    if not path.is_file():
        raise BundleError(folder, "no bundle.json: not a model bundle, or its training did not finish")
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BundleError(folder, f"bundle.json is unreadable ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format_version") != FORMAT_VERSION:
        version = meta.get("format_version") if isinstance(meta, dict) else None
        raise BundleError(folder, f"bundle format_version {version!r}; this hrr_garment reads {FORMAT_VERSION} "
                                  "(retrain with hrr-train)")
    check_manifest(folder, meta)
    for name, digest in meta["files"].items():
        if not (folder / name).is_file():
            raise BundleError(folder, f"{name} is missing")
        if sha256(folder / name) != digest:
            raise BundleError(folder, f"{name} does not match its recorded hash (corrupt or truncated file)")
    return meta
