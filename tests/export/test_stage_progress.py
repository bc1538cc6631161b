"""The progress bar of work done in a few long silent stages (an ONNX export's): each stage named as
it starts, the count of stages done, a clock that keeps moving while a stage works, and nothing
shown (no thread started) when disabled."""

import threading
import time

import pytest

from hrr_garment.export import stage_progress as module
from hrr_garment.export.stage_progress import stage_progress

STAGES = ("tracing", "optimising", "writing")


def _tickers() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "stage-progress"]


def test_each_stage_is_named_as_it_starts_and_counted_when_the_next_one_does(capsys):
    with stage_progress(STAGES, desc="export of x.onnx") as stage:
        for name in STAGES:
            stage(name)
            assert _tickers(), "the clock's thread runs while a stage works"
    err = capsys.readouterr().err
    assert "export of x.onnx" in err
    for name in STAGES:
        assert name in err
    assert "3/3 stages" in err and err.index("tracing") < err.index("optimising") < err.index("writing")
    assert not _tickers(), "the clock's thread ends with the bar"


def test_the_clock_moves_while_a_stage_works(capsys, monkeypatch):
    monkeypatch.setattr(module, "REDRAW_S", 0.02)
    with stage_progress(STAGES, desc="export") as stage:
        stage("tracing")
        capsys.readouterr()
        time.sleep(0.3)  # a stage that reports nothing
        redrawn = capsys.readouterr().err
    assert redrawn.count("tracing") >= 3, f"the bar was not redrawn while the stage worked: {redrawn!r}"


def test_a_stage_that_fails_is_not_counted_done_and_the_thread_ends(capsys):
    with pytest.raises(RuntimeError, match="trace failed"):
        with stage_progress(STAGES, desc="export") as stage:
            stage("tracing")
            stage("optimising")
            raise RuntimeError("trace failed")
    err = capsys.readouterr().err
    assert "1/3 stages" in err and "3/3" not in err
    assert not _tickers()


def test_an_unknown_stage_is_refused_naming_the_stages():
    with stage_progress(STAGES, desc="export", enabled=False) as stage:
        with pytest.raises(ValueError, match="no stage 'saving'.*tracing, optimising, writing"):
            stage("saving")


def test_disabled_it_shows_nothing_and_starts_no_thread(capsys):
    with stage_progress(STAGES, desc="export", enabled=False) as stage:
        for name in STAGES:
            stage(name)
            assert not _tickers()
    captured = capsys.readouterr()
    assert captured.err == "" and captured.out == ""
