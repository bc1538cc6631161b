/* hrr_garment's native kernels, compiled on first use by hrr_garment/native/__init__.py (see its
   docstring): the workers' pinning, the mesh decoder's blocks, the register-tiled dense product
   (shared with window_codes.c) and the single-frame decoder. The push-out is in push_frame.c,
   strain_limit.c, subspace_push.c and push_out.c. */

#include "hrr_native.h"

#ifdef __linux__
#include <sched.h>
#endif

/* Pins the calling thread's OpenMP worker threads (not the calling thread) to distinct CPUs of
   its allowed set, skipping the CPU it runs on; returns how many were pinned, 0 where there is
   nothing to do (one thread, more threads than CPUs, not Linux), -1 on a failed system call.
   Why: a stream that idles between frames (a game loop at 30 frames/s) lets the workers fall
   asleep; the next frame's parallel region wakes them, and Linux may queue a woken worker on the
   caller's own CPU, behind the caller spinning at the region's barrier, until the next scheduler
   tick moves one of them: about 5 ms lost per frame on a 2-core VM (a 0.3 ms window step took
   5.9 ms after 30 ms asleep). A pinned worker wakes on its own CPU. OMP_PROC_BIND does the same
   but binds the caller too, and only if set before the runtime starts. */
int hrr_pin_workers(int threads)
{
#ifdef __linux__
    cpu_set_t allowed;
    if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) return -1;
    if (threads < 2 || threads > CPU_COUNT(&allowed)) return 0;
    const int caller = sched_getcpu();
    int cpus[CPU_SETSIZE], n = 0, pinned = 0, failed = 0;
    for (int c = 0; c < CPU_SETSIZE; ++c)
        if (CPU_ISSET(c, &allowed) && c != caller) cpus[n++] = c;
    if (n == 0) return 0;
    #pragma omp parallel num_threads(threads) reduction(+ : pinned, failed)
    {
        const int me = omp_get_thread_num();
        if (me > 0) {
            cpu_set_t one;
            CPU_ZERO(&one);
            CPU_SET(cpus[(me - 1) % n], &one);
            if (sched_setaffinity(0, sizeof one, &one) == 0) ++pinned; else ++failed;
        }
    }
    return failed ? -1 : pinned;
#else
    (void)threads;
    return 0;
#endif
}

/* The CPU the calling thread runs on (-1 where unknown): a pinned pool is re-pinned when its
   caller has moved to another CPU (which may be one of its workers'). */
int hrr_current_cpu(void)
{
#ifdef __linux__
    return sched_getcpu();
#else
    return -1;
#endif
}

/* acc (B, COUT) = bias + sum_j x[nbr[j]] (B, cin) times K[j] (cin, COUT). Neighbour slot outer,
   so its kernel block (cin x COUT, at most 64 KB) stays in L1 while all B frames pass through it;
   then one LANES-wide column block at a time and RB frames at a time, so the RB accumulators stay
   in vector registers (GCC vector extensions; VT holds LANES floats) and one kernel-row load feeds
   RB fused multiply-adds with broadcast operands. */
#define TILE(ROWS)                                                                             \
    for (int q = 0; q < COUT; q += LANES) {                                                    \
        VT t[ROWS]; /* loaded and stored through copies: an accumulator whose address is taken stays on the stack */ \
        for (int r = 0; r < ROWS; ++r) { VT v_; memcpy(&v_, acc + (size_t)(bb + r) * COUT + q, sizeof(VT)); t[r] = v_; } \
        const float *restrict xs = xj + (size_t)bb * cin;                                      \
        for (int c = 0; c < cin; ++c) {                                                        \
            VT kv;                                                                             \
            memcpy(&kv, k + (size_t)c * COUT + q, sizeof(VT));                                 \
            for (int r = 0; r < ROWS; ++r) t[r] += xs[(size_t)r * cin + c] * kv;               \
        }                                                                                      \
        for (int r = 0; r < ROWS; ++r) { const VT v_ = t[r]; memcpy(acc + (size_t)(bb + r) * COUT + q, &v_, sizeof(VT)); } \
    }

#define DEFINE_CONV(NAME, COUT_, VT_, LANES_)                                                  \
    static void NAME(float *restrict acc, const float *restrict x, int B, int cin, int j0,      \
                     int j1, const int32_t *restrict nbr, const float *restrict K,             \
                     const float *restrict bias)                                               \
    {                                                                                          \
        typedef VT_ VT;                                                                        \
        /* 16 accumulators fit AVX-512's 32 registers; AVX2 holds 12 of its 16 */              \
        enum { COUT = COUT_, LANES = LANES_, RB = WIDE_REGISTERS ? 16 : 12 };                  \
        for (int bb = 0; bb < B; ++bb) memcpy(acc + (size_t)bb * COUT, bias, sizeof(float) * COUT); \
        for (int j = j0; j < j1; ++j) {                                                        \
            const float *restrict xj = x + (size_t)nbr[j] * B * cin;                           \
            const float *restrict k = K + (size_t)j * cin * COUT;                              \
            int bb = 0;                                                                        \
            for (; bb + RB <= B; bb += RB) TILE(RB)                                            \
            for (; bb < B; ++bb) TILE(1)                                                       \
        }                                                                                      \
    }

