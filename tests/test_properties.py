"""Property-based tests (hypothesis) over the parsers and loaders: whatever the input, each one
either returns a finite, plausible result or raises its one documented error type naming the file.
Bounded (a fixed number of examples each, derandomized) so that `make test` stays quick; the wider
search through the real command-line tools is tools/fuzz.py."""

from __future__ import annotations

import json
import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hrr_garment import save_amass, save_motion, synthesize
from hrr_garment.artifacts.bundle import BundleError
from hrr_garment.artifacts.typed_manifest import read_manifest
from hrr_garment.data.dataset import DatasetError, _json_attr
from hrr_garment.errors import InputError, MotionError
from hrr_garment.io_utils import strict_json
from hrr_garment.motion.bvh_write import write_bvh
from hrr_garment.motion.io import load_motion
from hrr_garment.motion.limits import check_source_fps
from hrr_garment.motion.skeleton import CANONICAL, JOINT_NAMES, PARENTS
from tests.conftest import write_meta

# HRR_PROPERTY_EXAMPLES raises the count for a longer search than make test's
BOUNDED = settings(
    max_examples=int(os.environ.get("HRR_PROPERTY_EXAMPLES", "60")),
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

ODD_NUMBERS = st.sampled_from(
    ["nan", "inf", "-inf", "1e308", "-1e308", "0", "-0", "1e-320", "1e6", "x", "", "1e999"]
)


@pytest.fixture(scope="module")
def seeds(tmp_path_factory) -> dict[str, Path]:
    """A valid BVH, native npz and AMASS npz of a short walk, for the mutations below."""
    folder = tmp_path_factory.mktemp("seeds")
    motion = synthesize("walk", 0.5, seed=3)
    write_bvh(
        folder / "walk.bvh",
        list(JOINT_NAMES),
        list(PARENTS),
        CANONICAL.offsets,
        motion.local_rotations.astype(np.float64),
        motion.root_translation,
        1 / 30,
    )
    save_motion(motion, folder / "walk.npz")
    save_amass(motion, folder / "amass.npz")
    return {"bvh": folder / "walk.bvh", "native": folder / "walk.npz", "amass": folder / "amass.npz"}


def _loads_or_refuses(path: Path) -> None:
    """The property every motion loader keeps: a finite motion, or a MotionError naming the file."""
    try:
        motion = load_motion(path)
    except MotionError as exc:
        assert str(path) in str(exc) and "\n" not in str(exc).strip()
        return
    assert motion.num_frames >= 1
    assert np.isfinite(motion.local_rotations).all() and np.isfinite(motion.root_translation).all()
    assert np.isfinite(motion.joint_positions).all()


@BOUNDED
@given(edits=st.lists(st.tuples(st.integers(0, 10**6), ODD_NUMBERS), min_size=1, max_size=6))
def test_bvh_with_numbers_replaced_loads_or_is_refused(seeds, tmp_path, edits):
    text = seeds["bvh"].read_text()
    tokens = text.split(" ")
    for where, value in edits:
        tokens[where % len(tokens)] = value
    path = tmp_path / "edited.bvh"
    path.write_text(" ".join(tokens))
    _loads_or_refuses(path)


@BOUNDED
@given(
    cut=st.integers(0, 10**6), drop=st.lists(st.integers(0, 10**6), max_size=4), junk=st.binary(max_size=64)
)
def test_bvh_truncated_or_with_lines_dropped_loads_or_is_refused(seeds, tmp_path, cut, drop, junk):
    lines = seeds["bvh"].read_bytes().split(b"\n")
    for d in drop:
        lines.pop(d % len(lines))
    data = b"\n".join(lines)
    path = tmp_path / "cut.bvh"
    path.write_bytes(data[: cut % (len(data) + 1)] + junk)
    _loads_or_refuses(path)


_DTYPES = st.sampled_from(
    ["float64", "float32", "float16", "int64", "int8", "uint8", "bool", "complex64", "U4", "S4"]
)


@BOUNDED
@given(
    which=st.sampled_from(["native", "amass"]),
    key_index=st.integers(0, 100),
    dtype=_DTYPES,
    scale=st.sampled_from([1.0, 0.0, -1.0, 1e3, 1e300, math.nan, math.inf]),
    frames=st.integers(0, 3),
    drop=st.booleans(),
)
def test_npz_with_a_changed_array_loads_or_is_refused(
    seeds, tmp_path, which, key_index, dtype, scale, frames, drop
):
    with np.load(seeds[which]) as z:
        arrays = dict(z)
    key = sorted(arrays)[key_index % len(arrays)]
    if drop:
        del arrays[key]
    else:
        value = arrays[key]
        if value.dtype.kind in "fiu":
            with np.errstate(all="ignore"):
                value = value * scale
            if value.ndim and frames < 3:
                value = value[:frames]
        try:
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # casts that overflow: intended
                arrays[key] = value.astype(dtype)
        except (TypeError, ValueError):
            arrays[key] = np.zeros(value.shape, dtype)
    path = tmp_path / "changed.npz"
    np.savez(path, **arrays)
    _loads_or_refuses(path)


@BOUNDED
@given(rate=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10**12), 10**12)))
def test_frame_rates_are_plausible_or_refused(rate):
    try:
        got = check_source_fps(rate, "clip.bvh")
    except MotionError as exc:
        assert "clip.bvh" in str(exc)
        return
    assert math.isfinite(got) and 1 <= got <= 1000


