"""Fused C kernels for inference, compiled on first use: the mesh decoder's blocks (below) and the
capsule-body signed distance of the collision push-out.

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
import torch

SOURCE = r"""
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

#define ALWAYS_INLINE static inline __attribute__((always_inline))

/* Denormal floats read and produced as zero (flush-to-zero and denormals-are-zero) in the calling
   thread, restored afterwards: trained weights and activations hold some, and every product with
   one takes a slow microcode path. Set in each worker thread, which PyTorch's setting misses. */
#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
ALWAYS_INLINE unsigned denormals_off(void) { const unsigned old = _mm_getcsr(); _mm_setcsr(old | 0x8040); return old; }
ALWAYS_INLINE void denormals_restore(unsigned old) { _mm_setcsr(old); }
#else
ALWAYS_INLINE unsigned denormals_off(void) { return 0; }
ALWAYS_INLINE void denormals_restore(unsigned old) { (void)old; }
#endif

typedef float v8sf __attribute__((vector_size(32)));
typedef float v16sf __attribute__((vector_size(64)));

/* acc (B, COUT) = bias + sum_j x[nbr[j]] (B, cin) times K[j] (cin, COUT). Neighbour slot outer,
   so its kernel block (cin x COUT, at most 64 KB) stays in L1 while all B frames pass through it;
   then one LANES-wide column block at a time and RB frames at a time, so the RB accumulators stay
   in vector registers (GCC vector extensions; VT holds LANES floats) and one kernel-row load feeds
   RB fused multiply-adds with broadcast operands. */
#define TILE(ROWS)                                                                             \
    for (int q = 0; q < COUT; q += LANES) {                                                    \
        VT t[ROWS];                                                                            \
        for (int r = 0; r < ROWS; ++r) memcpy(&t[r], acc + (size_t)(bb + r) * COUT + q, sizeof(VT)); \
        const float *restrict xs = xj + (size_t)bb * cin;                                      \
        for (int c = 0; c < cin; ++c) {                                                        \
            VT kv;                                                                             \
            memcpy(&kv, k + (size_t)c * COUT + q, sizeof(VT));                                 \
            for (int r = 0; r < ROWS; ++r) t[r] += xs[(size_t)r * cin + c] * kv;               \
        }                                                                                      \
        for (int r = 0; r < ROWS; ++r) memcpy(acc + (size_t)(bb + r) * COUT + q, &t[r], sizeof(VT)); \
    }

#define DEFINE_CONV(NAME, COUT_, VT_, LANES_)                                                  \
    static void NAME(float *restrict acc, const float *restrict x, int B, int cin, int j0,      \
                     int j1, const int32_t *restrict nbr, const float *restrict K,             \
                     const float *restrict bias)                                               \
    {                                                                                          \
        typedef VT_ VT;                                                                        \
        enum { COUT = COUT_, LANES = LANES_, RB = 16 };                                        \
        for (int bb = 0; bb < B; ++bb) memcpy(acc + (size_t)bb * COUT, bias, sizeof(float) * COUT); \
        for (int j = j0; j < j1; ++j) {                                                        \
            const float *restrict xj = x + (size_t)nbr[j] * B * cin;                           \
            const float *restrict k = K + (size_t)j * cin * COUT;                              \
            int bb = 0;                                                                        \
            for (; bb + RB <= B; bb += RB) TILE(RB)                                            \
            for (; bb < B; ++bb) TILE(1)                                                       \
        }                                                                                      \
    }

DEFINE_CONV(conv8, 8, v8sf, 8)
DEFINE_CONV(conv16, 16, v16sf, 16)
DEFINE_CONV(conv32, 32, v16sf, 16)
DEFINE_CONV(conv64, 64, v16sf, 16)
DEFINE_CONV(conv128, 128, v16sf, 16)

/* exp(y) for y <= 0 in plain arithmetic so that loops over it vectorise (Cephes' expf polynomial,
   about 1e-7 relative error); libm's expf is a scalar call per element. */
