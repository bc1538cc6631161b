"""Ensemble ground truth: the scores on hand-computed cases, and perturbed members simulated once."""

from __future__ import annotations

import numpy as np
import pytest

from hrr_garment.eval.ensemble_metrics import (
    energy_score_mm,
    ensemble_metrics,
    ensemble_ratios,
    mean_pairwise_mm,
)
from hrr_garment.eval.metrics import MeshTopology
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.synth import synthesize


def _shifted(base: np.ndarray, dx_mm: float) -> np.ndarray:
    out = base.copy()
    out[..., 0] += dx_mm / 1000.0
    return out


@pytest.fixture(scope="module")
def skirt():
    """A skirt standing still on a still body for one second."""
    from hrr_garment.motion.motion import Motion
    from hrr_garment.motion.skeleton import REST_PELVIS_HEIGHT

    garment = make_garment("skirt", 200)
    motion = Motion(
        np.broadcast_to(np.eye(3, dtype=np.float32), (30, 22, 3, 3)).copy(),
        np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (30, 1)),
    )
    base = np.broadcast_to(garment.vertices, (motion.num_frames, *garment.vertices.shape)).astype(np.float64)
    return garment, motion, base, MeshTopology.of(garment.faces, garment.num_vertices)


def test_floor_pve_and_energy_score_on_hand_computed_cases(skirt):
    _, _, base, _ = skirt
    d = 6.0
    two = np.stack([_shifted(base, -d), _shifted(base, d)])
    assert mean_pairwise_mm(two) == pytest.approx(2 * d)
    # the midpoint: d from each member; energy d - 1/2 * mean(0, 2d, 2d, 0) = d / 2
    assert energy_score_mm(base, two) == pytest.approx(d / 2)
    # the two members as two samples: the same distribution, score 0
    assert energy_score_mm(two, two) == pytest.approx(0.0, abs=1e-9)
    three = np.stack([base, _shifted(base, d), _shifted(base, 2 * d)])
    assert mean_pairwise_mm(three) == pytest.approx(4 * d / 3)  # pairs d, 2d, d
    # the middle member: 2d/3 from the members, minus half of 8d/9 (nine ordered pairs, diagonal 0)
    assert energy_score_mm(three[1], three) == pytest.approx(2 * d / 3 - 4 * d / 9)
    # a prediction far off scores its distance beyond the members' own spread
    assert energy_score_mm(_shifted(base, 100 * d), two) == pytest.approx(100 * d - d / 2)


def test_ensemble_metrics_rank_a_member_and_the_blurry_mean(skirt):
    garment, motion, base, topo = skirt
    t = np.arange(motion.num_frames) / motion.fps
    hem = garment.groups["hem"]
    members = []
    for phase in (0.0, np.pi):  # the hem swinging 3 cm either way, in opposite phase
        v = base.copy()
        v[:, hem, 0] += 0.03 * np.sin(2 * np.pi * 1.5 * t + phase)[:, None]
        members.append(v)
    members = np.stack(members)
    rest = garment.vertices.astype(np.float64)
    as_member = ensemble_metrics(members[0], members, motion, rest, topo, hem)
    as_mean = ensemble_metrics(members.mean(0), members, motion, rest, topo, hem)
    r_member, r_mean = ensemble_ratios(as_member), ensemble_ratios(as_mean)
    # a member moves as the truths do; the mean of two opposite swings does not move at all
    for key in ("acceleration_ratio", "hem_swing_ratio"):
        assert r_member[key] == pytest.approx(1.0, rel=1e-6) and r_mean[key] < 0.02
    assert r_member["pve_floor_ratio"] == pytest.approx(0.5)  # 0 to itself, the floor to the other
    assert as_mean["pve_ensemble_mean_mm"] == pytest.approx(0.0, abs=1e-9)
    assert as_member["pve_ensemble_mean_mm"] == pytest.approx(as_member["floor_mm"] / 2)
    assert r_member["jitter_ratio"] == pytest.approx(0.5)  # like its PVE: 0 to itself, the floor to the other
    # sharpness: the member bends as much as the truths (their mean, up to the skirt's asymmetry);
    # the mean is the flat rest shape
    assert (
        r_member["bending_energy_ratio"] == pytest.approx(1.0, rel=0.02)
        and r_mean["bending_energy_ratio"] < 0.01
    )