JSON = st.recursive(
    st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=12,
)


@pytest.fixture(scope="module")
def bundle_json(trained) -> dict:
    root, _, _ = trained
    return json.loads((root / "model" / "bundle.json").read_text())


@BOUNDED
@given(
    key=st.sampled_from(
        ["files", "content_hash", "garment", "tau", "autoencoder", "codespace", "database", "format_version"]
    ),
    value=JSON,
)
def test_bundle_json_with_any_value_in_a_key_is_verified_or_refused(
    trained, bundle_json, tmp_path, key, value
):
    import shutil

    root, _, _ = trained
    folder = tmp_path / "model"
    if not folder.exists():
        shutil.copytree(root / "model", folder)
    meta = {**bundle_json, key: value}
    write_meta(folder, meta)
    try:
        manifest = read_manifest(folder)
    except BundleError as exc:
        assert str(folder) in str(exc)
        return
    # accepted: then the manifest is intact and every value the loader relies on has its type
    assert manifest.files == bundle_json["files"] and manifest.content_hash == bundle_json["content_hash"]
    assert isinstance(manifest.garment, str) and math.isfinite(manifest.tau) and manifest.tau >= 0


@BOUNDED
@given(value=JSON)
def test_strict_json_is_json_and_keeps_every_finite_number(value):
    text = strict_json(value)
    back = json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict constant {c}"))

    def same(a, b) -> bool:
        if isinstance(a, float) and not math.isfinite(a):
            return b is None
        if isinstance(a, dict):
            return set(map(str, a)) == set(b) and all(same(v, b[str(k)]) for k, v in a.items())
        if isinstance(a, (list, tuple)):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
        return a == b

    assert same(value, back)


@BOUNDED
@given(raw=st.one_of(st.text(max_size=40), JSON.map(json.dumps)), default=st.sampled_from([{}, []]))
def test_dataset_json_attributes_have_their_type_or_are_refused(raw, default):
    try:
        value = _json_attr(Path("data.h5"), {"info": raw}, "info", default)
    except DatasetError as exc:
        assert "data.h5" in str(exc) and "info" in str(exc)
        return
    assert isinstance(value, type(default))


def test_the_loaders_raise_only_input_errors():
    """The properties above accept MotionError, BundleError and DatasetError: all are InputErrors,
    which every command turns into one line and exit status 2."""
    assert all(issubclass(e, InputError) for e in (MotionError, BundleError, DatasetError))
