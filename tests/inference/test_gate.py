"""The hybrid's gate signals: the paper's entropy and the two that judge the match itself (code
similarity, motion distance), their calibration, storage in the bundle, and streaming with them."""

import json

import numpy as np
import pytest

from hrr_garment.artifacts.database import CodeDatabase
from hrr_garment.artifacts.gate_signals import GATE_SIGNALS, gate_doubt
from hrr_garment.motion.synth import synthesize
from tests.conftest import write_meta


@pytest.mark.parametrize(
    "signal, expected", [("entropy", [0.3, 1.2]), ("similarity", [0.25, 1.0]), ("distance", [2.0, 0.5])]
)
def test_each_signal_is_a_doubt_lower_where_retrieval_should_win(signal, expected):
    doubt = gate_doubt(
        signal, np.array([0.3, 1.2]), similarity=np.array([0.75, 0.0]), distance=np.array([2.0, 0.5])
    )
    assert np.allclose(doubt, expected)


def test_a_gate_without_its_input_or_unknown_is_refused():
    with pytest.raises(ValueError, match="needs the match's distance"):
        gate_doubt("distance", np.zeros(2), similarity=np.zeros(2))
    with pytest.raises(ValueError, match="unknown gate signal 'margin'"):
        gate_doubt("margin", np.zeros(2))


def test_motion_distance_is_the_rms_of_the_standardised_windows(rng):
    motion = rng.normal(size=(5, 3, 4)).astype(np.float32)
    db = CodeDatabase(
        np.zeros((5, 2), np.uint8),
        np.zeros((5, 3, 2, 1), np.float32),
        np.zeros(5, np.int32),
        np.arange(5, dtype=np.int32),
        ["a"],
        2,
        motion,
    )
    query = motion[[4, 1]] + np.float32(0.5)  # every feature 0.5 away from rows 4 and 1
    assert np.allclose(db.motion_distance(query, np.array([4, 1])), 0.5, atol=1e-6)
    assert np.allclose(db.motion_distance(motion[[2]], np.array([2])), 0.0)


def test_training_calibrates_every_gate_into_the_bundle(animator):
    bundle = animator.bundle
    assert bundle.gate in GATE_SIGNALS and set(bundle.manifest.gates) == set(GATE_SIGNALS)
    assert bundle.gate_tau(bundle.gate) == bundle.tau
    for g in GATE_SIGNALS:
        assert bundle.gate_tau(g) == pytest.approx(bundle.manifest.gates[g].tau)


@pytest.mark.parametrize("gate", ["similarity", "distance"])
def test_a_match_gate_spans_regression_to_retrieval(animator, gate):
    motion = synthesize("walk", 1.0, seed=3)
    never = animator.animate(motion, gate=gate, tau=0.0, push_out=False)
    regression = animator.animate(motion, mode="regression", push_out=False)
    assert not never.retrieved.any() and np.array_equal(never.vertices, regression.vertices)
    always = animator.animate(motion, gate=gate, tau=1e9, push_out=False)
    retrieval = animator.animate(motion, mode="retrieval", push_out=False)
    assert always.retrieved.all() and np.allclose(always.vertices, retrieval.vertices, atol=1e-6)
    # a threshold between two distinct signal values near the median: the gate compares in float64,
    # Animation.doubt is float32, and a threshold on a value itself would be a rounding tie
    values = np.unique(always.doubt.astype(np.float64))
    tau = float(values[len(values) // 2 - 1] + values[len(values) // 2]) / 2
    middle = animator.animate(motion, gate=gate, tau=tau, push_out=False)
    assert 0 < middle.retrieved.sum() < len(middle.retrieved)
    assert np.array_equal(middle.retrieved.astype(bool), middle.doubt < middle.settings["tau"])
    if gate == "similarity":
        assert (0 <= always.doubt).all() and (always.doubt <= 1).all()


@pytest.mark.parametrize("gate", ["similarity", "distance"])
def test_stream_with_a_match_gate_equals_offline_causal(animator, gate):
    motion = synthesize("walk_curve", 1.0, seed=5)
    tau = float(np.median(animator.animate(motion, gate=gate, tau=1e9, causal=True).doubt))
    causal = animator.animate(motion, gate=gate, tau=tau, causal=True)
    assert 0 < causal.retrieved.sum() < len(causal.retrieved)  # both sides of the gate
    stream = animator.stream(gate=gate, tau=tau)
    pushed = np.stack([stream.push(motion.slice(t, t + 1)) for t in range(motion.num_frames)])
    assert np.abs(pushed - causal.vertices).max() <= 1e-5


def test_a_bundle_before_the_match_gates_runs_the_entropy_and_says_what_is_missing(trained, tmp_path):
    import shutil

    from hrr_garment.artifacts.bundle_loader import BundleError, load_bundle
    from hrr_garment.artifacts.manifest import content_hash

    root, _, _ = trained
    old = tmp_path / "old"
    shutil.copytree(root / "model", old)
    meta = json.loads((old / "bundle.json").read_text())
    for key in ("gate", "gates"):
        meta.pop(key)
    meta["content_hash"], meta["format_version"] = content_hash(meta["files"]), 2  # as version 2 wrote them
    write_meta(old, meta)
    bundle = load_bundle(old)
    assert bundle.gate == "entropy" and bundle.gate_tau("entropy") == bundle.tau
    with pytest.raises(BundleError, match="not calibrated for the 'distance' gate"):
        bundle.gate_tau("distance")
    meta["gate"] = "margin"
    write_meta(old, meta)
    with pytest.raises(BundleError, match="'gate' must be one of"):
        load_bundle(old)


def test_hrr_animate_runs_the_gate_it_is_given(trained, tmp_path, capsys):
    from hrr_garment.cli.animate import main as animate_main
    from hrr_garment.motion.io import save_motion

    root, _, _ = trained
    clip = tmp_path / "walk.npz"
    save_motion(synthesize("walk", 1.0, seed=1), clip)
    out = tmp_path / "out.h5"
    assert (
        animate_main(
            [
                str(clip),
                "-o",
                str(out),
                "--model",
                str(root / "model"),
                "--gate",
                "distance",
                "--tau",
                "1e9",
                "--no-push-out",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "gate distance <" in text and "retrieval usage 100.0 %" in text
