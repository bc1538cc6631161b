"""A build's assigned split (BuildSettings.assigned, hrr-make's budget): the parts it names, drawn over
a larger library, hold whatever subset is simulated; mirrors follow their sources; a sequence it does
not name is refused."""

import pytest

from hrr_garment.sim.build import BuildSettings
from hrr_garment.sim.build_split import split_finished
from hrr_garment.sim.plan import SequenceSpec


def _specs(names):
    return [SequenceSpec(n, "walk", seconds=2.0) for n in names]


def test_the_assigned_split_holds_for_any_subset():
    assigned = {"a": "train", "b": "train", "c": "val", "d": "test", "e": "test"}
    options = BuildSettings(assigned=assigned, mirror="simulate")
    done = ["a", "a_mirror", "c", "c_mirror", "e", "e_mirror"]
    split = split_finished(done, _specs(["a", "c", "e"]), options)
    assert split == {"train": ["a", "a_mirror"], "val": ["c", "c_mirror"], "test": ["e", "e_mirror"]}


def test_a_sequence_it_does_not_name_is_refused():
    with pytest.raises(ValueError, match="names no part for"):
        split_finished(["a", "z"], _specs(["a", "z"]), BuildSettings(assigned={"a": "train"}))
