/* amx_block.c: the mesh decoder's batched block in bfloat16 on Intel's AMX tile unit (Sapphire
   Rapids and newer), for crowds. The same function as hrr_block in kernels.c,
     out[v] = a * act(bias + sum_j x[nbr[j]] K[j]) + b * residual(v),
   with x, the kernels and the residual map rounded to bfloat16 and every sum kept in float32.

   Why: a 32-character crowd's decoder multiplies every frame through 130 MB of float32 per-vertex
   kernels; on 2 AVX-512 cores that ran at about 50 GMAC/s, bounded by both the arithmetic and the
   stream of kernels. One AMX tile product (16 frames x 32 inputs x 16 outputs) does in about 16
   cycles what takes AVX-512 256 fused multiply-adds, and bfloat16 halves the stream.

   Layouts: x (Vin, Bp, cin) bfloat16, Bp frames a multiple of 16 (the caller pads with zero
   frames); the kernels in AMX's pair-interleaved ("VNNI") form, K[j] as (cin / 2, width, 2): input
   rows 2p and 2p + 1 of column n side by side. width: the padded output width, a multiple of 16,
   or 4 or 8 (one narrow tile). cin: a multiple of 32, or 8 or 16 (one short step). The residual's
   1x1 map runs first, over the input vertices (P = x proj, float32): the decoder's blocks grow the
   mesh, so projecting before the neighbour average costs a quarter of projecting after it. */

#include "hrr_native.h"

#if defined(__AMX_TILE__) && defined(__AMX_BF16__) && defined(__linux__)
#define HRR_AMX 1
#include <immintrin.h>
#include <sys/syscall.h>
#include <unistd.h>
#else
#define HRR_AMX 0
#endif

/* 1 where this build and this process can use AMX: Linux hands the tile registers' state to a
   process only on request (arch_prctl ARCH_REQ_XCOMP_PERM for XTILEDATA), process-wide. */
int hrr_amx_ready(void)
{
#if HRR_AMX
    static int ready = -1;
    if (ready < 0) ready = syscall(SYS_arch_prctl, 0x1023 /* ARCH_REQ_XCOMP_PERM */, 18 /* XTILEDATA */) == 0;
    return ready;
#else
    return 0;
#endif
}

#if HRR_AMX
typedef struct {
    uint8_t palette, start_row, reserved[14];
    uint16_t colsb[16];
    uint8_t rows[16];
} tile_config;

/* tiles 0-3: accumulators (2 frame blocks x 2 column blocks), 4-5: x rows, 6-7: kernel rows.
   step: inputs per product (cin, or 32); cols: output columns per tile (width, or 16) */
static void configure_tiles(int step, int cols)
{
    tile_config c;
    memset(&c, 0, sizeof c);
    c.palette = 1;
    for (int t = 0; t < 4; ++t) { c.rows[t] = 16; c.colsb[t] = (uint16_t)(cols * 4); }
    for (int t = 4; t < 6; ++t) { c.rows[t] = 16; c.colsb[t] = (uint16_t)(step * 2); }
    for (int t = 6; t < 8; ++t) { c.rows[t] = (uint8_t)(step / 2); c.colsb[t] = (uint16_t)(cols * 4); }
    _tile_loadconfig(&c);
}

/* acc (Bp, width) float32 = sum over j0 .. j1 of x[nbr[j]] K[j], for NR frame blocks of 16 from
   frame r and NC column tiles from column c; tile indices must be constants, hence a macro. */
