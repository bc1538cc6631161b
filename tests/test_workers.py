"""Signals held while a pool's internals run (hrr_garment.workers.DeferredSignals): delivered at
the next check, through the handler they would have met, never lost."""

import os
import signal
import subprocess
import sys
import textwrap
import time

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


def test_a_process_forked_while_signals_are_held_does_not_hold_them(raising_sigterm):
    with DeferredSignals():
        pid = os.fork()
        if pid == 0:  # the child: SIGTERM must end it (its pool's terminate), Ctrl-C is the parent's
            ok = signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
            ok = ok and signal.getsignal(signal.SIGINT) == signal.SIG_IGN
            os._exit(0 if ok else 1)
        _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0


STUCK_POOL = textwrap.dedent(
    """
    import multiprocessing, os, signal, sys, threading, time
    from hrr_garment.workers import DeferredSignals, die_with_parent, results_heeding

    def stuck(item):
        time.sleep(600)  # a frame that never comes

    def stop(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)
    threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGTERM)).start()
    try:
        with DeferredSignals() as signals, multiprocessing.get_context("fork").Pool(
            2, die_with_parent, (os.getpid(),)
        ) as pool:
            for _ in results_heeding(pool.imap(stuck, range(8)), signals):
                pass
    except KeyboardInterrupt:
        sys.exit(143)
    """
)


def test_a_signal_ends_a_pool_whose_workers_are_stuck():
    """Held signals are delivered while the pool is silent, and its terminate() then ends the
    workers: the process ends in seconds, not when the stuck frame would have come."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-c", STUCK_POOL], capture_output=True, text=True, timeout=120)
    assert done.returncode == 143, done.stderr
    assert time.perf_counter() - start < 60
