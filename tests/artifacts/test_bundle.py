"""Model bundles (hrr_garment.artifacts.bundle): corrupt files and the wrong garment explained, and
bundles written by earlier versions."""

import json

import pytest

from tests.conftest import synthetic_dataset, write_meta


def test_corrupt_bundle_and_wrong_garment_are_explained(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle
    from hrr_garment.data.dataset import DatasetError
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.train.calibrate import evaluate_bundle

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    dress = synthetic_dataset(tmp_path / "dress.h5", make_garment("dress", 300))
    with pytest.raises(DatasetError, match="dress dataset"):
        evaluate_bundle(load_bundle(copy), dress)
    db = copy / "database.safetensors"
    db.write_bytes(db.read_bytes()[:-100])
    with pytest.raises(BundleError, match="database.safetensors.*corrupt or truncated"):
        load_bundle(copy)
    (copy / "bundle.json").unlink()
    with pytest.raises(BundleError, match="no bundle.json"):
        load_bundle(copy)


def test_a_bundle_written_before_the_expected_code_regresses_from_the_argmax(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle_loader import load_bundle

    root, _, _ = trained
    assert load_bundle(root / "model").codespace.config.regression_code == "expected"  # the default now
    shutil.copytree(root / "model", tmp_path / "old")
    meta = json.loads((tmp_path / "old" / "bundle.json").read_text())
    del meta["codespace"]["config"]["regression_code"]
    meta["format_version"] = 2  # version 2 left it out; version 3 writes it
    write_meta(tmp_path / "old", meta)
    assert load_bundle(tmp_path / "old").codespace.config.regression_code == "argmax"
