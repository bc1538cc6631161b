"""Signed bundles: who made a model that travels between people (issue 48).

A bundle's hashes catch damage, not forgery: whoever edits a model can recompute them. A signature
can only be made with its author's private key. ``hrr-sign sign`` writes ``bundle.sig`` beside
``bundle.json``: an Ed25519 signature (the ``cryptography`` library, the ``sign`` extra) over the
SHA-256 of ``bundle.json``'s bytes, which record the SHA-256 of every other file, so one signature
covers the whole bundle.

On load (:func:`check_signature`, from :func:`~.typed_manifest.read_manifest`):

* a ``bundle.sig`` that does not verify is refused, whatever the settings (the bundle was changed
  after it was signed);
* with trusted public keys (``HRR_TRUSTED_KEYS``: key files, ``os.pathsep``-separated), a bundle
  that is unsigned or signed by another key loads with a :class:`SignatureWarning`, or is refused
  when ``HRR_REQUIRE_SIGNATURE=1``;
* with no trusted keys, unsigned bundles load as before (signing is optional).
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from ..input_files import read_input_text
from ..io_utils import atomic_path
from .manifest import BundleError

SIGNATURE_FILE = "bundle.sig"
SIGNATURE_FORMAT = "hrr_garment bundle signature"
SIGNATURE_VERSION = 1
# a key file's first line, which keeps a public key from being used to sign and a private one from
# being handed out as trusted (the two are 32 bytes of base64 alike)
KEY_LABELS = {"private": "# hrr-sign ed25519 private key", "public": "# hrr-sign ed25519 public key"}
MAX_SIGNATURE_BYTES = 4096  # the file is a few hundred bytes: a larger one is not ours


class SignatureWarning(UserWarning):
    """A bundle loaded although no trusted key signed it (``HRR_REQUIRE_SIGNATURE`` refuses it)."""


def _ed25519():
    try:
        from cryptography.hazmat.primitives.asymmetric import ed25519
    except ImportError:
        raise ImportError(
            "signed bundles need the cryptography library: pip install 'hrr_garment[sign]'"
        ) from None
    return ed25519


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")


def key_id(public: bytes) -> str:
    """A short name for a public key: the first 16 hex digits of its SHA-256."""
    return hashlib.sha256(public).hexdigest()[:16]


def generate_key(private_path: Path) -> Path:
    """A new Ed25519 key pair: the private key (raw, base64) at ``private_path``, readable by its
    owner only, and the public key beside it as ``.pub``; returns the public key's path."""
    ed25519 = _ed25519()
    from cryptography.hazmat.primitives import serialization

    key = ed25519.Ed25519PrivateKey.generate()
    raw = key.private_bytes(
        serialization.Encoding.Raw, serialization.PrivateFormat.Raw, serialization.NoEncryption()
    )
    public = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    private_path = Path(private_path)
    if private_path.suffix == ".pub":
        raise InputError(
            private_path,
            "is where the public key would go (PRIVATE.pub): name the private key otherwise (studio.key)",
        )
    with atomic_path(private_path, private=True) as tmp:
        Path(tmp).write_text(f"{KEY_LABELS['private']}\n{_b64(raw)}\n")
    public_path = private_path.with_suffix(".pub")
    with atomic_path(public_path) as tmp:
        Path(tmp).write_text(f"{KEY_LABELS['public']}\n{_b64(public)}\n")
    return public_path


def _read_key(path: Path, kind: str) -> bytes:
    """The raw key in a key file of hrr-sign keygen; ``kind``: "private" or "public", the file's
    label must say the same (a file without one, from before the labels, is taken as either, but a
    private key is never read from a .pub)."""
    size = 32
    text = read_input_text(path, limit=4096, what="a key file")
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    label = next((line for line in lines if line.startswith("#")), None)
    other = next(k for k in KEY_LABELS if k != kind)
    if label == KEY_LABELS[other] or (label is None and kind == "private" and Path(path).suffix == ".pub"):
        use = "sign with the private key beside it" if kind == "private" else "trust the .pub file"
        raise BundleError(path, f"is a {other} key where a {kind} key is needed: {use}")
    try:
        raw = base64.b64decode("".join(line for line in lines if not line.startswith("#")), validate=True)
    except ValueError as exc:
        raise BundleError(path, f"not a key written by hrr-sign keygen ({exc})") from None
    if len(raw) != size:
        raise BundleError(path, f"not an Ed25519 key: {len(raw)} bytes, expected {size}")
    return raw


