"""A glTF file from anywhere is checked before any of its arrays is made (issue 88): each rule of
hrr_garment.motion.gltf_checks broken on its own gives exit 2 and one line naming the file and the
property, never a traceback or an allocation the file's bytes do not back; pipes, devices and links
to them are refused before they are opened; a buffer is read from the .gltf's own folder only."""

import base64
import json
import os
from pathlib import Path

import numpy as np
import pytest

from hrr_garment import synthesize
from hrr_garment.errors import MotionError
from hrr_garment.motion.gltf_file import open_gltf
from hrr_garment.motion.io import load_motion
from tests.hostile import one_line_error

from .test_gltf import Rig, write_character

pygltflib = pytest.importorskip("pygltflib")


@pytest.fixture(scope="module")
def document(tmp_path_factory) -> dict:
    """A valid character with one animation as a .gltf's JSON (its buffer a data URI)."""
    path = tmp_path_factory.mktemp("good") / "walk.gltf"
    write_character(path, {"Walk": synthesize("walk", 0.5, seed=0)})
    return json.loads(path.read_text())


def _set(*keys, value):
    def mutate(doc):
        target = doc
        for key in keys[:-1]:
            target = target[key]
        target[keys[-1]] = value

    return mutate


def _many_joints(doc):
    doc["skins"][0]["joints"] = list(range(20022))