ALWAYS_INLINE float exp_nonpositive(float y)
{
    y = y > -87.0f ? y : -87.0f;  /* a ternary, not fmaxf: no libm call where a loop is not vectorised */
    const float n = floorf(y * 1.44269504088896341f + 0.5f);
    float r = fmaf(n, -0.693359375f, y);
    r = fmaf(n, 2.12194440e-4f, r);
    float p = 1.9875691500e-4f;
    p = fmaf(p, r, 1.3981999507e-3f);
    p = fmaf(p, r, 8.3334519073e-3f);
    p = fmaf(p, r, 4.1665795894e-2f);
    p = fmaf(p, r, 1.6666665459e-1f);
    p = fmaf(p, r, 5.0000001201e-1f);
    p = fmaf(p, r * r, r) + 1.0f;
    const int32_t bits = ((int32_t)n + 127) << 23;
    float scale;
    memcpy(&scale, &bits, sizeof scale);
    return p * scale;
}

typedef void (*conv_fn)(float *restrict, const float *restrict, int, int, int, int, const int32_t *restrict,
                        const float *restrict, const float *restrict);

/* One block for B frames, vertex-major tensors:
     out[v] = a * act(bias + sum_j x[nbr[j]] K[j]) + b * residual(v)
   x (Vin, B, cin); offsets (V + 1) and nbr (nnz): compressed neighbour rows; K (nnz, cin, cout),
   cout one of 8, 16, 32, 64, 128 (the caller pads); residual(v) = (sum_j pool[j] x[nbr[j]]) or
   x[v] when pool is NULL, then times proj (cin, cout) unless proj is NULL (cin == cout); the 1x1
   map runs through the same register-tiled loop as the convolution (one "neighbour"). */
void hrr_block(const float *x, int B, int cin, int cout, int V, const int32_t *offsets,
               const int32_t *nbr, const float *K, const float *bias, const float *pool,
               const float *proj, float a, float b, int elu, int threads, float *out)
{
    conv_fn conv = cout == 8 ? conv8 : cout == 16 ? conv16 : cout == 32 ? conv32 : cout == 64 ? conv64 : conv128;
    #pragma omp parallel num_threads(threads)
    {
        const unsigned csr = denormals_off();
        float *acc = (float *)aligned_alloc(64, (((size_t)B * cout * 4 + 63) / 64) * 64);
        float *mapped = (float *)aligned_alloc(64, (((size_t)B * cout * 4 + 63) / 64) * 64);
        float *res = (float *)aligned_alloc(64, (((size_t)B * cin * 4 + 63) / 64) * 64);
        float *zeros = (float *)calloc(cout, sizeof(float));
        #pragma omp for schedule(static)
        for (int v = 0; v < V; ++v) {
            const int j0 = offsets[v], j1 = offsets[v + 1];
            conv(acc, x, B, cin, j0, j1, nbr, K, bias);
            const float *src = x;
            int32_t row = v;
            if (pool) {
                memset(res, 0, sizeof(float) * (size_t)B * cin);
                for (int j = j0; j < j1; ++j) {
                    const float w = pool[j];
                    const float *restrict xs = x + (size_t)nbr[j] * B * cin;
                    #pragma omp simd
                    for (size_t i = 0; i < (size_t)B * cin; ++i) res[i] += w * xs[i];
                }
                src = res;
                row = 0;
            }
            const float *r = src + (size_t)row * B * cin;
            if (proj) {
                conv(mapped, src, B, cin, 0, 1, &row, proj, zeros);
                r = mapped;
            }
            float *d = out + (size_t)v * B * cout;
            const size_t n = (size_t)B * cout;
            if (elu) {
                #pragma omp simd
                for (size_t i = 0; i < n; ++i) {
                    const float y = acc[i];
                    d[i] = a * (y > 0.0f ? y : exp_nonpositive(y < 0.0f ? y : 0.0f) - 1.0f) + b * r[i];
                }
            } else {
                #pragma omp simd
                for (size_t i = 0; i < n; ++i) d[i] = a * acc[i] + b * r[i];
            }
        }
        free(acc);
        free(mapped);
        free(res);
        free(zeros);
        denormals_restore(csr);
    }
}

