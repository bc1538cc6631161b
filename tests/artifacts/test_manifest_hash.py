"""Every byte of a bundle's manifest counted: bundle.json's own content under its manifest hash,
and the fields a forger could re-hash checked for type and range at load (issue 48, reproducers
1-3)."""

import json
import shutil
from pathlib import Path

import pytest

from hrr_garment.artifacts.bundle_loader import load_bundle
from hrr_garment.artifacts.manifest import BundleError, manifest_hash
from hrr_garment.artifacts.typed_manifest import read_manifest, update_manifest

FIXTURE = Path(__file__).parents[1] / "fixtures" / "bundle-31b4ef9"


@pytest.fixture
def bundle(tmp_path) -> Path:
    """The version-2 fixture, written again: now at the current version, with its manifest hash."""
    folder = shutil.copytree(FIXTURE, tmp_path / "model")
    update_manifest(folder)
    meta = json.loads((folder / "bundle.json").read_text())
    assert meta["format_version"] == 5 and meta["manifest_hash"] == manifest_hash(meta)
    return folder


def _edit(folder: Path, change, rehash: bool = False) -> None:
    meta = json.loads((folder / "bundle.json").read_text())
    change(meta)
    if rehash:  # as a forger would: the manifest hash recomputed over the edit
        meta["manifest_hash"] = manifest_hash(meta)
    (folder / "bundle.json").write_text(json.dumps(meta))


@pytest.mark.parametrize(
    "change",
    [
        lambda m: m.update(garment="dress"),  # a skirt model passed off as a dress model
        lambda m: m.update(tau=1e308),
        lambda m: m["autoencoder"].update(scale=1000.0),
        lambda m: m["folds"].update(passes=1_000_000),  # a hang at run time
        lambda m: m["codespace"]["config"].update(window=-5),
    ],
)
def test_an_edited_manifest_is_refused(bundle, change):
    _edit(bundle, change)
    with pytest.raises(BundleError, match="was edited after it was written"):
        read_manifest(bundle)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda m: m["autoencoder"].update(scale="x"), "scale must be a number"),
        (lambda m: m["autoencoder"].update(scale=1000.0), "scale must be a number above 0 and at most 10"),
        (lambda m: m["folds"].update(passes=1_000_000), "fold passes must be a whole number from 1 to 16"),
        (
            lambda m: m["codespace"]["config"].update(window=-5),
            "window must be a whole number from 1 to 1000",
        ),
        (
            lambda m: m["autoencoder"]["config"].update(latent_fraction=-1),
            "latent_fraction must be a number above 0",
        ),
    ],
)
def test_a_re_hashed_manifest_still_has_its_values_checked(bundle, change, message):
    _edit(bundle, change, rehash=True)
    with pytest.raises(BundleError, match=message):
        load_bundle(bundle)


def test_a_manifest_written_again_stays_valid_and_a_version_3_one_still_loads(bundle, tmp_path):
    update_manifest(bundle, extra={"note": "calibrated again"})  # a key the manifest does not type
    assert read_manifest(bundle).extra["note"] == "calibrated again"
    assert json.loads((bundle / "bundle.json").read_text())["note"] == "calibrated again"
    old = shutil.copytree(bundle, tmp_path / "v3")
    _edit(old, lambda m: (m.update(format_version=3), m.pop("manifest_hash")))
    assert read_manifest(old).format_version == 5  # before the manifest hash: read as it was
