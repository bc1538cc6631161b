"""Fused C kernels (``kernels.c``, ``amx_block.c``, ``window_codes.c`` and ``features.c`` in this
folder, sharing ``hrr_native.h``), compiled on first use, and their ctypes glue: the mesh decoder's
blocks, its single-frame form (streaming) and its bfloat16 form on AMX (their glue in
:mod:`.decoder`), the capsule-body signed distance (:mod:`hrr_garment.body`), the
push-out and its strain limit of :mod:`hrr_garment.inference.collision` (their glue in
:mod:`.body`), the code space's window step
(:mod:`hrr_garment.models.native_codes`), and forward kinematics and causal motion features
(:mod:`hrr_garment.motion`). The ground floor of the package: it imports nothing of hrr_garment
but :mod:`hrr_garment.paths` (where the compiled library is cached).

PyTorch runs a spatially varying convolution as a gather (materialising every neighbour's row for
every output vertex: S times the layer's output), a layout copy, then small per-vertex matmuls;
on the CPU that is memory-bound (about 5 % of the matmul peak). This kernel walks the output
vertices once: for each it reads its neighbours' rows in place (vertex-major rows of B x C_in
floats, contiguous), accumulates them through its per-slot kernels into a B x C_out tile that
stays in L1, adds the residual path (the normalised neighbour average read from the same rows,
then the 1x1 map) and the activation, and writes the tile once. Padded neighbour slots are
dropped (compressed rows), which also removes about 40 % of the work.

The source is compiled with the system C compiler (``cc``/``gcc``, ``-O3 -march=native
-fopenmp``) into the workspace cache, keyed by a hash of the source, the flags and the CPU, and
loaded with ctypes. Without a compiler :func:`load_kernel` returns None and callers use the
PyTorch path; ``HRR_NATIVE=0`` forces that.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
import threading
import warnings
from pathlib import Path

import numpy as np

_HERE = Path(__file__).resolve().parent
HEADER = "hrr_native.h"  # what the sources share (helpers of kernels.c used by window_codes.c)
# one translation unit, so shared helpers inline across files; each source includes the header
SOURCES = ("kernels.c", "amx_block.c", "window_codes.c", "features.c")
SOURCE = "\n".join((_HERE / name).read_text() for name in SOURCES)
_HEADER_TEXT = (_HERE / HEADER).read_text()

FLAGS = ["-O3", "-march=native", "-mprefer-vector-width=512", "-fno-math-errno", "-fno-trapping-math", "-fopenmp",
         "-Werror=implicit-function-declaration",
         "-shared", "-fPIC"]
PRECISIONS = ("float32", "bfloat16")  # the batched decoder's arithmetic (bfloat16: hrr_block_bf16, AMX)
_lock = threading.Lock()
_loaded: dict[str, ctypes.CDLL | None] = {}
_requests: dict[tuple, ctypes.CDLL | None] = {}


@functools.lru_cache(maxsize=1)
def _cpu_signature() -> str:
    try:
        flags = next(line for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("flags"))
    except (OSError, StopIteration):
        flags = ""
    return f"{platform.machine()} {platform.processor()} {flags}"


@functools.lru_cache(maxsize=1)
def _source_key() -> str:
    return hashlib.sha1("\0".join([_HEADER_TEXT, SOURCE, *FLAGS, _cpu_signature()]).encode()).hexdigest()[:16]


def _compile(target: Path) -> None:
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise OSError("no C compiler (cc/gcc) on PATH")
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        src, lib = Path(tmp) / "kernel.c", Path(tmp) / "kernel.so"
        src.write_text(SOURCE)
        subprocess.run([compiler, *FLAGS, f"-I{_HERE}", str(src), "-o", str(lib), "-lm"], check=True, capture_output=True,
                       text=True)
        os.replace(lib, target)  # atomic: a concurrent process sees the whole library or none


def load_kernel(cache_dir: str | Path | None = None) -> ctypes.CDLL | None:
    """The compiled kernel library (compiling it on first use), or None without a working compiler
    or with ``HRR_NATIVE=0``."""
    if os.environ.get("HRR_NATIVE", "1") == "0":
        return None
    # the per-frame path (streaming push-out) asks on every call: answer without resolving paths
    request = (cache_dir, os.environ.get("HRR_HOME"), None if cache_dir else os.getcwd())
    if request in _requests:
        return _requests[request]
    from ..paths import workspace

    target = Path(cache_dir or workspace() / "cache") / f"fcmae_kernel-{_source_key()}.so"
    with _lock:
        if str(target) not in _loaded:
            try:
                if not target.exists():
                    _compile(target)
                lib = ctypes.CDLL(str(target))
                f = ctypes.POINTER(ctypes.c_float)
                i32 = ctypes.POINTER(ctypes.c_int32)
                c_int, c_float, c_double = ctypes.c_int, ctypes.c_float, ctypes.c_double
                lib.hrr_block.argtypes = [f, c_int, c_int, c_int, c_int, i32, i32, f, f, f, f, c_float, c_float, c_int,
                                          c_int, f]
                lib.hrr_block.restype = None
                d = ctypes.c_void_p  # addresses from ndarray.ctypes.data: per-frame calls, so the cheapest conversion
                lib.hrr_capsule_sdf.argtypes = [d, c_int, c_int, d, d, d, c_int, c_int, d, d]
                lib.hrr_capsule_sdf.restype = None
                lib.hrr_push_out.argtypes = [d, c_int, c_int, d, d, d, c_int, d, d, d, c_double, c_int, c_int, c_double,
                                             c_int, d, d]
                lib.hrr_push_out.restype = None
                lib.hrr_limit_strain.argtypes = [d, d, c_int, c_int, c_int, d, d, c_double, d, d, d, c_int, c_double, c_double,
                                                 c_int, d]
                lib.hrr_limit_strain.restype = c_int
                lib.hrr_factor_block.argtypes = [d, c_int, c_int, d, d, d, c_int, c_int, c_int, c_int, d, d, d, d, d,
                                                 c_float, c_float, c_int, c_int, d]
                lib.hrr_factor_block.restype = None
                lib.hrr_window_codes.argtypes = [d, c_int, d, d, c_int, d, d, d]
                lib.hrr_window_codes.restype = c_int
                lib.hrr_window_codes_work.argtypes = [d]
                lib.hrr_window_codes_work.restype = ctypes.c_long
                lib.hrr_forward_kinematics.argtypes = [d, d, c_int, c_int, d, d, d, d]
                lib.hrr_forward_kinematics.restype = None
                lib.hrr_causal_features.argtypes = [d, d, c_int, c_int, d, c_int, c_double, d]
                lib.hrr_causal_features.restype = None
                lib.hrr_body_to_world.argtypes = [d, c_int, c_int, d, d, c_int, d]
                lib.hrr_body_to_world.restype = None
                lib.hrr_block_bf16.argtypes = [d, c_int, c_int, c_int, c_int, c_int, d, d, d, d, d, d, c_float, c_float,
                                               c_int, c_int, d, d, d]
                lib.hrr_block_bf16.restype = c_int
                lib.hrr_rows_to_frames.argtypes = [d, c_int, c_int, c_int, c_int, c_int, d, c_float, c_int, d]
                lib.hrr_rows_to_frames.restype = None
                lib.hrr_amx_ready.argtypes = []
                lib.hrr_amx_ready.restype = c_int
                lib.hrr_pin_workers.argtypes = [c_int]
                lib.hrr_pin_workers.restype = c_int
                lib.hrr_current_cpu.argtypes = []
                lib.hrr_current_cpu.restype = c_int
                _loaded[str(target)] = lib
            except (OSError, subprocess.CalledProcessError) as exc:
                detail = getattr(exc, "stderr", "") or str(exc)
                warnings.warn(f"native decoder kernel unavailable, using the PyTorch path: {detail[:500]}", RuntimeWarning)
                _loaded[str(target)] = None
        _requests[request] = _loaded[str(target)]
        return _loaded[str(target)]


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


PANEL = 64  # PANEL in hrr_native.h


def pack_panels(wt: np.ndarray) -> np.ndarray:
    """A dense product's right-hand matrix (in, out) in the kernels' layout (``linear_rows``):
    panels of PANEL columns, (panels, in, PANEL), zero-padded to whole panels."""
    inp, out = wt.shape
    panels = np.pad(wt, [(0, 0), (0, -out % PANEL)]).reshape(inp, -1, PANEL).transpose(1, 0, 2)
    return np.ascontiguousarray(panels, np.float32)


def forward_kinematics(lib: ctypes.CDLL, local_rot: np.ndarray, root_pos: np.ndarray, offsets: np.ndarray,
                       parents) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hrr_garment.motion.skeleton.forward_kinematics` in the kernel, for numpy motions:
    local rotations (T, J, 3, 3), root positions (T, 3), offsets (J, 3) -> float64 global rotations
    (T, J, 3, 3) and positions (T, J, 3)."""
    local = np.ascontiguousarray(local_rot, np.float32)
    root = np.ascontiguousarray(root_pos, np.float64)
    off = np.ascontiguousarray(offsets, np.float64)
    par = np.ascontiguousarray(parents, np.int32)
    t, j = local.shape[:2]
    g_rot, g_pos = np.empty((t, j, 3, 3)), np.empty((t, j, 3))
    lib.hrr_forward_kinematics(local.ctypes.data, root.ctypes.data, t, j, off.ctypes.data, par.ctypes.data,
                               g_rot.ctypes.data, g_pos.ctypes.data)
    return g_rot, g_pos