def sign_bundle(folder: Path, private_path: Path) -> str:
    """Sign ``folder``'s bundle.json with the private key at ``private_path`` (bundle.sig beside
    it); returns the signing key's :func:`key_id`."""
    ed25519 = _ed25519()
    from cryptography.hazmat.primitives import serialization

    folder = Path(folder)
    key = ed25519.Ed25519PrivateKey.from_private_bytes(_read_key(private_path, "private"))
    digest = hashlib.sha256((folder / "bundle.json").read_bytes()).hexdigest()
    public = key.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    record = {
        "format": SIGNATURE_FORMAT,
        "version": SIGNATURE_VERSION,
        "algorithm": "ed25519",
        "key": _b64(public),
        "bundle_sha256": digest,
        "signature": _b64(key.sign(digest.encode("ascii"))),
    }
    with atomic_path(folder / SIGNATURE_FILE) as tmp:
        Path(tmp).write_text(json.dumps(record, indent=1) + "\n")
    return key_id(public)


@dataclass(frozen=True)
class SignatureCheck:
    """What :func:`verify_signature` found: ``signed`` (a valid signature is present) and by which key."""

    signed: bool
    key: str | None = None  # key_id of the signing key


def verify_signature(folder: Path, bundle_json: bytes) -> SignatureCheck:
    """The bundle's signature checked against ``bundle_json`` (its bytes as read); a BundleError
    when bundle.sig is present but damaged, forged or made for other content."""
    path = Path(folder) / SIGNATURE_FILE
    if not path.exists():
        return SignatureCheck(signed=False)
    if not path.is_file() or path.stat().st_size > MAX_SIGNATURE_BYTES:
        raise BundleError(folder, f"{SIGNATURE_FILE} is not a signature file")
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        ok = (
            isinstance(record, dict)
            and record.get("format") == SIGNATURE_FORMAT
            and record.get("version") == SIGNATURE_VERSION
            and record.get("algorithm") == "ed25519"
        )
        public = base64.b64decode(record["key"], validate=True) if ok else b""
        signature = base64.b64decode(record["signature"], validate=True) if ok else b""
        digest = str(record["bundle_sha256"]) if ok else ""
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, RecursionError) as exc:
        raise BundleError(folder, f"{SIGNATURE_FILE} is unreadable ({exc})") from None
    if not ok or len(public) != 32:
        raise BundleError(folder, f"{SIGNATURE_FILE} is not an Ed25519 bundle signature of this version")
    if digest != hashlib.sha256(bundle_json).hexdigest():
        raise BundleError(
            folder,
            f"{SIGNATURE_FILE} was made for another bundle.json: the bundle changed after it was signed",
        )
    from cryptography.exceptions import InvalidSignature

    try:
        _ed25519().Ed25519PublicKey.from_public_bytes(public).verify(signature, digest.encode("ascii"))
    except InvalidSignature:
        raise BundleError(
            folder, f"{SIGNATURE_FILE} does not verify: forged, or the bundle changed after it was signed"
        ) from None
    return SignatureCheck(signed=True, key=key_id(public))


def trusted_keys() -> dict[str, Path]:
    """key_id -> key file of the public keys in ``HRR_TRUSTED_KEYS``."""
    paths = [p for p in os.environ.get("HRR_TRUSTED_KEYS", "").split(os.pathsep) if p.strip()]
    return {key_id(_read_key(Path(p), "public")): Path(p) for p in paths}


def check_signature(folder: Path, bundle_json: bytes) -> SignatureCheck:
    """The load-time policy of the module docstring for the bundle at ``folder``."""
    trusted = trusted_keys()
    require = os.environ.get("HRR_REQUIRE_SIGNATURE", "") not in ("", "0")
    if require and not trusted:
        raise BundleError(folder, "HRR_REQUIRE_SIGNATURE is set but HRR_TRUSTED_KEYS names no key to trust")
    if not (Path(folder) / SIGNATURE_FILE).exists() and not trusted:
        return SignatureCheck(signed=False)
    check = verify_signature(folder, bundle_json)
    if trusted and check.key not in trusted:
        problem = (
            f"signed by key {check.key}, which is not in HRR_TRUSTED_KEYS"
            if check.signed
            else "not signed (HRR_TRUSTED_KEYS asks for signed bundles)"
        )
        if require:
            raise BundleError(folder, problem)
        warnings.warn(
            f"{folder}: {problem}; loading it anyway (HRR_REQUIRE_SIGNATURE=1 refuses it)",
            SignatureWarning,
            stacklevel=4,
        )
    return check