/* Signed distance of points to the union of C capsules (one frame's capsule ends ca, cb (C, 3),
   radii (C)): for entries i0 .. i1 (at most SDF_CHUNK) of the point list idx (NULL: 0, 1, ...),
   point k = idx[i], writes dist[k] (negative inside) and the nearest capsule's outward unit
   normal normal[k]. Capsules outer, points inner in structure-of-arrays form, so the inner loop
   has no division and vectorises across points. */
enum { SDF_CHUNK = 256, SDF_MAXC = 64 };

static void sdf_chunk(const double *p, const int32_t *idx, int i0, int i1, const double *ca, const double *cb,
                      const double *radii, int C, double *dist, double *normal)
{
    double cax[SDF_MAXC], cay[SDF_MAXC], caz[SDF_MAXC], cex[SDF_MAXC], cey[SDF_MAXC], cez[SDF_MAXC], cinv[SDF_MAXC];
    for (int c = 0; c < C; ++c) {
        cax[c] = ca[3 * c]; cay[c] = ca[3 * c + 1]; caz[c] = ca[3 * c + 2];
        cex[c] = cb[3 * c] - cax[c]; cey[c] = cb[3 * c + 1] - cay[c]; cez[c] = cb[3 * c + 2] - caz[c];
        const double den = cex[c] * cex[c] + cey[c] * cey[c] + cez[c] * cez[c];
        cinv[c] = 1.0 / (den > 1e-12 ? den : 1e-12);
    }
    double px[SDF_CHUNK], py[SDF_CHUNK], pz[SDF_CHUNK], best[SDF_CHUNK], bx[SDF_CHUNK], by[SDF_CHUNK], bz[SDF_CHUNK],
           baxis[SDF_CHUNK];
    const int n = i1 - i0;
    for (int i = 0; i < n; ++i) {
        const int k = idx ? idx[i0 + i] : i0 + i;
        px[i] = p[3 * k]; py[i] = p[3 * k + 1]; pz[i] = p[3 * k + 2];
        best[i] = 1e300; bx[i] = 0; by[i] = 0; bz[i] = 0; baxis[i] = 1;
    }
    for (int c = 0; c < C; ++c) {
        const double ax = cax[c], ay = cay[c], az = caz[c], ex = cex[c], ey = cey[c], ez = cez[c];
        const double inv_den = cinv[c], r = radii[c];
        #pragma omp simd
        for (int i = 0; i < n; ++i) {
            const double rx = px[i] - ax, ry = py[i] - ay, rz = pz[i] - az;
            double s = (rx * ex + ry * ey + rz * ez) * inv_den;
            s = s < 0 ? 0 : (s > 1 ? 1 : s);
            const double dx = rx - s * ex, dy = ry - s * ey, dz = rz - s * ez;
            const double axis = sqrt(dx * dx + dy * dy + dz * dz);
            const double sd = axis - r;
            const int closer = sd < best[i];
            best[i] = closer ? sd : best[i];
            bx[i] = closer ? dx : bx[i]; by[i] = closer ? dy : by[i]; bz[i] = closer ? dz : bz[i];
            baxis[i] = closer ? axis : baxis[i];
        }
    }
    for (int i = 0; i < n; ++i) {
        const int k = idx ? idx[i0 + i] : i0 + i;
        const double inv = 1.0 / (baxis[i] > 1e-12 ? baxis[i] : 1e-12);
        dist[k] = best[i];
        normal[3 * k] = bx[i] * inv; normal[3 * k + 1] = by[i] * inv; normal[3 * k + 2] = bz[i] * inv;
    }
}

static void sdf_points(const double *p, const int32_t *idx, int n, const double *ca, const double *cb,
                       const double *radii, int C, double *dist, double *normal)
{
    for (int i0 = 0; i0 < n; i0 += SDF_CHUNK)
        sdf_chunk(p, idx, i0, i0 + SDF_CHUNK < n ? i0 + SDF_CHUNK : n, ca, cb, radii, C, dist, normal);
}