def causal_features(lib: ctypes.CDLL, g_rot: np.ndarray, g_pos: np.ndarray, joints, fps: float) -> np.ndarray:
    """Motion features (T, 6 F + 4) of every frame from it and the frame before (frame 0 from
    itself: zero velocities), from global rotations (T, J, 3, 3) and positions (T, J, 3): what
    :func:`hrr_garment.motion.features.causal_features` computes in numpy."""
    rot, pos = np.ascontiguousarray(g_rot, np.float64), np.ascontiguousarray(g_pos, np.float64)
    idx = np.ascontiguousarray(joints, np.int32)
    t, j = rot.shape[:2]
    out = np.empty((t, 6 * len(idx) + 4), np.float32)
    lib.hrr_causal_features(rot.ctypes.data, pos.ctypes.data, t, j, idx.ctypes.data, len(idx), float(fps), out.ctypes.data)
    return out


def body_to_world(lib: ctypes.CDLL, points: np.ndarray, yaw: np.ndarray, origin: np.ndarray, threads: int = 1) -> np.ndarray:
    """:func:`hrr_garment.motion.frame.from_body_frame` in the kernel, into float32: body-frame
    points (T, N, 3), each frame's yaw (T,) and body-frame origin (T, 3) -> world points (T, N, 3)."""
    p = np.ascontiguousarray(points, np.float32)
    turn = np.ascontiguousarray(np.stack([np.cos(yaw), np.sin(yaw)], 1), np.float64)
    o = np.ascontiguousarray(origin, np.float64)
    out = np.empty(p.shape, np.float32)
    lib.hrr_body_to_world(p.ctypes.data, p.shape[0], p.shape[1], turn.ctypes.data, o.ctypes.data, threads, out.ctypes.data)
    return out
