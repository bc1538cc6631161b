"""bundle.json, the manifest (hrr_garment.artifacts.manifest): tampered, malformed or unreadable
manifests are refused, saying which and why."""

import json

import numpy as np
import pytest

from hrr_garment.artifacts.manifest import FORMAT_VERSION


def _retamper_hashes(folder, meta, names):
    """Re-hash ``names`` in ``meta`` as a careful tamperer would (so only the check under test can fire)."""
    import hashlib

    for name in names:
        meta["files"][name] = hashlib.sha256((folder / name).read_bytes()).hexdigest()
    meta["content_hash"] = hashlib.sha256(json.dumps(meta["files"], sort_keys=True).encode()).hexdigest()[:16]


def _nan_weights(folder, meta):
    from safetensors.torch import load_file, save_file

    path = folder / "decoder.safetensors"
    state = load_file(str(path))
    key = next(k for k, v in state.items() if v.is_floating_point())
    state[key] = state[key].clone().fill_(float("nan"))
    save_file(state, str(path))
    _retamper_hashes(folder, meta, ["decoder.safetensors"])


def _nan_stats(folder, meta):
    from safetensors.numpy import load_file, save_file

    path = folder / "stats.safetensors"
    arrays = load_file(str(path))
    arrays["latent_std"] = arrays["latent_std"].copy()
    arrays["latent_std"][0] = np.nan
    save_file(arrays, str(path))
    _retamper_hashes(folder, meta, ["stats.safetensors"])


def _escape(folder, meta):
    outside = folder.parent / "secret.txt"
    outside.write_text("not part of the model")
    meta["files"]["../secret.txt"] = ""
    _retamper_hashes(folder, meta, ["../secret.txt"])


def _bad_template_faces(folder, meta):
    """Found by tools/fuzz.py: template faces that index past the vertices, hashes redone."""
    from safetensors.numpy import load_file, save_file

    path = folder / "template.safetensors"
    arrays = load_file(str(path))
    arrays["faces"] = arrays["faces"].copy()
    arrays["faces"][0, 0] = -587202263
    save_file(arrays, str(path))
    _retamper_hashes(folder, meta, ["template.safetensors"])


TAMPERS = {  # name: (edit of bundle.json's dict, or of the folder and dict; the error it must raise)
    "files deleted": (lambda f, m: m.pop("files"), "no valid 'files'"),
    "one file unlisted": (
        lambda f, m: m["files"].pop("decoder.safetensors"),
        r"does not list \['decoder.safetensors'\]",
    ),
    "files as a list": (lambda f, m: m.update(files=list(m["files"])), "no valid 'files'"),
    "path escape": (_escape, "directly in the bundle folder"),
    "content_hash edited": (lambda f, m: m.update(content_hash="0" * 16), "content_hash .* was edited"),
    "tau a string": (lambda f, m: m.update(tau="abc"), "'tau' must be a finite number"),
    "tau NaN": (lambda f, m: m.update(tau=float("nan")), "'tau' must be a finite number"),
    "tau negative": (lambda f, m: m.update(tau=-1.0), "'tau' must be a finite number"),
    "garment a list": (lambda f, m: m.update(garment=["skirt"]), "'garment' must be a name"),
    "database missing": (lambda f, m: m.pop("database"), "lacks its 'database' section"),
    "auto an unknown mode": (
        lambda f, m: m.update(auto={"mode": "retrieval"}),
        "'auto' must hold a 'mode' of",
    ),
    "auto a string": (lambda f, m: m.update(auto="detail"), "'auto' must hold a 'mode' of"),
    "gates missing": (lambda f, m: m.pop("gates"), "'gates' must map gate signals"),
    "a newer format": (
        lambda f, m: m.update(format_version=FORMAT_VERSION + 1),
        f"format_version {FORMAT_VERSION + 1}; .*upgrade hrr_garment",
    ),
    "format 1": (lambda f, m: m.update(format_version=1), "format_version 1; .*retrain"),
    "detail base unknown": (
        lambda f, m: m.update(auto={"mode": "detail", "detail_base": "retrieval"}),
        "'detail_base' must be one of regression, residual",
    ),
    "detail strength negative": (
        lambda f, m: m.update(auto={"mode": "detail", "detail_base": "regression", "detail_strength": -0.5}),
        "'detail_strength' must be a number in",
    ),
    "detail strength NaN": (
        lambda f, m: m.update(
            auto={"mode": "detail", "detail_base": "regression", "detail_strength": float("nan")}
        ),
        "'detail_strength' must be a number in",
    ),
    "NaN weights, hashes redone": (_nan_weights, "decoder.safetensors: non-finite weights"),
    "NaN statistics, hashes redone": (_nan_stats, "stats.safetensors: non-finite values"),
    "template faces out of range, hashes redone": (
        _bad_template_faces,
        "template.safetensors: face indices must lie",
    ),
}


@pytest.mark.parametrize("case", list(TAMPERS))
def test_a_tampered_bundle_is_refused(trained, tmp_path, case):
    import shutil

    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle
    from hrr_garment.artifacts.manifest import manifest_hash

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    meta = json.loads((copy / "bundle.json").read_text())
    edit, message = TAMPERS[case]
    edit(copy, meta)
    meta["manifest_hash"] = manifest_hash(
        meta
    )  # as a careful tamperer would: only the check under test can fire
    (copy / "bundle.json").write_text(json.dumps(meta))
    with pytest.raises(BundleError, match=message):
        load_bundle(copy)


def test_bundle_json_that_is_not_an_object_or_not_text_is_refused(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle

    root, _, _ = trained
    copy = tmp_path / "model"
    shutil.copytree(root / "model", copy)
    (copy / "bundle.json").write_text("[1, 2]")
    with pytest.raises(BundleError, match="format_version None"):
        load_bundle(copy)
    (copy / "bundle.json").write_bytes(b'{"garment": "\xff\xfe"}')
    with pytest.raises(BundleError, match="unreadable"):
        load_bundle(copy)
