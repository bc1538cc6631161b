"""A fused C kernel for the mesh decoder's blocks (inference only), compiled on first use.

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
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

import numpy as np

SOURCE = r"""
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

#define ALWAYS_INLINE static inline __attribute__((always_inline))

/* acc (RB, cout) += x rows (RB frames of one neighbour, stride cin) times k (cin, cout). With cout
   and RB compile-time constants (see hrr_block's switch) the tile stays in registers. */
ALWAYS_INLINE void tile(float *restrict acc, const float *restrict xs, const float *restrict k,
                        int cin, const int cout, const int RB)
{
    for (int c = 0; c < cin; ++c) {
        const float *restrict kr = k + (size_t)c * cout;
        for (int r = 0; r < RB; ++r) {
            const float xv = xs[(size_t)r * cin + c];
            #pragma omp simd
            for (int o = 0; o < cout; ++o) acc[r * cout + o] += xv * kr[o];
        }
    }
}

ALWAYS_INLINE void conv_rows(float *restrict acc, const float *restrict x, int B, int cin, const int cout,
                             const int RB, int j0, int j1, const int32_t *restrict nbr,
                             const float *restrict K, const float *restrict bias)
{
    int bb = 0;
    for (; bb + RB <= B; bb += RB) {
        float t[RB * cout];
        for (int r = 0; r < RB; ++r)
            for (int o = 0; o < cout; ++o) t[r * cout + o] = bias[o];
        for (int j = j0; j < j1; ++j)
            tile(t, x + ((size_t)nbr[j] * B + bb) * cin, K + (size_t)j * cin * cout, cin, cout, RB);
        memcpy(acc + (size_t)bb * cout, t, sizeof(float) * RB * cout);
    }
    for (; bb < B; ++bb) {
        float t[cout];
        for (int o = 0; o < cout; ++o) t[o] = bias[o];
        for (int j = j0; j < j1; ++j)
            tile(t, x + ((size_t)nbr[j] * B + bb) * cin, K + (size_t)j * cin * cout, cin, cout, 1);
        memcpy(acc + (size_t)bb * cout, t, sizeof(float) * cout);
    }
}

/* Any cout; K transposed (nnz, cout, cin): dot products along cin (for cout = 3). */
static void conv_rows_dot(float *restrict acc, const float *restrict x, int B, int cin, int cout, int j0,
                          int j1, const int32_t *restrict nbr, const float *restrict K,
                          const float *restrict bias)
{
    for (int bb = 0; bb < B; ++bb)
        for (int o = 0; o < cout; ++o) {
            float s = bias[o];
            for (int j = j0; j < j1; ++j) {
                const float *restrict xr = x + ((size_t)nbr[j] * B + bb) * cin;
                const float *restrict kr = K + ((size_t)j * cout + o) * cin;
                #pragma omp simd reduction(+:s)
                for (int c = 0; c < cin; ++c) s += xr[c] * kr[c];
            }
            acc[(size_t)bb * cout + o] = s;
        }
}

/* One block for B frames, vertex-major tensors:
     out[v] = a * act(bias + sum_j x[nbr[j]] K[j]) + b * residual(v)
   x (Vin, B, cin); offsets (V + 1) and nbr (nnz): compressed neighbour rows; K (nnz, cin, cout) for
   cout in {8, 16, 32, 64, 128}, else (nnz, cout, cin); residual(v) = (sum_j pool[j] x[nbr[j]]) or
   x[v] when pool is NULL, then times proj (cin, cout) unless proj is NULL (cin == cout). */