# the faults a hostile user found (issue 88), one rule each: (mutation, what the error must say)
BROKEN = {
    "accessor offset negative": (_set("accessors", 0, "byteOffset", value=-4), "accessor 0: byteOffset"),
    "accessor offset past the view": (_set("accessors", 0, "byteOffset", value=1 << 30), "reach byte"),
    "accessor count of a billion": (_set("accessors", 0, "count", value=10**9), "reach byte"),
    "accessor count a float": (_set("accessors", 0, "count", value=12.5), "accessor 0: count"),
    "accessor count zero": (_set("accessors", 0, "count", value=0), "accessor 0: count"),
    "accessor count negative": (_set("accessors", 0, "count", value=-3), "accessor 0: count"),
    "accessor count a string": (_set("accessors", 0, "count", value="12"), "accessor 0: count"),
    "accessor of no view, a billion zeros": (
        lambda d: d["accessors"][0].update(bufferView=None, count=10**9),
        "without a buffer view",
    ),
    "component type unknown": (_set("accessors", 0, "componentType", value=5127), "componentType"),
    "element type a list": (_set("accessors", 0, "type", value=["VEC3"]), "element type"),
    "view stride negative": (_set("bufferViews", 0, "byteStride", value=-12), "bufferView 0: byteStride"),
    "view stride a float": (_set("bufferViews", 0, "byteStride", value=4.5), "bufferView 0: byteStride"),
    "view stride past 252": (_set("bufferViews", 0, "byteStride", value=256), "bufferView 0: byteStride"),
    "view of a missing buffer": (_set("bufferViews", 0, "buffer", value=7), "bufferView 0: buffer must"),
    "view of buffer -1": (_set("bufferViews", 0, "buffer", value=-1), "bufferView 0: buffer must index"),
    "view of buffer '0'": (_set("bufferViews", 0, "buffer", value="0"), "bufferView 0: buffer must index"),
    "view past its buffer": (_set("bufferViews", 0, "byteOffset", value=1 << 20), "reaches byte"),
    "buffer length null": (_set("buffers", 0, "byteLength", value=None), "buffer 0: byteLength"),
    "skin of 20,022 joints": (_many_joints, "20,022 joints"),
    "skin joint a string": (_set("skins", 0, "joints", 0, value="Hips"), "skin 0: a joint"),
    "node translation a string": (_set("nodes", 1, "translation", value="up"), "node 1: translation"),
    "node rotation of NaN": (
        _set("nodes", 1, "rotation", value=[float("nan"), 0, 0, 1]),
        "node 1: rotation",
    ),
    "child of a string": (_set("nodes", 0, "children", value=["1"]), "node 0: a child"),
    "channel of a missing sampler": (
        _set("animations", 0, "channels", 0, "sampler", value=999),
        "animation 0 channel 0: sampler",
    ),
    "channel target path unknown": (
        _set("animations", 0, "channels", 0, "target", "path", value="pose"),
        "target path",
    ),
    "sampler interpolation unknown": (
        _set("animations", 0, "samplers", 0, "interpolation", value="SMOOTH"),
        "interpolation",
    ),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_each_broken_rule_is_one_line_naming_the_file_and_property(tmp_path, document, case, capsys):
    from hrr_garment.cli.motion import main

    mutate, phrase = BROKEN[case]
    doc = json.loads(json.dumps(document))
    mutate(doc)
    path = tmp_path / "hostile.gltf"
    path.write_text(json.dumps(doc))
    err = one_line_error(main, ["info", str(path)], capsys)
    assert str(path) in err and phrase in err, err


def test_the_valid_document_and_a_glb_of_it_still_read(tmp_path, document):
    path = tmp_path / "walk.gltf"
    path.write_text(json.dumps(document))
    assert open_gltf(path).accessor(0).shape[0] > 0
    glb = tmp_path / "walk.glb"
    write_character(glb, {"Walk": synthesize("walk", 0.5, seed=0)}, Rig())
    assert open_gltf(glb).doc.skins[0].joints


def test_a_json_nested_thousands_deep_is_refused(tmp_path, document):
    path = tmp_path / "deep.gltf"
    depth = 200_000
    path.write_text(json.dumps(document)[:-1] + ', "extras": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(MotionError, match="nested too deep"):
        open_gltf(path)


@pytest.mark.parametrize("kind", ["fifo", "device link", "folder"])
def test_pipes_devices_and_folders_are_refused_unopened(tmp_path, kind, capsys):
    from hrr_garment.cli.motion import main

    path = tmp_path / "character.glb"
    if kind == "fifo":
        os.mkfifo(path)  # opening it would wait for a writer forever
    elif kind == "device link":
        path.symlink_to("/dev/zero")  # reading it would never end
    else:
        path.mkdir()
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and "not a regular file" in err


def _external(tmp_path: Path, document: dict, name: str) -> tuple[Path, bytes]:
    """The document as a .gltf whose buffer is the file ``name`` beside it."""
    doc = json.loads(json.dumps(document))
    data = base64.b64decode(doc["buffers"][0]["uri"].split(",", 1)[1])
    doc["buffers"][0]["uri"] = name
    path = tmp_path / "walk.gltf"
    path.write_text(json.dumps(doc))
    return path, data


def test_a_buffer_is_read_from_the_gltf_folder_only(tmp_path, document):
    folder = tmp_path / "asset"
    folder.mkdir()
    path, data = _external(folder, document, "walk.bin")
    (folder / "walk.bin").write_bytes(data)
    assert open_gltf(path).accessor(0).shape[0] > 0  # beside it: read
    outside = tmp_path / "secret.bin"
    outside.write_bytes(data)
    (folder / "link.bin").symlink_to(outside)  # a link out of the folder, resolved before the check
    for name in ("link.bin", "../secret.bin", str(outside)):
        path, _ = _external(folder, document, name)
        with pytest.raises(MotionError, match="not a file beside the .gltf"):
            open_gltf(path).accessor(0)
    (folder / "zero.bin").symlink_to("/dev/zero")
    path, _ = _external(folder, document, "zero.bin")
    with pytest.raises(MotionError, match="not a file beside the .gltf|not a regular file"):
        open_gltf(path).accessor(0)
    (folder / "pipe.bin").unlink(missing_ok=True)
    os.mkfifo(folder / "pipe.bin")
    path, _ = _external(folder, document, "pipe.bin")
    with pytest.raises(MotionError, match="not a regular file"):
        open_gltf(path).accessor(0)


def test_an_output_never_replaces_a_buffer_the_command_read(tmp_path, document, capsys):
    """``hrr-motion features walk.gltf -o data.npy`` where the .gltf's buffer is data.npy."""
    from hrr_garment.cli.motion import main

    path, data = _external(tmp_path, document, "data.npy")
    (tmp_path / "data.npy").write_bytes(data)
    assert main(["features", str(path), "-o", str(tmp_path / "data.npy")]) == 2
    err = capsys.readouterr().err
    assert "data.npy" in err and "destroy the input" in err
    assert (tmp_path / "data.npy").read_bytes() == data
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data.npy", "walk.gltf"]


def _float_span(doc: dict, index: int) -> tuple[int, int]:
    """The bytes of float accessor ``index`` in the document's one buffer."""
    accessor = doc["accessors"][index]
    start = doc["bufferViews"][accessor["bufferView"]].get("byteOffset", 0) + accessor.get("byteOffset", 0)
    return start, start + 4 * accessor["count"] * {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[accessor["type"]]


def _keys_changed(document: dict, path: str, change) -> dict:
    """The document with the first ``path`` channel's key values changed by ``change``."""
    doc = json.loads(json.dumps(document))
    head, encoded = doc["buffers"][0]["uri"].split(",", 1)
    data = bytearray(base64.b64decode(encoded))
    animation = doc["animations"][0]
    channel = next(c for c in animation["channels"] if c["target"]["path"] == path)
    start, end = _float_span(doc, animation["samplers"][channel["sampler"]]["output"])
    data[start:end] = change(np.frombuffer(bytes(data[start:end]), "<f4")).astype("<f4").tobytes()
    doc["buffers"][0]["uri"] = f"{head},{base64.b64encode(bytes(data)).decode()}"
    return doc


@pytest.mark.parametrize(
    "path, change, phrase",
    [
        ("rotation", lambda q: 0 * q, "is no rotation"),
        ("rotation", lambda q: 3 * q, "is no rotation"),
        ("translation", lambda t: t + 1e30, r"beyond 1e\+06 file units"),
        ("translation", lambda t: t + 1e5, "the pelvis goes"),  # within a file's units, too far in metres
    ],
)
def test_keys_that_are_no_transform_are_refused_naming_the_file(
    tmp_path, document, path, change, phrase, capsys
):

    hostile = tmp_path / "keys.gltf"
    hostile.write_text(json.dumps(_keys_changed(document, path, change)))
    with pytest.raises(MotionError, match=phrase) as err:
        load_motion(hostile)
    assert str(err.value).startswith(f"{hostile}: ")


def test_two_keys_ten_hours_apart_are_refused_before_they_are_sampled(tmp_path, document):
    """A 294 KB GLB whose two keys lay 35,000 s apart took 5.9 GB and 127 s: the span a file's keys
    may cover follows how many keys it holds."""
    doc = json.loads(json.dumps(document))
    head, encoded = doc["buffers"][0]["uri"].split(",", 1)
    data = bytearray(base64.b64decode(encoded))
    for sampler in doc["animations"][0]["samplers"]:
        accessor = doc["accessors"][sampler["input"]]
        start = doc["bufferViews"][accessor["bufferView"]].get("byteOffset", 0) + accessor.get(
            "byteOffset", 0
        )
        times = np.frombuffer(bytes(data[start : start + 4 * accessor["count"]]), "<f4").copy()
        times[-1] = 35_000.0
        data[start : start + 4 * accessor["count"]] = times.astype("<f4").tobytes()
        accessor["max"] = [35_000.0]
    doc["buffers"][0]["uri"] = f"{head},{base64.b64encode(bytes(data)).decode()}"
    path = tmp_path / "span.gltf"
    path.write_text(json.dumps(doc))
    with pytest.raises(MotionError, match="spans 35,000 s with 15 keys"):
        load_motion(path)