/* Frame by frame: points (T, N, 3), capsule ends a, b (T, C, 3) -> dist (T, N), normal (T, N, 3). */
void hrr_capsule_sdf(const double *p, int T, int N, const double *a, const double *b, const double *radii,
                     int C, int threads, double *dist, double *normal)
{
    const int chunks = (N + SDF_CHUNK - 1) / SDF_CHUNK;
    #pragma omp parallel for num_threads(threads) schedule(static)
    for (long job = 0; job < (long)T * chunks; ++job) {
        const int t = (int)(job / chunks), i0 = (int)(job % chunks) * SDF_CHUNK;
        sdf_chunk(p + (size_t)t * N * 3, NULL, i0, i0 + SDF_CHUNK < N ? i0 + SDF_CHUNK : N,
                  a + (size_t)t * 3 * C, b + (size_t)t * 3 * C, radii, C, dist + (size_t)t * N, normal + (size_t)t * N * 3);
    }
}

/* The collision push-out of hrr_garment/inference/collision.py for one frame, the same steps:
   distances; `rounds` times: each vertex needing to move (within `margin` of the body or inside)
   gets need * normal, spread by `smooth` Jacobi passes of the row-normalised adjacency (CSR
   indptr/indices/weights) that never lower a pushed vertex's push along its normal; then up to
   four exact projections of the vertices still inside. Only moved vertices are measured again.
   before/after: fractions of vertices deeper than `depth`. */
static void push_frame(double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                       const int32_t *indptr, const int32_t *indices, const double *weights, double margin,
                       int smooth, int rounds, double depth, double *before, double *after)
{
    double *d = (double *)malloc(sizeof(double) * (size_t)V * 12);
    double *nrm = d + V, *need = nrm + 3 * (size_t)V, *disp = need + V, *tmp = disp + 3 * (size_t)V;
    int32_t *list = (int32_t *)malloc(sizeof(int32_t) * (size_t)V);
    sdf_points(p, NULL, V, ca, cb, radii, C, d, nrm);
    int deep = 0;
    for (int v = 0; v < V; ++v) deep += d[v] < -depth;
    *before = (double)deep / V;
    for (int r = 0; r < rounds; ++r) {
        int any = 0;
        for (int v = 0; v < V; ++v) {
            need[v] = margin - d[v] > 0.0 ? margin - d[v] : 0.0;
            any |= need[v] > 0.0;
            for (int k = 0; k < 3; ++k) disp[3 * v + k] = need[v] * nrm[3 * v + k];
        }
        if (!any) break;
        for (int s = 0; s < smooth; ++s) {
            for (int v = 0; v < V; ++v) {
                double x = 0.0, y = 0.0, z = 0.0;
                for (int j = indptr[v]; j < indptr[v + 1]; ++j) {
                    const double w = weights[j], *q = disp + 3 * (size_t)indices[j];
                    x += w * q[0]; y += w * q[1]; z += w * q[2];
                }
                if (need[v] > 0.0) {
                    const double *nv = nrm + 3 * (size_t)v;
                    double shortfall = need[v] - (x * nv[0] + y * nv[1] + z * nv[2]);
                    shortfall = shortfall > 0.0 ? shortfall : 0.0;
                    x += shortfall * nv[0]; y += shortfall * nv[1]; z += shortfall * nv[2];
                }
                tmp[3 * v] = x; tmp[3 * v + 1] = y; tmp[3 * v + 2] = z;
            }
            double *swap = disp; disp = tmp; tmp = swap;
        }
        int m = 0;
        for (int v = 0; v < V; ++v) {
            const double *q = disp + 3 * (size_t)v;
            if (q[0] != 0.0 || q[1] != 0.0 || q[2] != 0.0) {
                p[3 * v] += q[0]; p[3 * v + 1] += q[1]; p[3 * v + 2] += q[2];
                list[m++] = v;
            }
        }
        sdf_points(p, list, m, ca, cb, radii, C, d, nrm);
    }
    for (int it = 0; it < 4; ++it) {
        int m = 0;
        for (int v = 0; v < V; ++v)
            if (d[v] < 0.0) list[m++] = v;
        if (m == 0) break;
        for (int i = 0; i < m; ++i) {
            const int v = list[i];
            for (int k = 0; k < 3; ++k) p[3 * v + k] += (margin - d[v]) * nrm[3 * v + k];
        }
        sdf_points(p, list, m, ca, cb, radii, C, d, nrm);
    }
    deep = 0;
    for (int v = 0; v < V; ++v) deep += d[v] < -depth;
    *after = (double)deep / V;
    free(list);
    free(d);  /* heads the block; disp and tmp were swapped within it */
}

