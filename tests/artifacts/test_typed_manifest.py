"""bundle.json typed (hrr_garment.artifacts.typed_manifest): read as frozen sections, written back as
the same JSON (unknown keys and nulls included), replaced field by field, and a bad field named."""

import dataclasses
import json
import shutil
from pathlib import Path

import pytest

from hrr_garment.artifacts.auto_calibration import UNCALIBRATED
from hrr_garment.artifacts.manifest import BundleError, manifest_hash, migrate_manifest
from hrr_garment.artifacts.manifest_entries import BodiesEntry, PartEntry, ResidualEntry, SubspaceEntry
from hrr_garment.artifacts.typed_manifest import Manifest, parse_manifest, read_manifest, update_manifest
from tests.conftest import write_meta

FIXTURE = Path(__file__).parents[1] / "fixtures" / "bundle-31b4ef9"


def _fixture_json() -> dict:
    """The version-2 fixture's bundle.json, upgraded to the current version (as a reader sees it)."""
    return migrate_manifest(FIXTURE, json.loads((FIXTURE / "bundle.json").read_text()))


def _with_every_section(meta: dict) -> dict:
    """``meta`` with the sections the fixture lacks, nulls where a writer writes them, and keys no
    section types, at the top and inside sections."""
    return {
        **meta,
        "auto": {**meta["auto"], "residual_free_mm": None, "a_newer_field": [1, {"x": None}]},
        "bodies": {"range": {"bodies": 2}, "default": None, "made_for": None},
        "subspace": {"key": "k", "config": {"hidden": 64}, "components": 16, "candidates_mm": {"16": 8.5}},
        "direct": {"key": "d", "config": {}, "epochs": 3},
        "note": "kept as written",
    }


@pytest.mark.parametrize("every_section", [False, True])
def test_the_json_round_trip_is_exact(every_section):
    meta = _fixture_json()
    meta = _with_every_section(meta) if every_section else meta
    manifest = parse_manifest(FIXTURE, meta)
    again = manifest.to_dict()
    assert json.dumps(again) == json.dumps(meta)  # the same keys, values, nulls and order
    assert manifest_hash(again) == manifest_hash(meta)
    if every_section:  # a null read stays a null, an absent field stays absent
        assert again["auto"]["residual_free_mm"] is None and "folds_free_mm" not in again["auto"]


def test_sections_are_typed_and_frozen():
    manifest = parse_manifest(FIXTURE, _with_every_section(_fixture_json()))
    assert isinstance(manifest.residual, ResidualEntry) and manifest.residual.weight >= 0
    assert isinstance(manifest.subspace, SubspaceEntry) and manifest.subspace.components == 16
    assert manifest.subspace.candidates_mm == {"16": 8.5} and isinstance(manifest.direct, PartEntry)
    assert isinstance(manifest.bodies, BodiesEntry) and manifest.bodies.count == 2
    assert manifest.default_body_is_mannequin and manifest.auto.residual_free_mm is None
    assert manifest.extra["note"] == "kept as written" and manifest.auto.extra["a_newer_field"][0] == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        manifest.tau = 1.0
    with pytest.raises(TypeError):
        manifest.auto.candidates["hybrid"] = {}  # read-only all the way down
    uncalibrated = {k: v for k, v in _fixture_json().items() if k != "auto"}
    assert parse_manifest(FIXTURE, uncalibrated).auto_or_uncalibrated is UNCALIBRATED


def test_a_replaced_field_changes_only_that_field_on_disk(tmp_path):
    folder = shutil.copytree(FIXTURE, tmp_path / "model")
    update_manifest(folder)  # at the current version, with its manifest hash
    before = json.loads((folder / "bundle.json").read_text())
    manifest = read_manifest(folder)
    update_manifest(folder, auto=dataclasses.replace(manifest.auto, mode="hybrid", swing_gain=1.2))
    after = json.loads((folder / "bundle.json").read_text())
    changed = {k for k in before if before[k] != after[k]}
    assert changed == {"auto", "manifest_hash"} and list(after) == list(before)
    assert {k for k in after["auto"] if after["auto"].get(k) != before["auto"].get(k)} == {
        "mode",
        "swing_gain",
    }
    assert read_manifest(folder).auto.mode == "hybrid"
    update_manifest(folder, auto=None)  # an optional section dropped
    assert "auto" not in json.loads((folder / "bundle.json").read_text())
    assert read_manifest(folder).auto is None


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda m: m["auto"].update(swing_gain="x"), r"'auto.swing_gain' must be a finite number"),
        (lambda m: m["database"].update(names="walk"), r"'database.names' must be a list of names"),
        (lambda m: m["codespace"].update(features=1.5), r"'codespace.features' must be a whole number"),
        (lambda m: m.update(bodies={"default": "hero"}), r"'bodies.default' must be an object"),
        (
            lambda m: m["gates"].update(entropy={"tau": -1}),
            r"'gates.entropy.tau' must be a finite number >= 0",
        ),
        (lambda m: m.update(dataset=3), r"'dataset' must be a string"),
    ],
)
def test_a_bad_field_is_named_with_the_folder(tmp_path, change, message):
    folder = shutil.copytree(FIXTURE, tmp_path / "model")
    meta = _fixture_json()
    change(meta)
    write_meta(folder, meta)
    with pytest.raises(BundleError, match=message) as raised:
        read_manifest(folder)
    assert str(folder) in str(raised.value)


def test_a_manifest_built_in_memory_is_checked_as_a_read_one():
    meta = _fixture_json()
    assert Manifest.parse(meta, "bundle.json") == parse_manifest(FIXTURE, meta)
    with pytest.raises(ValueError, match="'residual' must hold a finite 'weight'"):
        ResidualEntry.from_report({"weight": float("nan")}, "residual")  # NaN reads back as null