#define AMX_PRODUCT(NR, NC)                                                                    \
    do {                                                                                       \
        _tile_zero(0);                                                                         \
        if (NC > 1) _tile_zero(1);                                                             \
        if (NR > 1) _tile_zero(2);                                                             \
        if (NR > 1 && NC > 1) _tile_zero(3);                                                   \
        for (int j = j0; j < j1; ++j) {                                                        \
            const uint16_t *xa = x + ((size_t)nbr[j] * Bp + r) * cin;                          \
            const uint16_t *kb = K + (size_t)j * cin * width + (size_t)c * 2;                  \
            for (int s = 0; s < cin; s += step) {                                              \
                _tile_loadd(4, xa + s, cin * 2);                                               \
                if (NR > 1) _tile_loadd(5, xa + (size_t)16 * cin + s, cin * 2);                \
                _tile_loadd(6, kb + (size_t)s * width, width * 4);                             \
                if (NC > 1) _tile_loadd(7, kb + (size_t)s * width + 32, width * 4);            \
                _tile_dpbf16ps(0, 4, 6);                                                       \
                if (NC > 1) _tile_dpbf16ps(1, 4, 7);                                           \
                if (NR > 1) _tile_dpbf16ps(2, 5, 6);                                           \
                if (NR > 1 && NC > 1) _tile_dpbf16ps(3, 5, 7);                                 \
            }                                                                                  \
        }                                                                                      \
        _tile_stored(0, acc + (size_t)r * width + c, width * 4);                               \
        if (NC > 1) _tile_stored(1, acc + (size_t)r * width + c + 16, width * 4);              \
        if (NR > 1) _tile_stored(2, acc + (size_t)(r + 16) * width + c, width * 4);            \
        if (NR > 1 && NC > 1) _tile_stored(3, acc + (size_t)(r + 16) * width + c + 16, width * 4); \
    } while (0)

static void amx_product(float *restrict acc, const uint16_t *restrict x, int Bp, int cin, int step, int width,
                        int j0, int j1, const int32_t *restrict nbr, const uint16_t *restrict K)
{
    for (int r = 0; r < Bp; r += 32) {
        const int two_rows = r + 32 <= Bp;
        for (int c = 0; c < width; c += 32) {
            const int two_cols = c + 32 <= width;
            if (two_rows && two_cols) AMX_PRODUCT(2, 2);
            else if (two_rows) AMX_PRODUCT(2, 1);
            else if (two_cols) AMX_PRODUCT(1, 2);
            else AMX_PRODUCT(1, 1);
        }
    }
}

/* ELU of 16 floats: y, or e^y - 1 below zero, with e^y = 2^k 2^f (k = round(y log2 e), |f| <= 1/2,
   2^f to degree 5: relative error 2.4e-6, far below bfloat16's 2^-9; half the operations of
   exp_nonpositive, and this loop is a third of the block) */
ALWAYS_INLINE __m512 elu16(__m512 y)
{
    const __m512 t = _mm512_mul_ps(_mm512_min_ps(y, _mm512_setzero_ps()), _mm512_set1_ps(1.44269504088896341f));
    const __m512 k = _mm512_roundscale_ps(t, _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    const __m512 f = _mm512_mul_ps(_mm512_sub_ps(t, k), _mm512_set1_ps(0.693147180559945f)); /* e^f = 2^(t - k) */
    __m512 p = _mm512_set1_ps(1.0f / 120.0f);
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 24.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 6.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(0.5f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f));
    const __m512 below = _mm512_sub_ps(_mm512_scalef_ps(p, k), _mm512_set1_ps(1.0f));
    return _mm512_mask_blend_ps(_mm512_cmp_ps_mask(y, _mm512_setzero_ps(), _CMP_GT_OQ), below, y);
}
#endif

/* One block for Bp frames (see the top of the file). proj (cin / 2, width, 2) bfloat16: the
   residual's 1x1 map (the identity where the block has none); P: float32 room for Vin x Bp x width.
   Writes out_bf16 (V, Bp, width), the next block's input, or out (V, Bp, width) float32 where
   out_bf16 is NULL. Returns 0, or -1 where this build or process has no AMX (nothing written). */