void hrr_push_out(double *p, int T, int V, const double *a, const double *b, const double *radii, int C,
                  const int32_t *indptr, const int32_t *indices, const double *weights, double margin, int smooth,
                  int rounds, double depth, int threads, double *before, double *after)
{
    #pragma omp parallel for num_threads(threads) schedule(dynamic)
    for (int t = 0; t < T; ++t)
        push_frame(p + (size_t)t * V * 3, V, a + (size_t)t * 3 * C, b + (size_t)t * 3 * C, radii, C, indptr, indices,
                   weights, margin, smooth, rounds, depth, before + t, after + t);
}

/* One frame, factored and transformed first (streaming): with y = x W (Vin, (M + 1) * WIDTH), the
   input already multiplied by each of the layer's M shared basis kernels and by the residual's
   1x1 map (column block M), each block zero-padded from cout to WIDTH columns,
     out[v] = a * act(bias + sum_j sum_m coeff[j, m] y[nbr[j], m]) + b * res(v),
   res(v) = sum_j pool[j] y[nbr[j], M] (pool given) or y[v, M]. Per frame this reads the basis
   coefficients (nnz x M floats) instead of the folded per-vertex kernels (C_in x C_out times
   larger), and multiplying before gathering costs C_in / C_out times less where channels shrink.
   The WIDTH accumulators of a vertex stay in vector registers (WIDTH fixed per variant). */
#define LOAD(PTR) ({ VT t_; memcpy(&t_, (PTR), sizeof(VT)); t_; })
#define DEFINE_APPLY(NAME, WIDTH_, VT_, LANES_)                                                 \
    static void NAME(const float *restrict y, int M, int cout, int v0, int v1,                 \
                     const int32_t *restrict offsets, const int32_t *restrict nbr,             \
                     const float *restrict coeff, const float *restrict pool,                  \
                     const float *restrict bias, float a, float b, int elu, float *restrict out) \
    {                                                                                          \
        typedef VT_ VT;                                                                        \
        enum { WIDTH = WIDTH_, LANES = LANES_, NB = WIDTH_ / LANES_ };                          \
        const size_t ld = (size_t)(M + 1) * WIDTH;                                             \
        for (int v = v0; v < v1; ++v) {                                                        \
            float za[WIDTH], zr[WIDTH];                                                        \
            for (int q = 0; q < NB; ++q) {                                                     \
                /* four independent accumulators: one chain of FMAs would wait on each */      \
                VT a0 = LOAD(bias + q * LANES), a1 = a0 * 0.0f, a2 = a1, a3 = a1, r = a1;      \
                for (int j = offsets[v]; j < offsets[v + 1]; ++j) {                            \
                    const float *restrict yr = y + (size_t)nbr[j] * ld + q * LANES;            \
                    const float *restrict c = coeff + (size_t)j * M;                           \
                    int m = 0;                                                                 \
                    for (; m + 4 <= M; m += 4) {                                               \
                        a0 += c[m] * LOAD(yr + (size_t)m * WIDTH);                             \
                        a1 += c[m + 1] * LOAD(yr + (size_t)(m + 1) * WIDTH);                   \
                        a2 += c[m + 2] * LOAD(yr + (size_t)(m + 2) * WIDTH);                   \
                        a3 += c[m + 3] * LOAD(yr + (size_t)(m + 3) * WIDTH);                   \
                    }                                                                          \
                    for (; m < M; ++m) a0 += c[m] * LOAD(yr + (size_t)m * WIDTH);              \
                    if (pool) r += pool[j] * LOAD(yr + (size_t)M * WIDTH);                     \
                }                                                                              \
                const VT sum = (a0 + a1) + (a2 + a3);                                          \
                memcpy(za + q * LANES, &sum, sizeof(VT));                                      \
                memcpy(zr + q * LANES, &r, sizeof(VT));                                        \
            }                                                                                  \
            if (!pool)                                                                         \
                memcpy(zr, y + (size_t)v * ld + (size_t)M * WIDTH, sizeof(float) * WIDTH);     \
            if (elu) {                                                                         \
                _Pragma("omp simd")                                                            \
                for (int i = 0; i < WIDTH; ++i)                                                \
                    za[i] = za[i] > 0.0f ? za[i] : exp_nonpositive(za[i] < 0.0f ? za[i] : 0.0f) - 1.0f; \
            }                                                                                  \
            float *d = out + (size_t)v * cout;                                                 \
            _Pragma("omp simd")                                                                \
            for (int i = 0; i < cout; ++i) d[i] = a * za[i] + b * zr[i];                       \
        }                                                                                      \
    }