/* GCC splits a 16-float vector into two 8-float halves on AVX2, and does it through the stack:
   there every accumulator is 8 floats wide */
#if WIDE_REGISTERS
typedef v16sf vwide;
enum { WIDE_LANES = 16 };
#else
typedef v8sf vwide;
enum { WIDE_LANES = 8 };
#endif
DEFINE_CONV(conv8, 8, v8sf, 8)
DEFINE_CONV(conv16, 16, vwide, WIDE_LANES)
DEFINE_CONV(conv32, 32, vwide, WIDE_LANES)
DEFINE_CONV(conv64, 64, vwide, WIDE_LANES)
DEFINE_CONV(conv128, 128, vwide, WIDE_LANES)

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

/* Y (n, out) = X (n, in) W^T + b, with W^T (in, out) packed in panels of PANEL columns: panel k
   holds columns PANEL k .. PANEL k + PANEL - 1 as (in, PANEL) contiguous floats, zero past out
   (bias padded likewise). A panel streams through in order (weights come from L3: a window step
   reads about 7 MB of them, more than L2 holds, and strided rows defeat the prefetcher) into a tile
   of R rows x PANEL columns of accumulators in registers, each X value broadcast: no horizontal
   sums. Used by the window step (window_codes.c) and the single-frame decoder. */
static inline v16sf load16(const float *p) { v16sf v; memcpy(&v, p, sizeof v); return v; }

/* stores through a copy: taking an accumulator's own address kept the whole tile on the stack
   (every multiply-add a load and a store), which GCC does on AVX2 */
#define STORE_TILE_COLUMN(R, c, acc_of)                                                                \
    for (int r = 0; r < R; ++r) {                                                                      \
        const int n = cols - 16 * (c);                                                                 \
        const v16sf v_ = acc_of;                                                                       \
        if (n >= 16) memcpy(Y + (size_t)r * out + 16 * (c), &v_, 64); /* a vector store */              \
        else memcpy(Y + (size_t)r * out + 16 * (c), &v_, sizeof(float) * n);                            \
    }
#if WIDE_REGISTERS
/* R rows x C vectors of accumulators at once: 20 of AVX-512's 32 registers at 5 x 4 */
#define DEFINE_TILE(R, C)                                                                              \
    static void tile_##R##_##C(const float *restrict X, int in, const float *restrict panel,           \
                               const float *restrict b, float *restrict Y, int out, int cols)          \
    {                                                                                                  \
        v16sf acc[R][C];                                                                               \
        for (int c = 0; c < C; ++c) {                                                                  \
            const v16sf bias = load16(b + 16 * c);                                                     \
            for (int r = 0; r < R; ++r) acc[r][c] = bias;                                              \
        }                                                                                              \
        for (int i = 0; i < in; ++i) {                                                                 \
            v16sf w[C];                                                                                \
            for (int c = 0; c < C; ++c) w[c] = load16(panel + (size_t)i * PANEL + 16 * c);             \
            for (int r = 0; r < R; ++r) {                                                              \
                const float x = X[(size_t)r * in + i];                                                 \
                for (int c = 0; c < C; ++c) acc[r][c] += x * w[c];                                     \
            }                                                                                          \
        }                                                                                              \
        for (int c = 0; c < C; ++c) STORE_TILE_COLUMN(R, c, acc[r][c])                                 \
    }
#else
/* one 16-column group at a time as two 8-float halves (R x 2 AVX2 registers, 10 at 5 rows, plus
   the two weight halves): the X rows are read C times, the weights once, as above */
