"""hrr-make's motion library (hrr_garment.pipeline.make_library): the split is drawn over the whole
library, so a budget's subset holds out the library's own held-out clips; the character's own clips
always train and come first; a selection is a prefix of each part's order within its frames."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from hrr_garment.motion.native_file import save_motion
from hrr_garment.motion.synth import synthesize
from hrr_garment.pipeline.make_budget import BudgetPlan
from hrr_garment.pipeline.make_library import (
    PARTS,
    library_descriptors,
    motion_library,
    ordered_parts,
    select,
    sized_selection,
)
from hrr_garment.sim.build import BuildSettings
from hrr_garment.sim.build_split import split_sources
from hrr_garment.sim.preset import load_preset


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    folder = tmp_path_factory.mktemp("own")
    own = folder / "own_Dance.npz"
    save_motion(synthesize("dance", 3.0, seed=7), own)  # named as hrr-make names them: own_Dance
    preset = replace(load_preset("tiny"), sequences={"walk": 4, "run": 3, "spin": 3, "hop": 3, "idle": 3})
    return motion_library(preset, [own]), folder


def test_the_split_is_the_presets_over_the_whole_library(library):
    lib, _ = library
    library_only = [s for s in lib.specs if s.name not in lib.own]
    drawn = split_sources([s.name for s in library_only], library_only, BuildSettings(**lib.options))
    for part in PARTS:
        assert {n for n in drawn[part]} == {n for n in lib.names if lib.part[n] == part and n not in lib.own}
    assert lib.own == ["own_Dance"] and lib.part["own_Dance"] == "train"
    assert lib.copies == 1  # the tiny preset simulates no mirrors
    assert lib.frames["own_Dance"] == 90 and lib.frames["walk_000"] == 60


def test_selections_are_prefixes_of_their_parts(library):
    lib, folder = library
    described = library_descriptors(lib, folder / "descriptors.npz", progress=False)
    assert set(described) == set(lib.names)
    again = library_descriptors(lib, folder / "descriptors.npz", progress=False)  # read back
    assert all((again[n] == described[n]).all() for n in lib.names)
    for selection in ("coverage", "random"):
        order = ordered_parts(lib, described, selection, probe=2)
        assert order["train"][0] == "own_Dance"  # the character's own clip first
        # then two training clips drawn at random, the same for either selection (the probe's)
        probe = ordered_parts(lib, described, "random", probe=2)["train"][1:3]
        assert order["train"][1:3] == probe
        assert {n for p in PARTS for n in order[p]} == set(lib.names)
        chosen = select(lib, order, 600, test_frames=100, validation=0.25)
        for part in PARTS:
            assert chosen[part] == order[part][: len(chosen[part])]
            assert all(lib.part[n] == part for n in chosen[part])
        assert len(chosen["test"]) >= 2 and len(chosen["val"]) >= 2
        train_frames = sum(lib.frames[n] for n in chosen["train"])
        assert train_frames <= 600 - sum(lib.frames[n] for n in chosen["test"] + chosen["val"]) + 90
    with pytest.raises(ValueError, match="unknown selection"):
        ordered_parts(lib, described, "alphabetical")


def test_a_selection_pays_for_its_lead_ins(library):
    """The simulator runs each sequence's lead-in too: the plan buys the frames the simulator's rate
    pays for, lead-ins included, at the rate the chosen clips give data (a 30-frame lead-in is half
    of a 60-frame clip)."""
    lib, _ = library
    assert lib.lead == 39  # the tiny preset's: settle 0.5 s and blend 0.8 s at 30 frames a second
    order = {part: [n for n in lib.names if lib.part[n] == part] for part in PARTS}
    seconds, simulator = 12.0, 40.0  # what a plan gives the simulation, the simulator's rate

    def plan_at(rate: float) -> BudgetPlan:
        return BudgetPlan(0.0, int(rate * seconds), 1.0, 1.0, {"simulate": seconds}, rate)

    bought = {}
    for lead in (0, 30):
        plan, chosen = sized_selection(
            replace(lib, lead=lead), order, plan_at, simulator_rate=simulator, test_frames=60, validation=0.25
        )
        names = [n for part in PARTS for n in chosen[part]]
        data = sum(lib.frames[n] for n in names)
        bought[lead] = data
        # the rate the plan assumed is the one its clips give: data frames a second
        assert plan.sim_frames_per_s == pytest.approx(simulator * data / (data + lead * len(names)), rel=0.05)
        # what the simulator runs is what the plan pays for, within a clip a part (prefixes of whole
        # clips; the held-out parts keep two clips whatever the budget)
        assert data + lead * len(names) <= simulator * seconds + 3 * (90 + lead)
    assert bought[30] < 0.8 * bought[0]


def test_own_clips_are_found_from_a_relative_folder_and_always_train(tmp_path, monkeypatch):
    """hrr-make -o hero/ gives relative paths; the plan records files resolved: the character's clip
    is still its own (trained, first, never held out, kept by the smallest budget)."""
    monkeypatch.chdir(tmp_path)
    Path("hero/motions").mkdir(parents=True)
    save_motion(synthesize("dance", 3.0, seed=7), Path("hero/motions/own_Dance.npz"))
    preset = replace(load_preset("tiny"), sequences={"walk": 3, "run": 3})
    lib = motion_library(preset, [Path("hero/motions/own_Dance.npz")])
    assert lib.own == ["own_Dance"] and lib.part["own_Dance"] == "train"
    order = ordered_parts(lib, {n: np.zeros((1, 2)) + i for i, n in enumerate(lib.names)}, "random")
    chosen = select(lib, order, 10, test_frames=0, validation=0.1)  # a budget of 10 frames
    assert chosen["train"] == ["own_Dance"]
