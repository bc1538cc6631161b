"""hrr-make's record (hrr_garment.pipeline.make_record): a stage is current only for the inputs it was
made from, the record reads back what was written, and a newer format is refused."""

import json

import pytest

from hrr_garment.errors import InputError
from hrr_garment.pipeline.make_record import MakeRecord, content_key, file_key


def test_a_stage_is_current_for_its_own_inputs(tmp_path):
    record = MakeRecord.open(tmp_path / "out")
    key = content_key(["body", "abc"])
    assert not record.current("body", key)
    record.plan["estimates"] = {"body": 4.0}
    record.finish("body", key, 3.5, {"animations": ["Walk"]})
    again = MakeRecord.open(tmp_path / "out")
    assert again.current("body", key)
    assert not again.current("body", content_key(["body", "abd"]))
    assert again.stages["body"] == {"key": key, "seconds": 3.5, "estimate_s": 4.0, "animations": ["Walk"]}
    again.forget(["body"])
    assert not MakeRecord.open(tmp_path / "out").current("body", key)


def test_keys_follow_content_not_paths(tmp_path):
    a, b = tmp_path / "a.obj", tmp_path / "b.obj"
    a.write_text("v 0 0 0\n")
    b.write_text("v 0 0 0\n")
    assert file_key(a) == file_key(b)
    b.write_text("v 0 0 1\n")
    assert file_key(a) != file_key(b)
    assert content_key(["x", 1]) != content_key(["x", 2])
    assert content_key([tmp_path]) == content_key([str(tmp_path)])


def test_a_newer_or_broken_record_is_refused(tmp_path):
    (tmp_path / "make.json").write_text(json.dumps({"format": 99}))
    with pytest.raises(InputError, match="newer hrr-make"):
        MakeRecord.open(tmp_path)
    (tmp_path / "make.json").write_text("{")
    with pytest.raises(InputError, match="cannot read"):
        MakeRecord.open(tmp_path)
