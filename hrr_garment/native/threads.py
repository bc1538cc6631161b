"""The kernels' threads: how many they use unless told (:func:`default_threads`) and the pinning
of their OpenMP workers away from the calling thread's CPU (:func:`pin_workers`)."""

from __future__ import annotations

import os
import threading

from .build import load_kernel


def default_threads() -> int:
    """Threads the kernels use unless told: PyTorch's setting (``torch.set_num_threads``), one
    knob for the whole library."""
    import torch

    return torch.get_num_threads()


_pinned: dict[int, tuple[int, int]] = {}  # calling thread -> (threads, its CPU) its workers were pinned for


def pin_workers(threads: int | None = None) -> None:
    """Pins the OpenMP worker threads of the calling thread to CPUs other than the caller's
    (``hrr_pin_workers`` in ``kernels.c`` says why: a stream paced like a game loop lost about 5 ms
    a frame waking unpinned workers). Cheap enough for every frame: it acts only when the thread
    count changed or the caller moved to another CPU. Does nothing with ``HRR_PIN_THREADS=0``,
    where ``OMP_PROC_BIND`` is set (the user binds threads), or without the kernel."""
    if os.environ.get("HRR_PIN_THREADS", "1") == "0" or "OMP_PROC_BIND" in os.environ:
        return
    lib = load_kernel()
    if lib is None:
        return
    threads = default_threads() if threads is None else threads
    key = (threads, lib.hrr_current_cpu())
    me = threading.get_ident()
    if _pinned.get(me) != key:
        lib.hrr_pin_workers(threads)  # -1 (a refused system call): left as the scheduler has them
        _pinned[me] = key