int hrr_block_bf16(const uint16_t *x, int Bp, int cin, int width, int Vin, int V, const int32_t *offsets,
                   const int32_t *nbr, const uint16_t *K, const float *bias, const float *pool, const uint16_t *proj,
                   float a, float b, int elu, int threads, float *P, uint16_t *out_bf16, float *out)
{
#if HRR_AMX
    if (!hrr_amx_ready() || Bp % 16 || !(cin % 32 == 0 || cin == 8 || cin == 16)
        || !(width % 16 == 0 || width == 4 || width == 8))
        return -1;
    const int step = cin < 32 ? cin : 32, cols = width < 16 ? width : 16;
    #pragma omp parallel num_threads(threads)
    {
        const unsigned csr = denormals_off();
        configure_tiles(step, cols);
        const size_t n = (size_t)Bp * width;
        float *acc = (float *)aligned_alloc(64, ((n * 4 + 63) / 64) * 64);
        float *bias_rows = (float *)aligned_alloc(64, ((n * 4 + 63) / 64) * 64); /* bias per frame: flat loops */
        for (size_t i = 0; i < n; ++i) bias_rows[i] = bias[i % width];
        #pragma omp for schedule(static)
        for (int u = 0; u < Vin; ++u) amx_product(P + (size_t)u * n, x, Bp, cin, step, width, 0, 1, &u, proj);
        /* the implicit barrier: every P row is ready */
        #pragma omp for schedule(static)
        for (int v = 0; v < V; ++v) {
            const int j0 = offsets[v], j1 = offsets[v + 1];
            amx_product(acc, x, Bp, cin, step, width, j0, j1, nbr, K);
            /* out = a act(acc + bias) + b residual, the residual the pooled projections (or this
               vertex's own), 16 floats at a time with the residual in a register */
            const size_t at = (size_t)v * n;
            const __m512 va = _mm512_set1_ps(a), vb = _mm512_set1_ps(b);
            for (size_t i = 0; i < n; i += 16) {
                __m512 r;
                if (pool) {
                    r = _mm512_setzero_ps();
                    for (int j = j0; j < j1; ++j)
                        r = _mm512_fmadd_ps(_mm512_set1_ps(pool[j]), _mm512_loadu_ps(P + (size_t)nbr[j] * n + i), r);
                } else {
                    r = _mm512_loadu_ps(P + at + i);
                }
                __m512 y = _mm512_add_ps(_mm512_load_ps(acc + i), _mm512_load_ps(bias_rows + i));
                if (elu) y = elu16(y);
                const __m512 o = _mm512_fmadd_ps(va, y, _mm512_mul_ps(vb, r));
                if (out_bf16) _mm256_storeu_si256((__m256i *)(out_bf16 + at + i), (__m256i)_mm512_cvtneps_pbh(o));
                else _mm512_storeu_ps(out + at + i, o);
            }
        }
        free(acc);
        free(bias_rows);
        _tile_release();
        denormals_restore(csr);
    }
    return 0;
#else
    (void)x; (void)Bp; (void)cin; (void)width; (void)Vin; (void)V; (void)offsets; (void)nbr; (void)K; (void)bias;
    (void)pool; (void)proj; (void)a; (void)b; (void)elu; (void)threads; (void)P; (void)out_bf16; (void)out;
    return -1;
#endif
}

/* The decoder's last rows (V, Bp, width) float32 -> frames out (B, V, C) = template (V, C) + scale *
   rows[:, :B, :C]: frames first, in one pass (PyTorch's strided add took 0.5 ms for 32 frames of
   4,156 vertices). */
void hrr_rows_to_frames(const float *rows, int V, int Bp, int width, int B, int C, const float *template_,
                        float scale, int threads, float *out)
{
    enum { CHUNK = 64 }; /* vertices per pass: their rows of every frame stay in L1, each frame's run is written whole */
    #pragma omp parallel for num_threads(threads) schedule(static)
    for (int v0 = 0; v0 < V; v0 += CHUNK) {
        const int v1 = v0 + CHUNK < V ? v0 + CHUNK : V;
        for (int f = 0; f < B; ++f)
            for (int v = v0; v < v1; ++v) {
                const float *restrict r = rows + ((size_t)v * Bp + f) * width;
                float *restrict o = out + ((size_t)f * V + v) * C;
                for (int c = 0; c < C; ++c) o[c] = template_[(size_t)v * C + c] + scale * r[c];
            }
    }
}
