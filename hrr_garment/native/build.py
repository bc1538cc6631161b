"""The kernels' build and load: the C sources compiled on first use into the workspace cache and
loaded with ctypes, each exported function's argument types declared (:func:`load_kernel`).

The sources (``kernels.c``, ``push_frame.c``, ``strain_limit.c``, ``subspace_push.c``,
``push_out.c``, ``amx_block.c``, ``window_codes.c``, ``features.c``, ``skin_sdf.c`` and
``mesh_probe.c``, sharing ``hrr_native.h``; the push-out's four also ``push_out.h``) are compiled as
one translation unit with the system C
compiler (``cc``/``gcc``, ``-O3 -march=native -fopenmp``) into the workspace cache, keyed by a hash
of the source, the flags and the CPU, and loaded with ctypes. Without a compiler :func:`load_kernel`
returns None and callers use the PyTorch path; ``HRR_NATIVE=0`` forces that.
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

_HERE = Path(__file__).resolve().parent
# what the sources share (hrr_native.h: helpers of kernels.c used by window_codes.c, the skin
# collider the push-out reads; push_out.h: the push-out's own)
HEADERS = ("hrr_native.h", "push_out.h")
# one translation unit, so shared helpers inline across files; each source includes its header
SOURCES = (
    "kernels.c",
    "push_frame.c",
    "strain_limit.c",
    "subspace_push.c",
    "push_out.c",
    "amx_block.c",
    "window_codes.c",
    "features.c",
    "skin_sdf.c",
    "mesh_probe.c",
)
SOURCE = "\n".join((_HERE / name).read_text() for name in SOURCES)
_HEADER_TEXT = "\n".join((_HERE / name).read_text() for name in HEADERS)

FLAGS = [
    "-O3",
    "-march=native",
    "-mprefer-vector-width=512",
    "-fno-math-errno",
    "-fno-trapping-math",
    "-fopenmp",
    "-Werror=implicit-function-declaration",
    "-shared",
    "-fPIC",
]
_lock = threading.Lock()
_loaded: dict[str, ctypes.CDLL | None] = {}
_requests: dict[tuple, ctypes.CDLL | None] = {}


@functools.lru_cache(maxsize=1)
def _cpu_signature() -> str:
    try:
        flags = next(
            line for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("flags")
        )
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
        subprocess.run(
            [compiler, *FLAGS, f"-I{_HERE}", str(src), "-o", str(lib), "-lm"],
            check=True,
            capture_output=True,
            text=True,
        )
        os.replace(lib, target)  # atomic: a concurrent process sees the whole library or none


def _declare(lib: ctypes.CDLL) -> None:
    """The argument and result types of the library's exported functions (the ctypes table)."""
    f = ctypes.POINTER(ctypes.c_float)
    i32 = ctypes.POINTER(ctypes.c_int32)
    c_int, c_float, c_double = ctypes.c_int, ctypes.c_float, ctypes.c_double
    lib.hrr_block.argtypes = [
        f,
        c_int,
        c_int,
        c_int,
        c_int,
        i32,
        i32,
        f,
        f,
        f,
        f,
        c_float,
        c_float,
        c_int,
        c_int,
        f,
    ]
    lib.hrr_block.restype = None
    d = ctypes.c_void_p  # addresses from ndarray.ctypes.data: per-frame calls, so the cheapest conversion
    lib.hrr_capsule_sdf.argtypes = [d, c_int, c_int, d, d, d, c_int, c_int, d, d]
    lib.hrr_capsule_sdf.restype = None
    lib.hrr_push_out.argtypes = [
        d,
        c_int,
        d,
        c_int,
        c_int,
        d,
        d,
        d,
        c_int,
        c_int,
        d,
        d,
        d,
        d,
        d,
        c_int,
        c_int,
        d,
        d,
        c_int,
        d,
        d,
        d,
        d,
        d,
        d,
        c_int,
        d,
        d,
        d,
    ]  # PushArgs, StrainArgs, SubspaceArgs by reference; SkinPose (T,) or NULL; base or NULL
    lib.hrr_push_out.restype = None
    lib.hrr_limit_strain.argtypes = [d, d, c_int, c_int, d, c_int, d]
    lib.hrr_limit_strain.restype = c_int
    lib.hrr_factor_block.argtypes = [
        d,
        c_int,
        c_int,
        d,
        d,
        d,
        c_int,
        c_int,
        c_int,
        c_int,
        d,
        d,
        d,
        d,
        d,
        c_float,
        c_float,
        c_int,
        c_int,
        d,
    ]
    lib.hrr_factor_block.restype = None
    lib.hrr_window_codes.argtypes = [d, d, c_int, d, d, c_int, d, d, d]
    lib.hrr_window_codes.restype = c_int
    lib.hrr_frame_gates.argtypes = [d, c_int, d, d, c_int, d]
    lib.hrr_frame_gates.restype = c_int
    lib.hrr_window_codes_work.argtypes = [d]
    lib.hrr_window_codes_work.restype = ctypes.c_long
    lib.hrr_forward_kinematics.argtypes = [d, d, c_int, c_int, d, d, d, d]
    lib.hrr_forward_kinematics.restype = None
    lib.hrr_causal_features.argtypes = [d, d, c_int, c_int, d, c_int, c_double, d]
    lib.hrr_causal_features.restype = None
    lib.hrr_body_to_world.argtypes = [d, c_int, c_int, d, d, c_int, d]
    lib.hrr_body_to_world.restype = None
    lib.hrr_block_bf16.argtypes = [
        d,
        c_int,
        c_int,
        c_int,
        c_int,
        c_int,
        d,
        d,
        d,
        d,
        d,
        d,
        c_float,
        c_float,
        c_int,
        c_int,
        d,
        d,
        d,
    ]
    lib.hrr_block_bf16.restype = c_int
    lib.hrr_rows_to_frames.argtypes = [d, c_int, c_int, c_int, c_int, c_int, d, c_float, c_int, d]
    lib.hrr_rows_to_frames.restype = None
    lib.hrr_amx_ready.argtypes = []
    lib.hrr_amx_ready.restype = c_int
    lib.hrr_pin_workers.argtypes = [c_int]
    lib.hrr_pin_workers.restype = c_int
    lib.hrr_skin_pose.argtypes = [d, d, d, d]
    lib.hrr_skin_pose.restype = None
    lib.hrr_skin_frames.argtypes = [d, c_int, d, d, d, d, d, d, c_int, d, d, d, c_int, d, c_int]
    lib.hrr_skin_frames.restype = None
    lib.hrr_skin_sdf.argtypes = [d, d, d, d, d, c_int, d, d]
    lib.hrr_skin_sdf.restype = None
    lib.hrr_skin_cells.argtypes = [d, d, c_double, c_double, d, d, d]
    lib.hrr_skin_cells.restype = None
    lib.hrr_skin_far.argtypes = [d, d, c_double, c_double, d, c_int, d]
    lib.hrr_skin_far.restype = c_int
    lib.hrr_mesh_probe.argtypes = [d, c_int, c_int, c_int, d, c_int, d, d, c_double, c_double, d, d, c_int]
    lib.hrr_mesh_probe.restype = c_int
    lib.hrr_current_cpu.argtypes = []
    lib.hrr_current_cpu.restype = c_int


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
                _declare(lib)
                _loaded[str(target)] = lib
            except (OSError, subprocess.CalledProcessError) as exc:
                detail = getattr(exc, "stderr", "") or str(exc)
                warnings.warn(
                    f"native decoder kernel unavailable, using the PyTorch path: {detail[:500]}",
                    RuntimeWarning,
                )
                _loaded[str(target)] = None
        _requests[request] = _loaded[str(target)]
        return _loaded[str(target)]