static inline v8sf load8(const float *p) { v8sf v; memcpy(&v, p, sizeof v); return v; }
#define DEFINE_TILE(R, C)                                                                              \
    static void tile_##R##_##C(const float *restrict X, int in, const float *restrict panel,           \
                               const float *restrict b, float *restrict Y, int out, int cols)          \
    {                                                                                                  \
        for (int c = 0; c < C; ++c) {                                                                  \
            v8sf lo[R], hi[R];                                                                         \
            const v8sf blo = load8(b + 16 * c), bhi = load8(b + 16 * c + 8);                           \
            for (int r = 0; r < R; ++r) { lo[r] = blo; hi[r] = bhi; }                                  \
            for (int i = 0; i < in; ++i) {                                                             \
                const v8sf wlo = load8(panel + (size_t)i * PANEL + 16 * c);                            \
                const v8sf whi = load8(panel + (size_t)i * PANEL + 16 * c + 8);                        \
                for (int r = 0; r < R; ++r) {                                                          \
                    const float x = X[(size_t)r * in + i];                                             \
                    lo[r] += x * wlo;                                                                  \
                    hi[r] += x * whi;                                                                  \
                }                                                                                      \
            }                                                                                          \
            for (int r = 0; r < R; ++r) {                                                              \
                const int n = cols - 16 * c;                                                           \
                float v_[16];                                                                          \
                const v8sf a_ = lo[r], b_ = hi[r];                                                     \
                memcpy(v_, &a_, 32);                                                                   \
                memcpy(v_ + 8, &b_, 32);                                                               \
                memcpy(Y + (size_t)r * out + 16 * c, v_, sizeof(float) * (n >= 16 ? 16 : n));         \
            }                                                                                          \
        }                                                                                              \
    }
#endif
DEFINE_TILE(5, 1)
DEFINE_TILE(5, 2)
DEFINE_TILE(5, 3)
DEFINE_TILE(5, 4)
DEFINE_TILE(1, 1)
DEFINE_TILE(1, 2)
DEFINE_TILE(1, 3)
DEFINE_TILE(1, 4)

/* by rows (5 or 1) and 16-column vectors (1 to 4): a partial last panel computes only what it needs */
static const tile_fn TILES[2][4] = {{tile_1_1, tile_1_2, tile_1_3, tile_1_4}, {tile_5_1, tile_5_2, tile_5_3, tile_5_4}};

static void linear_rows(const float *restrict X, int n, int in, const float *restrict Wp, const float *restrict b,
                        int out, float *restrict Y)
{
    for (int t = 0; t < n;) {
        const int rows = n - t >= 5 ? 5 : 1;
        for (int o = 0; o < out; o += PANEL) {
            const float *panel = Wp + (size_t)o * in;  /* after o / PANEL panels of in x PANEL */
            const int cols = out - o < PANEL ? out - o : PANEL;
            TILES[rows == 5][(cols + 15) / 16 - 1](X + (size_t)t * in, in, panel, b + o, Y + (size_t)t * out + o, out,
                                                   cols);
        }
        t += rows;
    }
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
DEFINE_APPLY(apply16, 16, vwide, WIDE_LANES)
DEFINE_APPLY(apply32, 32, vwide, WIDE_LANES)
DEFINE_APPLY(apply64, 64, vwide, WIDE_LANES)
DEFINE_APPLY(apply128, 128, vwide, WIDE_LANES)

typedef void (*apply_fn)(const float *restrict, int, int, int, int, const int32_t *restrict, const int32_t *restrict,
                         const float *restrict, const float *restrict, const float *restrict, float, float, int,
                         float *restrict);

/* width: the padded block width of y, one of 4, 8, 16, 32, 64, 128 (>= cout); bias has width values. */
/* One decoder block for one frame in one parallel region: y (Vin, (M + 1) * width) = x (Vin, cin)
   times the transform (packed in panels; zeros: a zero bias as long as a row of y), rows shared
   among the threads, then the apply above, vertex chunks shared. */
void hrr_factor_block(const float *x, int Vin, int cin, const float *transform, const float *zeros, float *y, int M,
                      int cout, int width, int V, const int32_t *offsets, const int32_t *nbr, const float *coeff,
                      const float *pool, const float *bias, float a, float b, int elu, int threads, float *out)
{
    apply_fn fn = width == 4 ? apply4 : width == 8 ? apply8 : width == 16 ? apply16 : width == 32 ? apply32
                : width == 64 ? apply64 : apply128;
    enum { CHUNK = 64, ROWS = 5 };
    const int chunks = (V + CHUNK - 1) / CHUNK, row_blocks = (Vin + ROWS - 1) / ROWS, ld = (M + 1) * width;
    #pragma omp parallel num_threads(threads)
    {
        const unsigned csr = denormals_off();
        #pragma omp for schedule(static)
        for (int r = 0; r < row_blocks; ++r) {
            const int rows = Vin - r * ROWS < ROWS ? Vin - r * ROWS : ROWS;
            linear_rows(x + (size_t)r * ROWS * cin, rows, cin, transform, zeros, ld, y + (size_t)r * ROWS * ld);
        }
        #pragma omp for schedule(static)
        for (int k = 0; k < chunks; ++k) {
            const int v1 = (k + 1) * CHUNK < V ? (k + 1) * CHUNK : V;
            fn(y, M, cout, k * CHUNK, v1, offsets, nbr, coeff, pool, bias, a, b, elu, out);
        }
        denormals_restore(csr);
    }
}
