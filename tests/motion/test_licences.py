"""Motion sources and their licences: which source an entry is, what a set of sequences may do."""

import pytest

from hrr_garment.motion.licences import SOURCES, MotionLicences, entry_source, licences_of


@pytest.mark.parametrize(
    ("entry", "declared", "source"),
    [
        ("mocap:bandai/clips.tar.xz", None, "bandai"),
        ("mocap:cmu/*.bvh", None, "cmu"),
        ("mocap:cmu-01-09/clips.tar.xz", None, "cmu"),
        ("mocap:somewhere-new/x.bvh", None, "own"),  # a shared folder nobody has declared
        ("/data/my_takes/*.bvh", None, "own"),
        ("/data/copied_bandai/", "bandai", "bandai"),  # declared: a copy elsewhere keeps its terms
    ],
)
def test_an_entry_is_the_source_it_declares_else_its_shared_folders(entry, declared, source):
    assert entry_source(entry, declared) == source


def test_an_unknown_declared_source_is_refused_naming_the_known_ones():
    with pytest.raises(ValueError, match="unknown motion source 'mixamo'.*bandai.*cmu"):
        entry_source("x.bvh", "mixamo")


def _info(sources: dict[str, str]) -> dict:
    used = {p for v in sources.values() for p in v.split("+")}
    return {"motion_sources": sources, "sources": {k: SOURCES[k].to_dict() for k in used}}


def test_one_non_commercial_clip_bars_the_whole_model():
    info = _info({"walk_000": "procedural", "02_01": "cmu", "dataset-1_walk_sad_001": "bandai"})
    clean = licences_of(["walk_000", "02_01"], info)
    assert clean.commercial is True and clean.sequences == {"procedural": 1, "cmu": 1}
    assert clean.statement.startswith("may ship commercially")
    assert clean.credits == [SOURCES["cmu"].credit]  # the procedural source asks for none
    barred = licences_of(["walk_000", "02_01", "dataset-1_walk_sad_001"], info)
    assert barred.commercial is False
    assert "NOT for commercial use" in barred.statement and "CC BY-NC 4.0" in barred.statement
    assert "real-quick-commercial" in barred.statement  # and what to use instead


def test_a_splice_counts_both_its_sources():
    info = _info({"splice_000": "bandai+cmu", "backward_000": "cmu"})
    licences = licences_of(["splice_000", "backward_000"], info)
    assert licences.sequences == {"bandai": 1, "cmu": 2} and licences.commercial is False


def test_unrecorded_sequences_leave_commercial_use_unknown_unless_a_known_one_bars_it():
    info = _info({"walk_000": "procedural", "dataset-1_bow_old_003": "bandai"})
    unknown = licences_of(["walk_000", "from_an_old_build"], info)
    assert unknown.commercial is None and unknown.unrecorded == 1 and "unknown" in unknown.statement
    assert licences_of(["dataset-1_bow_old_003", "from_an_old_build"], info).commercial is False
    assert licences_of(["a", "b"], {}).commercial is None  # a dataset from before sources were recorded


def test_the_terms_recorded_in_a_file_win_over_todays_table():
    info = _info({"clip": "cmu"})
    info["sources"]["cmu"] = {**info["sources"]["cmu"], "commercial": False, "licence": "as it stood then"}
    assert licences_of(["clip"], info).commercial is False


def test_the_record_round_trips_through_json():
    licences = licences_of(["a", "b", "c"], _info({"a": "bandai", "b": "cmu", "c": "procedural"}))
    again = MotionLicences.from_dict(licences.to_dict())
    assert again == licences and again.statement == licences.statement