typedef float v4sf __attribute__((vector_size(16)));
DEFINE_APPLY(apply4, 4, v4sf, 4)
DEFINE_APPLY(apply8, 8, v8sf, 8)
DEFINE_APPLY(apply16, 16, v16sf, 16)
DEFINE_APPLY(apply32, 32, v16sf, 16)
DEFINE_APPLY(apply64, 64, v16sf, 16)
DEFINE_APPLY(apply128, 128, v16sf, 16)

typedef void (*apply_fn)(const float *restrict, int, int, int, int, const int32_t *restrict, const int32_t *restrict,
                         const float *restrict, const float *restrict, const float *restrict, float, float, int,
                         float *restrict);

/* width: the padded block width of y, one of 4, 8, 16, 32, 64, 128 (>= cout); bias has width values. */
void hrr_factor_apply(const float *y, int M, int cout, int width, int V, const int32_t *offsets, const int32_t *nbr,
                      const float *coeff, const float *pool, const float *bias, float a, float b, int elu,
                      int threads, float *out)
{
    apply_fn fn = width == 4 ? apply4 : width == 8 ? apply8 : width == 16 ? apply16 : width == 32 ? apply32
                : width == 64 ? apply64 : apply128;
    enum { CHUNK = 64 };
    const int chunks = (V + CHUNK - 1) / CHUNK;
    #pragma omp parallel num_threads(threads)
    {
        const unsigned csr = denormals_off();
        #pragma omp for schedule(static)
        for (int k = 0; k < chunks; ++k) {
            const int v1 = (k + 1) * CHUNK < V ? (k + 1) * CHUNK : V;
            fn(y, M, cout, k * CHUNK, v1, offsets, nbr, coeff, pool, bias, a, b, elu, out);
        }
        denormals_restore(csr);
    }
}
"""

FLAGS = ["-O3", "-march=native", "-mprefer-vector-width=512", "-fno-math-errno", "-fno-trapping-math", "-fopenmp",
         "-Werror=implicit-function-declaration",
         "-shared", "-fPIC"]
WIDTHS = (8, 16, 32, 64, 128)  # output widths the kernel is specialised for
APPLY_WIDTHS = (4, 8, 16, 32, 64, 128)  # block widths of the single-frame kernel
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
    return hashlib.sha1("\0".join([SOURCE, *FLAGS, _cpu_signature()]).encode()).hexdigest()[:16]


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
                c_int, c_float = ctypes.c_int, ctypes.c_float
                lib.hrr_block.argtypes = [f, c_int, c_int, c_int, c_int, i32, i32, f, f, f, f, c_float, c_float, c_int,
                                          c_int, f]
                lib.hrr_block.restype = None
                d = ctypes.c_void_p  # addresses from ndarray.ctypes.data: per-frame calls, so the cheapest conversion
                lib.hrr_capsule_sdf.argtypes = [d, c_int, c_int, d, d, d, c_int, c_int, d, d]
                lib.hrr_capsule_sdf.restype = None
                c_double = ctypes.c_double
                lib.hrr_push_out.argtypes = [d, c_int, c_int, d, d, d, c_int, d, d, d, c_double, c_int, c_int, c_double,
                                             c_int, d, d]
                lib.hrr_push_out.restype = None
                lib.hrr_factor_apply.argtypes = [ctypes.c_void_p, c_int, c_int, c_int, c_int, i32, i32, f, f, f, c_float,
                                                 c_float, c_int, c_int, ctypes.c_void_p]
                lib.hrr_factor_apply.restype = None
                _loaded[str(target)] = lib
            except (OSError, subprocess.CalledProcessError) as exc:
                detail = getattr(exc, "stderr", "") or str(exc)
                warnings.warn(f"native decoder kernel unavailable, using the PyTorch path: {detail[:500]}", RuntimeWarning)
                _loaded[str(target)] = None
        _requests[request] = _loaded[str(target)]
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
        width = next((w for w in WIDTHS if w >= cout), None)
        if width is None:
            raise ValueError(f"the native kernel handles up to {WIDTHS[-1]} output channels, not {cout}")
        pad = [(0, 0)] * 2 + [(0, width - cout)]  # zero columns: the kernel's widths are fixed
        self.kernel = np.ascontiguousarray(np.pad(kernel.reshape(v, s, cin, cout)[keep], pad), np.float32)  # (nnz, cin, width)
        self.bias = np.ascontiguousarray(np.pad(bias, (0, width - cout)), np.float32)
        self.pool = None if pool is None else np.ascontiguousarray(pool[keep], np.float32)
        if proj is None and width != cout:
            proj = np.eye(cin, cout, dtype=np.float32)
        self.proj = None if proj is None else np.ascontiguousarray(np.pad(proj, [(0, 0), (0, width - cout)]), np.float32)
        self.cin, self.cout, self.width, self.vertices = cin, cout, width, v
        self.a, self.b, self.elu = float(a), float(b), bool(elu)
        self.factored = None  # (transform (cin, (M + 1) * width), kernel arguments, arrays) via set_factored

    def set_factored(self, coeff: np.ndarray, basis: np.ndarray, mask: np.ndarray, proj: np.ndarray | None) -> None:
        """Basis coefficients (V, S, M) and basis (M, cin, cout) for single frames (``one``)."""
        keep = mask > 0
        m, cin, cout = basis.shape
        width = next(w for w in APPLY_WIDTHS if w >= cout)
        proj = np.eye(cin, cout, dtype=np.float32) if proj is None else proj  # identity residual: cin == cout
        # x (Vin, cin) @ transform = [x W_0 | ... | x W_{M-1} | x proj], each block padded to width
        blocks = np.concatenate([basis, proj[None]], 0)  # (M + 1, cin, cout)
        blocks = np.pad(blocks, [(0, 0), (0, 0), (0, width - cout)]).transpose(1, 0, 2).reshape(cin, (m + 1) * width)
        coeff = np.ascontiguousarray(coeff[keep], np.float32)
        bias = np.ascontiguousarray(np.pad(self.bias[:cout], (0, width - cout)), np.float32)
        # the constant arguments, converted once: ctypes conversions cost microseconds each, per frame
        constants = (m, self.cout, width, self.vertices, _ptr(self.offsets, ctypes.c_int32), _ptr(self.nbr, ctypes.c_int32),
                     _ptr(coeff), _ptr(self.pool), _ptr(bias), ctypes.c_float(self.a), ctypes.c_float(self.b), int(self.elu))
        self.factored = (torch.from_numpy(np.ascontiguousarray(blocks, np.float32)), constants, (coeff, bias))

    def one(self, lib: ctypes.CDLL, x: np.ndarray, threads: int) -> np.ndarray:
        """One frame: x (V_in, C_in) float32 -> (V, C_out), the same function as ``__call__``. The
        result lives in a buffer of the block that the next call overwrites (fresh buffers of up
        to a few MB per frame cost more in page faults than the arithmetic): one call at a time
        per decoder, and copy what you keep."""
        transform, constants, _ = self.factored  # the last item keeps the arrays behind the pointers alive
        if getattr(self, "_buffers", None) is None or self._buffers[0].shape[0] != len(x):
            self._buffers = (torch.empty(len(x), transform.shape[1]), np.empty((self.vertices, self.cout), np.float32))
        y, out = self._buffers
        torch.mm(torch.from_numpy(x), transform, out=y)  # one dense product per layer, multithreaded by torch
        lib.hrr_factor_apply(y.data_ptr(), *constants, threads, out.ctypes.data)
        return out

    def __call__(self, lib: ctypes.CDLL, x: np.ndarray, threads: int) -> np.ndarray:
        """x (V_in, B, C_in) float32 C-contiguous -> (V, B, C_out)."""
        batch = x.shape[1]
        out = np.empty((self.vertices, batch, self.width), np.float32)
        lib.hrr_block(_ptr(x), batch, self.cin, self.width, self.vertices, _ptr(self.offsets, ctypes.c_int32),
                      _ptr(self.nbr, ctypes.c_int32), _ptr(self.kernel), _ptr(self.bias),
                      _ptr(self.pool), _ptr(self.proj), self.a, self.b, int(self.elu), threads, _ptr(out))
        return out if self.width == self.cout else np.ascontiguousarray(out[..., :self.cout])


def capsule_sdf(lib: ctypes.CDLL, points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray,
                threads: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hrr_garment.body.capsules.capsule_signed_distance` (distance, normal) in the kernel,
    for points (T, N, 3) against per-frame capsules a, b (T, C, 3)."""
    if len(radii) > 64:
        raise ValueError(f"the native capsule distance handles up to 64 capsules, not {len(radii)}")
    p = np.ascontiguousarray(points, np.float64)
    a, b, r = (np.ascontiguousarray(x, np.float64) for x in (a, b, radii))
    t, n = p.shape[:2]
    dist, normal = np.empty((t, n)), np.empty((t, n, 3))
    lib.hrr_capsule_sdf(p.ctypes.data, t, n, a.ctypes.data, b.ctypes.data, r.ctypes.data, len(r), threads, dist.ctypes.data,
                        normal.ctypes.data)
    return dist, normal


