"""Training budgets in epochs, minutes as a cap: why a run stopped, the warnings when the cap cut it
short or its error is far above its target, and the resume once the cap is raised."""

import warnings
from types import SimpleNamespace

import pytest

from hrr_garment.train.schedule import (
    STOPPED_BY_CAP,
    STOPPED_EARLY,
    STOPPED_EPOCHS,
    cap_since_raised,
    stop_reason,
)


def test_a_run_stops_for_its_epochs_its_cap_or_a_stalled_error(monkeypatch):
    from hrr_garment.train import schedule

    monkeypatch.setattr(schedule.time, "perf_counter", lambda: 100.0)
    config = SimpleNamespace(epochs=5, patience=3)
    assert (
        stop_reason({"epoch": 5, "stale": 0}, config, deadline=None, epoch_s=10.0, progress=1.0)
        == STOPPED_EPOCHS
    )
    assert (
        stop_reason({"epoch": 2, "stale": 0}, config, deadline=None, epoch_s=10.0, progress=0.4) is None
    )  # no cap
    assert (
        stop_reason({"epoch": 2, "stale": 0}, config, deadline=109.0, epoch_s=10.0, progress=0.4)
        == STOPPED_BY_CAP
    )  # 100 + 10 > 109
    assert stop_reason({"epoch": 2, "stale": 0}, config, deadline=110.0, epoch_s=10.0, progress=0.4) is None
    assert (
        stop_reason({"epoch": 4, "stale": 3}, config, deadline=None, epoch_s=10.0, progress=0.85)
        == STOPPED_EARLY
    )
    assert (
        stop_reason({"epoch": 4, "stale": 3}, config, deadline=None, epoch_s=10.0, progress=0.5) is None
    )  # not in the last fifth
    assert cap_since_raised(STOPPED_BY_CAP, 8.0, 24.0) and cap_since_raised(STOPPED_BY_CAP, 8.0, None)
    assert not cap_since_raised(STOPPED_BY_CAP, 8.0, 8.0) and not cap_since_raised(STOPPED_EPOCHS, 8.0, 24.0)


def test_presets_that_extend_another_merge_its_training_settings():
    from hrr_garment.pipeline.train import TrainSettings
    from hrr_garment.sim.preset import load_preset

    base, bodies = (TrainSettings.load(load_preset(n)) for n in ("real-quick", "real-quick-bodies"))
    assert bodies.codespace_train.target_mm != base.codespace_train.target_mm  # its own target and epochs ...
    assert bodies.autoencoder_train.epochs != base.autoencoder_train.epochs
    for section in ("autoencoder_train", "codespace_train"):  # ... over everything else of real-quick's
        a, b = getattr(base, section), getattr(bodies, section)
        assert a.max_minutes == b.max_minutes and a.epochs < 100 and a.max_minutes
    assert bodies.codespace_train.latent_loss == base.codespace_train.latent_loss == "vertex"
    assert (
        bodies.codespace_train.contact_steps > base.codespace_train.contact_steps > 0
    )  # its own contact phase
    assert bodies.autoencoder_train.refine_steps == base.autoencoder_train.refine_steps


@pytest.fixture
def capped(tmp_path, monkeypatch):
    """The tiny autoencoder (3 epochs asked) whose cap stops it after its first epoch."""
    from hrr_garment.garment.templates import make_garment
    from hrr_garment.train import schedule
    from tests.conftest import TINY_TRAINING, synthetic_dataset

    data = synthetic_dataset(tmp_path / "skirt.h5", make_garment("skirt", 300))
    (tmp_path / "cfg.yaml").write_text(TINY_TRAINING)
    fits = schedule.epoch_fits
    monkeypatch.setattr(
        schedule, "epoch_fits", lambda now, deadline, epoch_s: epoch_s is None if deadline else True
    )
    return data, tmp_path, lambda: monkeypatch.setattr(schedule, "epoch_fits", fits)


@pytest.mark.slow  # trains the tiny autoencoder, resumes it and trains it on: 3 to 7 s
def test_a_run_its_cap_cut_short_warns_and_resumes_when_the_cap_is_raised(capped):
    from hrr_garment.pipeline.budget import TrainingBudgetWarning
    from tests.conftest import train_tiny

    data, root, lift_cap = capped
    cap = {
        "autoencoder": {"train": {"max_minutes": 5.0, "target_mm": 0.01, "refine_steps": 0}}
    }  # no refinement: faster
    with pytest.warns(TrainingBudgetWarning) as heard:
        result = train_tiny(data, root / "model", root / "cfg.yaml", stages=("autoencoder",), overrides=cap)
    check = result.budgets["autoencoder"]
    assert (check.epochs, check.epochs_asked, check.stopped) == (1, 3, STOPPED_BY_CAP)
    messages = [str(w.message) for w in heard]
    assert any("5-minute cap stopped training after 1 of 3 epochs" in m for m in messages)
    assert any("x the 0.01 mm these settings reach" in m for m in messages)  # far above its target
    assert "1 of 3 epochs, stopped by minutes cap" in check.summary()

    with pytest.warns(TrainingBudgetWarning):  # the same cap: what there is stays, and still warns
        again = train_tiny(data, root / "model", root / "cfg.yaml", stages=("autoencoder",), overrides=cap)
    assert again.reports["autoencoder"].reused and again.budgets["autoencoder"].epochs == 1

    lift_cap()
    raised = {"autoencoder": {"train": {"max_minutes": 60.0, "refine_steps": 0}}}
    with warnings.catch_warnings():
        warnings.simplefilter("error", TrainingBudgetWarning)
        done = train_tiny(data, root / "model", root / "cfg.yaml", stages=("autoencoder",), overrides=raised)
    report = done.reports["autoencoder"]
    assert not report.reused and (report.epochs, report.stopped) == (
        3,
        STOPPED_EPOCHS,
    )  # resumed, and finished
    assert done.budgets["autoencoder"].target_ratio is None  # the config without a target says nothing of one
