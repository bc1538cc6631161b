"""Worker processes that die with the process that started them.

A build killed with SIGKILL runs no cleanup, so its pool workers would live on, finish their parts
and idle, holding the caller's terminal and pipes (issue 48). Each worker calls
:func:`die_with_parent` as it starts: on Linux the kernel sends it SIGKILL when its parent dies
(``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread watches the parent's process id. The
multiprocessing resource tracker then sees its last pipe close and exits on its own.

:func:`spawned_pool` is the process pool the simulator's build and ``hrr-eval``'s truth ensembles
run in: its workers die with their parent, and an interrupted run stops them at once.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Iterator

PR_SET_PDEATHSIG = 1  # linux/prctl.h


def die_with_parent(parent_pid: int) -> None:
    """In a worker process started by ``parent_pid``: end this process when that parent ends (at
    once when it already has). Ctrl-C is the parent's to handle (a terminal sends it to the whole
    process group; the parent stops its workers) and SIGTERM ends a worker quietly, whatever
    handler a forked worker inherited."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    asked = (
        sys.platform.startswith("linux")
        and ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL) == 0
    )
    if not asked:
        threading.Thread(
            target=_watch_parent, args=(parent_pid,), daemon=True, name="die-with-parent"
        ).start()
    if os.getppid() != parent_pid:  # the parent died before the signal was asked for
        os._exit(1)


@contextlib.contextmanager
def spawned_pool(workers: int, setup: Callable | None = None, *setup_args) -> Iterator[ProcessPoolExecutor]:
    """A pool of ``workers`` spawned processes (a forked one would inherit this process's threads and
    locks: the simulator is not fork-safe), each of which dies with this process
    (:func:`die_with_parent`) and then runs ``setup(*setup_args)``. An exception inside the block
    (Ctrl-C, SIGTERM, an error) kills the workers mid-task, so that what they had not finished is
    simply not written; leaving the block never runs what was still queued."""
    pool = ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("spawn"),
        initializer=_start_worker,
        initargs=(os.getpid(), setup, setup_args),
    )
    try:
        yield pool
    except BaseException:
        _kill_workers(pool)
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _start_worker(parent_pid: int, setup: Callable | None, setup_args: tuple) -> None:
    die_with_parent(parent_pid)
    if setup is not None:
        setup(*setup_args)


def _kill_workers(pool: ProcessPoolExecutor) -> None:
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    if terminate is not None:
        terminate()
        return
    for process in list((pool._processes or {}).values()):  # noqa: SLF001 - the only handle before 3.14
        process.kill()


def _watch_parent(parent_pid: int) -> None:
    while os.getppid() == parent_pid:
        time.sleep(1.0)
    os._exit(1)


_HOLDING = 0  # DeferredSignals blocks open in this process


def _reset_in_child() -> None:
    # A process forked while signals are held would inherit the holding handler and, until its own
    # start-up code ran, ignore the SIGTERM its pool's terminate() sends it: a worker stuck there
    # would then keep the pool's clean-up waiting forever.
    if _HOLDING:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_reset_in_child)


def results_heeding(results, signals: "DeferredSignals", poll_s: float = 0.2) -> Iterator:
    """The items of a pool's ``imap`` iterator, in order, delivering a held signal within
    ``poll_s`` even while no result comes (a slow or stuck worker), not only between results.
    ``results`` must be an ``imap`` of chunksize 1 (a larger one gives a generator without waits)."""
    if not callable(getattr(results, "next", None)):
        raise TypeError(f"results_heeding needs a pool's imap iterator of chunksize 1, not {type(results)}")
    while True:
        try:
            item = results.next(timeout=poll_s)
        except multiprocessing.TimeoutError:
            signals.check()
            continue
        except StopIteration:
            return
        signals.check()
        yield item


class DeferredSignals(contextlib.AbstractContextManager):
    """SIGINT and SIGTERM held while a pool's internals run, delivered at :meth:`check` (a point
    between results, where nothing is half done) or on leaving, through the handlers they would
    have met. A handler that raises at an arbitrary point inside multiprocessing can leave its
    locks held and its clean-up waiting forever (a SIGTERM hung an MP4 preview's render pool).
    Outside the main thread it does nothing: signals are the main thread's."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.pending: int | None = None
        self._previous: dict = {}

    def __enter__(self) -> "DeferredSignals":
        global _HOLDING
        if threading.current_thread() is threading.main_thread():
            self._previous = {s: signal.signal(s, self._hold) for s in self.SIGNALS}
            _HOLDING += 1
        return self

    def _hold(self, signum: int, frame: object) -> None:
        self.pending = signum

    def _restore(self) -> None:
        global _HOLDING
        if self._previous:
            _HOLDING -= 1
        for s, handler in self._previous.items():
            signal.signal(s, handler)
        self._previous = {}

    def check(self) -> None:
        """Deliver a held signal now (its handler raises, typically)."""
        if self.pending is None:
            return
        signum, handlers = self.pending, dict(self._previous)
        self.pending = None
        self._restore()
        handler = handlers.get(signum)
        if callable(handler):
            handler(signum, None)
        elif handler != signal.SIG_IGN:  # the default action: end the process as the signal would
            os.kill(os.getpid(), signum)

    def __exit__(self, *exc: object) -> None:
        self.check()  # a signal held to the end is not lost (its exception replaces one in flight)
        self._restore()