def push_out_frames(lib: ctypes.CDLL, points: np.ndarray, a: np.ndarray, b: np.ndarray, radii: np.ndarray, mean,
                    margin: float, smooth: int, rounds: int, depth: float, threads: int = 1
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`hrr_garment.inference.collision.push_out`'s per-frame steps in the kernel: points
    (T, V, 3), capsule ends a, b (T, C, 3), ``mean`` the (V, V) CSR mean operator -> (pushed
    points float32, fraction deeper than ``depth`` before (T,), after (T,)). Frames in parallel."""
    if len(radii) > 64:
        raise ValueError(f"the native push-out handles up to 64 capsules, not {len(radii)}")
    p = np.array(points, np.float64, order="C")  # a copy: pushed in place
    a, b, r = (np.ascontiguousarray(x, np.float64) for x in (a, b, radii))
    indptr, indices = (np.ascontiguousarray(x, np.int32) for x in (mean.indptr, mean.indices))
    weights = np.ascontiguousarray(mean.data, np.float64)
    t, v = p.shape[:2]
    before, after = np.empty(t), np.empty(t)
    lib.hrr_push_out(p.ctypes.data, t, v, a.ctypes.data, b.ctypes.data, r.ctypes.data, len(r), indptr.ctypes.data,
                     indices.ctypes.data, weights.ctypes.data, margin, smooth, rounds, depth, threads, before.ctypes.data,
                     after.ctypes.data)
    return p.astype(np.float32), before, after
