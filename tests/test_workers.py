"""Signals held while a pool's internals run (hrr_garment.workers.DeferredSignals): delivered at
the next check, through the handler they would have met, never lost."""

import os
import signal

import pytest

from hrr_garment.workers import DeferredSignals


class Caught(Exception):
    pass


def _raise(signum, frame):
    raise Caught(signum)


@pytest.fixture
def raising_sigterm():
    previous = signal.signal(signal.SIGTERM, _raise)
    yield
    signal.signal(signal.SIGTERM, previous)


def test_a_signal_waits_for_the_check_and_meets_its_handler(raising_sigterm):
    with DeferredSignals() as signals:
        os.kill(os.getpid(), signal.SIGTERM)  # delivered to this (main) thread before kill returns
        assert signals.pending == signal.SIGTERM  # held: nothing raised here
        with pytest.raises(Caught):
            signals.check()
    assert signal.getsignal(signal.SIGTERM) is _raise  # the handler back


def test_a_signal_held_to_the_end_is_delivered_on_leaving(raising_sigterm):
    with pytest.raises(Caught):
        with DeferredSignals():
            os.kill(os.getpid(), signal.SIGTERM)
    assert signal.getsignal(signal.SIGTERM) is _raise


def test_nothing_held_nothing_raised(raising_sigterm):
    with DeferredSignals() as signals:
        signals.check()
    assert signal.getsignal(signal.SIGTERM) is _raise