void hrr_block(const float *x, int B, int cin, int cout, int V, const int32_t *offsets,
               const int32_t *nbr, const float *K, const float *bias, const float *pool,
               const float *proj, float a, float b, int elu, int threads, float *out)
{
    #pragma omp parallel num_threads(threads)
    {
        float *acc = (float *)aligned_alloc(64, (((size_t)B * cout * 4 + 63) / 64) * 64);
        float *res = (float *)aligned_alloc(64, (((size_t)B * cin * 4 + 63) / 64) * 64);
        float *tmp = (float *)aligned_alloc(64, (((size_t)cout * 4 + 63) / 64) * 64);
        #pragma omp for schedule(static)
        for (int v = 0; v < V; ++v) {
            const int j0 = offsets[v], j1 = offsets[v + 1];
            switch (cout) {
            case 8: conv_rows(acc, x, B, cin, 8, 8, j0, j1, nbr, K, bias); break;
            case 16: conv_rows(acc, x, B, cin, 16, 8, j0, j1, nbr, K, bias); break;
            case 32: conv_rows(acc, x, B, cin, 32, 4, j0, j1, nbr, K, bias); break;
            case 64: conv_rows(acc, x, B, cin, 64, 2, j0, j1, nbr, K, bias); break;
            case 128: conv_rows(acc, x, B, cin, 128, 1, j0, j1, nbr, K, bias); break;
            default: conv_rows_dot(acc, x, B, cin, cout, j0, j1, nbr, K, bias);
            }
            if (pool) {
                memset(res, 0, sizeof(float) * (size_t)B * cin);
                for (int j = j0; j < j1; ++j) {
                    const float w = pool[j];
                    const float *restrict xs = x + (size_t)nbr[j] * B * cin;
                    #pragma omp simd
                    for (size_t i = 0; i < (size_t)B * cin; ++i) res[i] += w * xs[i];
                }
            }
            const float *r = pool ? res : x + (size_t)v * B * cin;
            float *dst = out + (size_t)v * B * cout;
            for (int bb = 0; bb < B; ++bb) {
                const float *rr = r + (size_t)bb * cin;
                const float *ar = acc + (size_t)bb * cout;
                if (proj) {
                    memset(tmp, 0, sizeof(float) * cout);
                    for (int c = 0; c < cin; ++c) {
                        const float rv = rr[c];
                        const float *pr = proj + (size_t)c * cout;
                        #pragma omp simd
                        for (int o = 0; o < cout; ++o) tmp[o] += rv * pr[o];
                    }
                }
                const float *rp = proj ? tmp : rr;
                float *d = dst + (size_t)bb * cout;
                for (int o = 0; o < cout; ++o) {
                    float y = ar[o];
                    if (elu) y = y > 0.0f ? y : expm1f(y);
                    d[o] = a * y + b * rp[o];
                }
            }
        }
        free(acc);
        free(res);
        free(tmp);
    }
}
"""

FLAGS = ["-O3", "-march=native", "-mprefer-vector-width=512", "-fopenmp", "-shared", "-fPIC"]
_lock = threading.Lock()
_loaded: dict[str, ctypes.CDLL | None] = {}


def _cpu_signature() -> str:
    try:
        flags = next(line for line in Path("/proc/cpuinfo").read_text().splitlines() if line.startswith("flags"))
    except (OSError, StopIteration):
        flags = ""
    return f"{platform.machine()} {platform.processor()} {flags}"


def _compile(target: Path) -> None:
    compiler = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        raise OSError("no C compiler (cc/gcc) on PATH")
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        src, lib = Path(tmp) / "kernel.c", Path(tmp) / "kernel.so"
        src.write_text(SOURCE)
        subprocess.run([compiler, *FLAGS, str(src), "-o", str(lib), "-lm"], check=True, capture_output=True, text=True)
        os.replace(lib, target)  # atomic: a concurrent process sees the whole library or none


def load_kernel(cache_dir: str | Path | None = None) -> ctypes.CDLL | None:
    """The compiled kernel library (compiling it on first use), or None without a working compiler
    or with ``HRR_NATIVE=0``."""
    if os.environ.get("HRR_NATIVE", "1") == "0":
        return None
    from ..paths import workspace

    key = hashlib.sha1("\0".join([SOURCE, *FLAGS, _cpu_signature()]).encode()).hexdigest()[:16]
    target = Path(cache_dir or workspace() / "cache") / f"fcmae_kernel-{key}.so"
    with _lock:
        if str(target) not in _loaded:
            try:
                if not target.exists():
                    _compile(target)
                lib = ctypes.CDLL(str(target))
                f = ctypes.POINTER(ctypes.c_float)
                i32 = ctypes.POINTER(ctypes.c_int32)
                c_int, c_float = ctypes.c_int, ctypes.c_float
                lib.hrr_block.argtypes = [f, c_int, c_int, c_int, c_int, i32, i32, f, f, f, f, c_float, c_float, c_int,
                                          c_int, f]
                lib.hrr_block.restype = None
                _loaded[str(target)] = lib
            except (OSError, subprocess.CalledProcessError):
                _loaded[str(target)] = None
        return _loaded[str(target)]


def _ptr(a: np.ndarray | None, kind=ctypes.c_float):
    return None if a is None else a.ctypes.data_as(ctypes.POINTER(kind))


class NativeBlock:
    """One decoder block's constants in the kernel's layout (see ``SOURCE``)."""

    def __init__(self, index: np.ndarray, mask: np.ndarray, kernel: np.ndarray, bias: np.ndarray,
                 pool: np.ndarray | None, proj: np.ndarray | None, a: float, b: float, elu: bool):
        keep = mask > 0  # (V, S): real neighbour slots
        self.offsets = np.concatenate([[0], np.cumsum(keep.sum(1))]).astype(np.int32)
        self.nbr = np.ascontiguousarray(index[keep], np.int32)
        v, s = index.shape
        cin, cout = kernel.shape[1] // s, kernel.shape[2]
        k = kernel.reshape(v, s, cin, cout)[keep]  # (nnz, cin, cout)
        self.transposed = cout not in (8, 16, 32, 64, 128)  # the kernel's specialised widths
        self.kernel = np.ascontiguousarray(k.transpose(0, 2, 1) if self.transposed else k, np.float32)
        self.bias = np.ascontiguousarray(bias, np.float32)
        self.pool = None if pool is None else np.ascontiguousarray(pool[keep], np.float32)
        self.proj = None if proj is None else np.ascontiguousarray(proj, np.float32)
        self.cin, self.cout, self.vertices = cin, cout, v
        self.a, self.b, self.elu = float(a), float(b), bool(elu)

    def __call__(self, lib: ctypes.CDLL, x: np.ndarray, threads: int) -> np.ndarray:
        """x (V_in, B, C_in) float32 C-contiguous -> (V, B, C_out)."""
        batch = x.shape[1]
        out = np.empty((self.vertices, batch, self.cout), np.float32)
        lib.hrr_block(_ptr(x), batch, self.cin, self.cout, self.vertices, _ptr(self.offsets, ctypes.c_int32),
                      _ptr(self.nbr, ctypes.c_int32), _ptr(self.kernel), _ptr(self.bias),
                      _ptr(self.pool), _ptr(self.proj), self.a, self.b, int(self.elu), threads, _ptr(out))
        return out