@pytest.mark.sim
def test_members_are_perturbed_cached_and_close(tmp_path):
    from hrr_garment.data.dataset import SequenceRecord
    from hrr_garment.eval.ensemble import member_config, truth_ensembles
    from hrr_garment.sim.simulator import SimSettings

    config = SimSettings(substeps=5, iterations=1, settle_s=0.2, blend_s=0.2, device="cpu")
    labels = [member_config(config, k, 30.0)[1] for k in range(6)]
    assert labels[:4] == ["density x 1.0001", "density x 0.9999", "settle +1 frame", "settle -1 frame"]
    assert labels[4] == "density x 1.0002"
    with pytest.raises(ValueError, match="settle"):
        member_config(SimSettings(settle_s=0.0), 3, 30.0)

    garment = make_garment("skirt", 200)
    motion = synthesize("walk", 0.5, seed=3)
    record = SequenceRecord(
        "walk_000", np.zeros((motion.num_frames, garment.num_vertices, 3), np.float32), motion, {}
    )
    cache = tmp_path / "cache"
    first = truth_ensembles(garment, [record], config, members=2, jobs=1, cache=cache, progress=False)[
        "walk_000"
    ]
    assert first.members.shape == (2, motion.num_frames, garment.num_vertices, 3) and not first.failed
    floor = mean_pairwise_mm(first.members)
    assert 0.0 < floor < 20.0  # different, yet the same cloth on the same motion
    files = sorted(cache.glob("*.npy"))
    stamps = [f.stat().st_mtime_ns for f in files]
    again = truth_ensembles(garment, [record], config, members=2, jobs=1, cache=cache, progress=False)[
        "walk_000"
    ]
    assert np.array_equal(again.members, first.members) and [f.stat().st_mtime_ns for f in files] == stamps


ENSEMBLE_RUN = """
import signal, sys
import numpy as np
from hrr_garment.data.dataset import SequenceRecord
from hrr_garment.eval.ensemble import truth_ensembles
from hrr_garment.garment.templates import make_garment
from hrr_garment.motion.synth import synthesize
from hrr_garment.sim.simulator import SimSettings

signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # as every command unwinds on SIGTERM
garment, motion = make_garment("skirt", 200), synthesize("walk", 20.0, seed=3)
frames = np.zeros((motion.num_frames, garment.num_vertices, 3), np.float32)
record = SequenceRecord("walk_000", frames, motion, {})
config = SimSettings(substeps=5, iterations=1, settle_s=0.2, blend_s=0.2, device="cpu")
truth_ensembles(garment, [record], config, members=2, jobs=2, cache=sys.argv[1], progress=False)
"""


@pytest.mark.slow  # two workers started and stopped: 10 to 20 s
@pytest.mark.sim
def test_a_terminated_ensemble_stops_its_workers_at_once(tmp_path):
    """SIGTERM while two ensemble members simulate (hrr-eval's truth, 20 s of motion each): the run
    ends within seconds and leaves no process, where its pool used to simulate every member first
    (and a SIGKILLed one left its workers simulating)."""
    import signal
    import subprocess
    import sys

    from tests.sim.test_killed_build import session_processes, started_alone, wait_for, workers_asked_to_die

    run = started_alone([sys.executable, "-c", ENSEMBLE_RUN, str(tmp_path / "cache")])
    try:
        assert wait_for(lambda: workers_asked_to_die(run.pid, 2), 120), session_processes(run.pid)
        run.send_signal(signal.SIGTERM)
        assert run.wait(timeout=10) == 143
        assert wait_for(lambda: not session_processes(run.pid), 5), session_processes(run.pid)
    finally:
        subprocess.run(["pkill", "-9", "-s", str(run.pid)])
    assert not list((tmp_path / "cache").glob("*.npy"))  # neither member finished: nothing half written


def test_members_simulate_as_the_dataset_did_against_the_bodys_mesh_and_in_its_cloth(tmp_path, monkeypatch):
    """A member of a sequence on a body with a mesh of its own collides with that mesh, as the
    dataset's simulation did (its cache key apart from a capsule-collided member's); a sequence in
    a cloth of its own (sim/material_plan.py) is re-simulated in it."""
    from types import SimpleNamespace

    from hrr_garment.body.capsules import DEFAULT_BODY
    from hrr_garment.data.dataset import SequenceRecord
    from hrr_garment.eval import ensemble
    from hrr_garment.garment.fabrics import FABRICS
    from hrr_garment.sim.simulator import SimSettings
    from tests.body.limb import BulgingMannequin

    garment, motion = make_garment("skirt", 200), synthesize("walk", 0.3, seed=3)
    frames = np.zeros((motion.num_frames, garment.num_vertices, 3), np.float32)
    config = SimSettings(substeps=5, iterations=1)
    denim = SequenceRecord("a", frames, motion, {"material": FABRICS["denim"].to_dict()})
    assert ensemble.record_settings(config, denim).material == FABRICS["denim"]
    plain = SequenceRecord("b", frames, motion, {})
    assert ensemble.record_settings(config, plain) is config
    skin = BulgingMannequin(0.05).skinned()
    on_capsules = ensemble._member_key(garment, plain, config, DEFAULT_BODY)
    assert ensemble._member_key(garment, plain, config, DEFAULT_BODY, skin) != on_capsules
    seen = []
    monkeypatch.setattr(
        ensemble, "simulate_garment", lambda *a, **kw: seen.append(kw) or SimpleNamespace(vertices=frames)
    )
    for k, on in enumerate([(DEFAULT_BODY, None), (DEFAULT_BODY, skin)]):
        assert (
            ensemble._simulate_member(garment, plain, config.to_dict(), str(tmp_path / f"{k}.npy"), on)
            is None
        )
    assert seen[0]["collider"] is None and seen[1]["collider"] is not None
