"""A body.json written by hand or by another tool (issue 88): each fault a hostile user found is one
line naming the file and the problem with exit 2, never a traceback, a hang or gigabytes read; a
skeleton upside down or mirrored is refused rather than animated; what is printed as --json is
strict JSON."""

import json
import os

import pytest

from hrr_garment.body.body_file import BodyRecord, read_body, write_body
from hrr_garment.body.capsules import DEFAULT_BODY
from hrr_garment.errors import InputError
from tests.hostile import one_line_error


@pytest.fixture(scope="module")
def body(tmp_path_factory) -> dict:
    """The mannequin's body.json content."""
    record = BodyRecord(DEFAULT_BODY.skeleton, DEFAULT_BODY, DEFAULT_BODY.pelvis_height, stature=1.7)
    path = write_body(tmp_path_factory.mktemp("body") / "mannequin.json", record)
    return json.loads(path.read_text())


def _capsules(change):
    def mutate(data):
        data["capsules"] = change(data["capsules"])

    return mutate


def _offsets(scale_x: float, scale_y: float):
    def mutate(data):
        data["offsets"] = [[x * scale_x, y * scale_y, z] for x, y, z in data["offsets"]]

    return mutate


HOSTILE = {
    "a capsule renamed": (_capsules(lambda c: [{**c[0], "name": "pelvis_bone"}, *c[1:]]), "'capsules' must"),
    "capsules reordered": (_capsules(lambda c: [c[1], c[0], *c[2:]]), "'capsules' must"),
    "hips missing": (_capsules(lambda c: c[1:]), "'capsules' must"),
    "hips twice": (_capsules(lambda c: [c[0], *c]), "'capsules' must"),
    "a capsule on another joint": (
        _capsules(lambda c: [{**c[0], "joint": "head"}, *c[1:]]),
        "'capsules' must",
    ),
    "fit a list": (lambda d: d.update(fit=[1, 2]), "'fit' must be an object"),
    "fit a string": (lambda d: d.update(fit="good"), "'fit' must be an object"),
    "shape of NaN": (lambda d: d.update(shape={"height": float("nan")}), "'shape' must map"),
    "upside down": (_offsets(1.0, -1.0), "upside down"),
    "mirrored": (_offsets(-1.0, 1.0), "mirrored"),
    "a radius of zero": (_capsules(lambda c: [{**c[0], "radius": 0.0}, *c[1:]]), "radius"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_each_fault_is_one_line_naming_the_file(tmp_path, body, case, capsys):
    from hrr_garment.cli.body import main

    mutate, phrase = HOSTILE[case]
    data = json.loads(json.dumps(body))
    mutate(data)
    path = tmp_path / "hostile.json"
    path.write_text(json.dumps(data))  # NaN written as JSON's NaN, as a careless writer does
    err = one_line_error(main, ["info", str(path)], capsys)
    assert str(path) in err and phrase in err, err


def test_the_mannequin_reads_and_prints_strict_json(tmp_path, body, capsys):
    from hrr_garment.cli.body import main

    path = tmp_path / "mannequin.json"
    path.write_text(json.dumps(body))
    assert read_body(path).body.capsules[0].name == "hips"
    assert main(["info", str(path), "--json"]) == 0

    def no_constants(name):
        raise AssertionError(f"{name} in --json output")

    assert json.loads(capsys.readouterr().out, parse_constant=no_constants)["stature_m"] > 1


@pytest.mark.parametrize("kind", ["fifo", "zero", "urandom", "deep"])
def test_special_files_and_deep_nesting_are_refused_at_once(tmp_path, kind):
    path = tmp_path / "body.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "deep":
        path.write_text("[" * 100_000 + "]" * 100_000)
    else:
        path.symlink_to(f"/dev/{kind}")
    phrase = "nested too deep" if kind == "deep" else "not a regular file"
    with pytest.raises(InputError, match=phrase) as err:
        read_body(path)
    assert str(path) in str(err.value)
