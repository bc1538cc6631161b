"""Signed bundles (issue 48): a signature verifies on load, a bundle changed after signing is refused
however it was re-hashed, and trusted keys turn unsigned or foreign bundles into a warning or, when
required, a refusal."""

import json
import shutil
from pathlib import Path

import pytest

pytest.importorskip("cryptography")

from hrr_garment.artifacts.manifest import BundleError, manifest_hash  # noqa: E402
from hrr_garment.artifacts.signature import SIGNATURE_FILE, SignatureWarning  # noqa: E402
from hrr_garment.artifacts.typed_manifest import read_manifest, update_manifest  # noqa: E402
from hrr_garment.cli.sign import main as sign_main  # noqa: E402

FIXTURE = Path(__file__).parents[1] / "fixtures" / "bundle-31b4ef9"


@pytest.fixture
def bundle(tmp_path) -> Path:
    folder = shutil.copytree(FIXTURE, tmp_path / "model")
    update_manifest(folder)
    return folder


@pytest.fixture
def keys(tmp_path) -> tuple[Path, Path]:
    assert sign_main(["keygen", "-o", str(tmp_path / "studio.key")]) == 0
    assert (tmp_path / "studio.key").stat().st_mode & 0o077 == 0  # the private key is its owner's alone
    return tmp_path / "studio.key", tmp_path / "studio.pub"


@pytest.fixture(autouse=True)
def no_trust_settings(monkeypatch):
    monkeypatch.delenv("HRR_TRUSTED_KEYS", raising=False)
    monkeypatch.delenv("HRR_REQUIRE_SIGNATURE", raising=False)


def test_a_signed_bundle_verifies_and_loads(bundle, keys, capsys, monkeypatch):
    assert sign_main(["sign", str(bundle), "--key", str(keys[0])]) == 0
    assert sign_main(["verify", str(bundle)]) == 0
    assert "signature valid" in capsys.readouterr().out
    monkeypatch.setenv("HRR_TRUSTED_KEYS", str(keys[1]))
    monkeypatch.setenv("HRR_REQUIRE_SIGNATURE", "1")
    read_manifest(bundle)


def test_a_bundle_changed_after_signing_is_refused_however_rehashed(bundle, keys):
    assert sign_main(["sign", str(bundle), "--key", str(keys[0])]) == 0
    meta = json.loads((bundle / "bundle.json").read_text())
    meta["tau"] = 0.5  # a forger's edit, every hash recomputed
    meta["manifest_hash"] = manifest_hash(meta)
    (bundle / "bundle.json").write_text(json.dumps(meta))
    with pytest.raises(BundleError, match="made for another bundle.json"):
        read_manifest(bundle)


def test_a_forged_signature_is_refused(bundle, keys, tmp_path):
    assert sign_main(["sign", str(bundle), "--key", str(keys[0])]) == 0
    assert sign_main(["keygen", "-o", str(tmp_path / "other.key")]) == 0
    record = json.loads((bundle / SIGNATURE_FILE).read_text())
    other = json.loads(json.dumps(record))
    other["key"] = (tmp_path / "other.pub").read_text().split()[-1]  # the signature claimed for another key
    (bundle / SIGNATURE_FILE).write_text(json.dumps(other))
    with pytest.raises(BundleError, match="does not verify"):
        read_manifest(bundle)
    (bundle / SIGNATURE_FILE).write_text("{not json")
    with pytest.raises(BundleError, match="unreadable"):
        read_manifest(bundle)


def test_trusted_keys_warn_about_unsigned_bundles_and_require_refuses_them(
    bundle, keys, tmp_path, monkeypatch
):
    monkeypatch.setenv("HRR_TRUSTED_KEYS", str(keys[1]))
    with pytest.warns(SignatureWarning, match="not signed"):
        read_manifest(bundle)
    monkeypatch.setenv("HRR_REQUIRE_SIGNATURE", "1")
    with pytest.raises(BundleError, match="not signed"):
        read_manifest(bundle)
    assert sign_main(["keygen", "-o", str(tmp_path / "other.key")]) == 0
    assert sign_main(["sign", str(bundle), "--key", str(tmp_path / "other.key")]) == 0
    with pytest.raises(BundleError, match="not in HRR_TRUSTED_KEYS"):
        read_manifest(bundle)


def test_requiring_a_signature_without_a_trusted_key_is_an_error(bundle, monkeypatch):
    monkeypatch.setenv("HRR_REQUIRE_SIGNATURE", "1")
    with pytest.raises(BundleError, match="names no key to trust"):
        read_manifest(bundle)


def test_unsigned_bundles_load_as_before_and_verify_says_so(bundle, capsys):
    read_manifest(bundle)
    assert sign_main(["verify", str(bundle)]) == 2
    assert "not signed" in capsys.readouterr().err


def test_keygen_never_overwrites_a_key(keys, capsys):
    assert sign_main(["keygen", "-o", str(keys[0])]) == 2
    assert "already exists" in capsys.readouterr().err


def test_keys_keep_their_kind_and_keygen_never_writes_a_key_over_the_other(bundle, keys, tmp_path, capsys):
    """Issue 88: ``keygen -o mine.pub`` wrote the private key, then the public key over it;
    ``sign --key studio.pub`` signed with a public key; a key file that is a device read forever."""
    assert sign_main(["keygen", "-o", str(tmp_path / "mine.pub")]) == 2
    assert "mine.pub" in capsys.readouterr().err and not (tmp_path / "mine.pub").exists()
    assert sign_main(["sign", str(bundle), "--key", str(keys[1])]) == 2
    err = capsys.readouterr().err
    assert "studio.pub" in err and "public key where a private key is needed" in err
    assert not (bundle / SIGNATURE_FILE).exists()
    labelled_public = keys[1].read_text()
    unlabelled = tmp_path / "old.key"  # a private key from before the labels still signs
    unlabelled.write_text(keys[0].read_text().split()[-1] + "\n")
    assert sign_main(["sign", str(bundle), "--key", str(unlabelled)]) == 0
    swapped = tmp_path / "swapped.key"  # a public key's content under a private key's name
    swapped.write_text(labelled_public)
    assert sign_main(["sign", str(bundle), "--key", str(swapped)]) == 2
    (tmp_path / "zero.key").symlink_to("/dev/zero")
    assert sign_main(["sign", str(bundle), "--key", str(tmp_path / "zero.key")]) == 2
    assert "not a regular file" in capsys.readouterr().err
