/* hrr_garment's native kernels, compiled on first use by hrr_garment/native/__init__.py (see its
   docstring): the mesh decoder's blocks, the capsule-body distance, the collision push-out, the
   register-tiled dense product (shared with window_codes.c) and the single-frame decoder. */

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

/* Signed distance of points to the union of C capsules (one frame's capsule ends ca, cb (C, 3),
   radii (C)): for n points (px, py, pz; at most SDF_CHUNK), entries i0 .. i0 + n - 1 of the point
   list idx (NULL: 0, 1, ...), point k = idx[i], writes dist[k] (negative inside) and the nearest
   capsule's outward unit normal normal[k]. Capsules outer, points inner in structure-of-arrays
   form, so the inner loop has no division and vectorises across points. */
enum { SDF_CHUNK = 256, SDF_MAXC = 64 };

static void sdf_soa(const double *px, const double *py, const double *pz, const int32_t *idx, int i0, int n,
                    const double *ca, const double *cb, const double *radii, int C, double *dist, double *normal)
{
    double cax[SDF_MAXC], cay[SDF_MAXC], caz[SDF_MAXC], cex[SDF_MAXC], cey[SDF_MAXC], cez[SDF_MAXC], cinv[SDF_MAXC];
    for (int c = 0; c < C; ++c) {
        cax[c] = ca[3 * c]; cay[c] = ca[3 * c + 1]; caz[c] = ca[3 * c + 2];
        cex[c] = cb[3 * c] - cax[c]; cey[c] = cb[3 * c + 1] - cay[c]; cez[c] = cb[3 * c + 2] - caz[c];
        const double den = cex[c] * cex[c] + cey[c] * cey[c] + cez[c] * cez[c];
        cinv[c] = 1.0 / (den > 1e-12 ? den : 1e-12);
    }
    double best[SDF_CHUNK], bx[SDF_CHUNK], by[SDF_CHUNK], bz[SDF_CHUNK], baxis[SDF_CHUNK];
    for (int i = 0; i < n; ++i) {
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

/* Points i0 .. i1 - 1 (at most SDF_CHUNK) of the list idx (NULL: i0 .. i1 - 1) gathered into
   structure-of-arrays form (px, py, pz), as sdf_soa takes them. */
static void gather_points(const double *p, const int32_t *idx, int i0, int i1, double *px, double *py, double *pz)
{
    for (int i = 0; i < i1 - i0; ++i) {
        const int k = idx ? idx[i0 + i] : i0 + i;
        px[i] = p[3 * k]; py[i] = p[3 * k + 1]; pz[i] = p[3 * k + 2];
    }
}

static void sdf_chunk(const double *p, const int32_t *idx, int i0, int i1, const double *ca, const double *cb,
                      const double *radii, int C, double *dist, double *normal)
{
    double px[SDF_CHUNK], py[SDF_CHUNK], pz[SDF_CHUNK];
    gather_points(p, idx, i0, i1, px, py, pz);
    sdf_soa(px, py, pz, idx, i0, i1 - i0, ca, cb, radii, C, dist, normal);
}

/* sdf_chunk over n entries of the point list idx (NULL: 0 .. n-1), chunks shared among the team
   of the innermost parallel region (ends with its barrier). */
static void sdf_points(const double *p, const int32_t *idx, int n, const double *ca, const double *cb,
                       const double *radii, int C, double *dist, double *normal)
{
    #pragma omp for schedule(static)
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

/* What the push-out needs of the garment: the mean operator (CSR indptr/indices/weights) that
   smooths a push; the padded 1-ring (V x width, padding = the vertex itself) with slope x rest
   distance per slot (infinite in the padding) for the neighbour-follow, `follow` passes of it; the
   vertex patches (offsets, indices, and each vertex's patch) measured against only the capsules
   near them. ring NULL: every loop runs over the whole mesh and nothing follows; patch_ptr NULL:
   every vertex is measured against every capsule. */
typedef struct {
    const int32_t *indptr, *indices;
    const double *weights;
    const int32_t *ring;
    const double *ring_drop;
    int width, follow;
    const int32_t *patch_ptr, *patch_idx;
    int patches;
    const int32_t *vertex_patch;
} PushMesh;

/* The push's settings (hrr_garment.native.body.PushSteps): the margin outside the body a pushed
   vertex lands, the smoothing passes, the push-and-smooth rounds, and the depth past which a vertex
   counts as inside in the before and after fractions. */
typedef struct {
    double margin;
    int smooth, rounds;
    double depth;
} PushArgs;

enum { MAX_REGION_RINGS = 256 };
#define FAR_AWAY 1e30 /* the distance of a vertex whose patch no capsule comes near */
#define TAKE_BACK_MOVED 1e-6 /* an addition no longer than this is none (take_back.MOVED_M) */
#define TAKE_BACK_HALVINGS 3 /* a share to within an eighth of the addition (take_back.HALVINGS) */
#define TAKE_BACK_PASSES 4 /* the shares' spread over the mesh (take_back.SPREAD_PASSES) */

/* Signed distances of every vertex, each patch against only the capsules that can come within
   `reach` of it (by its bounding sphere); a patch with none gets FAR_AWAY. A capsule left out is
   more than `reach` from every vertex of the patch, so wherever the distance is within reach
   (all that the push-out reads of it) it is the distance over every capsule, the same nearest.
   list (NULL: every patch): the `count` patches measured again, the others' distances left. */
static void sdf_patch_list(const double *p, const PushMesh *m, const int32_t *list, int count, const double *ca,
                           const double *cb, const double *radii, int C, double reach, double *d, double *nrm)
{
    double ex[SDF_MAXC], ey[SDF_MAXC], ez[SDF_MAXC], inv_den[SDF_MAXC];  /* each capsule's axis, once a frame */
    for (int c = 0; c < C; ++c) {
        const double *a = ca + 3 * c, *b = cb + 3 * c;
        ex[c] = b[0] - a[0]; ey[c] = b[1] - a[1]; ez[c] = b[2] - a[2];
        const double den = ex[c] * ex[c] + ey[c] * ey[c] + ez[c] * ez[c];
        inv_den[c] = 1.0 / (den > 1e-12 ? den : 1e-12);
    }
    #pragma omp for schedule(static)
    for (int k = 0; k < count; ++k) {
        const int q = list ? list[k] : k;
        const int i0 = m->patch_ptr[q], i1 = m->patch_ptr[q + 1], size = i1 - i0;
        if (size > SDF_CHUNK) {  /* a patch larger than a chunk (not the garment's own): every capsule */
            for (int j = i0; j < i1; j += SDF_CHUNK)
                sdf_chunk(p, m->patch_idx, j, j + SDF_CHUNK < i1 ? j + SDF_CHUNK : i1, ca, cb, radii, C, d, nrm);
            continue;
        }
        /* the patch's points gathered once: its bounding sphere and its distances read them there */
        double px[SDF_CHUNK], py[SDF_CHUNK], pz[SDF_CHUNK];
        gather_points(p, m->patch_idx, i0, i1, px, py, pz);
        double cx = 0.0, cy = 0.0, cz = 0.0, r2 = 0.0;
        for (int i = 0; i < size; ++i) { cx += px[i]; cy += py[i]; cz += pz[i]; }
        const double inv = 1.0 / (size > 0 ? size : 1);
        cx *= inv; cy *= inv; cz *= inv;
        for (int i = 0; i < size; ++i) {
            const double dx = px[i] - cx, dy = py[i] - cy, dz = pz[i] - cz, e = dx * dx + dy * dy + dz * dz;
            r2 = e > r2 ? e : r2;
        }
        const double sphere = sqrt(r2) + 1e-9;  /* the slack covers rounding in the centre and radius */
        double sa[3 * SDF_MAXC], sb[3 * SDF_MAXC], sr[SDF_MAXC];
        int n = 0;
        for (int c = 0; c < C; ++c) {  /* near: the centre's distance to the axis at most reach + radius + sphere */
            const double *a = ca + 3 * c, *b = cb + 3 * c;
            const double rx = cx - a[0], ry = cy - a[1], rz = cz - a[2];
            double s = (rx * ex[c] + ry * ey[c] + rz * ez[c]) * inv_den[c];
            s = s < 0 ? 0 : (s > 1 ? 1 : s);
            const double dx = rx - s * ex[c], dy = ry - s * ey[c], dz = rz - s * ez[c], near = reach + radii[c] + sphere;
            if (dx * dx + dy * dy + dz * dz <= near * near) {
                memcpy(sa + 3 * n, a, 3 * sizeof(double));
                memcpy(sb + 3 * n, b, 3 * sizeof(double));
                sr[n++] = radii[c];
            }
        }
        if (n > 0) {
            sdf_soa(px, py, pz, m->patch_idx, i0, size, sa, sb, sr, n, d, nrm);
        } else {
            for (int i = i0; i < i1; ++i) {
                const int k = m->patch_idx[i];
                d[k] = FAR_AWAY;
                nrm[3 * k] = nrm[3 * k + 1] = nrm[3 * k + 2] = 0.0;
            }
        }
    }
}

static void sdf_patches(const double *p, const PushMesh *m, const double *ca, const double *cb, const double *radii,
                        int C, double reach, double *d, double *nrm)
{
    sdf_patch_list(p, m, NULL, m->patches, ca, cb, radii, C, reach, d, nrm);
}

/* The vertices within `rings` rings of the `seeds` first entries of `list` (which it extends, in
   ring order): ends[k] = how many lie within k rings. mark (V, zero on entry) flags the listed
   ones; the caller clears them. Without a ring table: every vertex, all rings. */
static int grow_region(const PushMesh *m, int V, int rings, int seeds, int32_t *list, int *mark, int *ends)
{
    if (!m->ring) {
        for (int v = 0; v < V; ++v) list[v] = v;
        for (int k = 0; k <= rings; ++k) ends[k] = V;
        return V;
    }
    for (int i = 0; i < seeds; ++i) mark[list[i]] = 1;
    int lo = 0, hi = seeds;
    ends[0] = seeds;
    for (int k = 1; k <= rings; ++k) {
        int next = hi;
        for (int i = lo; i < hi; ++i) {
            const int32_t *r = m->ring + (size_t)list[i] * m->width;
            for (int j = 0; j < m->width; ++j)
                if (!mark[r[j]]) { mark[r[j]] = 1; list[next++] = r[j]; }
        }
        lo = hi; hi = next; ends[k] = hi;
    }
    return hi;
}

/* Against the skin (sk not NULL) the capsules are its hulls, each covering its piece of the posed
   mesh (hrr_garment/body/skin_envelope.py), so the skin lies inside their union and a vertex farther
   than the margin from every hull is farther than that from the skin: its hull distance stands (all
   the push reads of it is that it needs no push). The others, within the margin of a hull or inside
   one, are measured against the skin itself (skin_point, ~3 us), but for those the frame's broad
   phase shows farther than the margin from the skin and outside it (skin_far_by_column: its
   column's triangles and a ray; most of a garment inside the hulls, which hold the skin
   loosely): FAR_AWAY, as a patch no capsule comes near. Entries of the list idx (NULL: 0 .. n - 1). */
static inline void skin_measure(const SkinPose *sk, double margin, const double *x, double *d, double *nrm)
{
    if (sk->col_start && skin_far_by_column(sk, margin, x)) {
        *d = FAR_AWAY;
        nrm[0] = nrm[1] = nrm[2] = 0.0;
    } else {
        skin_point(sk->grid, sk->rot, sk->trans, sk->posed, x, d, nrm);
    }
}

static void skin_refine(const SkinPose *sk, const double *p, const int32_t *idx, int n, double margin, double *d,
                        double *nrm)
{
    if (!sk) return;
    #pragma omp for schedule(dynamic, 32)
    for (int i = 0; i < n; ++i) {
        const int v = idx ? idx[i] : i;
        if (d[v] <= margin) skin_measure(sk, margin, p + 3 * v, d + v, nrm + 3 * v); /* a NaN stays, as the push reads it */
    }
}

/* push_frame's projection list: vertex v appended to list (at *n) when inside, and to the moved
   vertices (at *total) the first time. */
static inline void take_if_inside(int v, const double *d, int32_t *list, int *n, int *vmark, int32_t *moved, int *total)
{
    if (!(d[v] < 0.0)) return;  /* as the comparison the push reads: a NaN is not inside */
    list[(*n)++] = v;
    if (!vmark[v]) { vmark[v] = 1; moved[(*total)++] = v; }
}

/* The collision push-out of hrr_garment/inference/collision.py for one frame, the same steps:
   distances (sdf_patches); `rounds` times: each vertex needing to move (within `margin` of the
   body or inside) gets need along its normal, the neighbour-follow (m->follow max-plus passes over
   the ring) raises the pushes around it, `smooth` Jacobi passes of the mean operator spread them,
   never lowering a moving vertex's push along its direction; all of it only over the region within
   follow + smooth + 1 rings of the pushed vertices (everything outside is exactly untouched); then
   up to four exact projections of the vertices still inside. Only the patches of moved vertices
   are measured again. before/after: fractions of vertices deeper than `depth`. The vertices it
   moved: ints + 3 V, flag[3] of them (what the strain limit measures). Called by every thread of
   the innermost parallel region, which share the work; buf (20 V doubles), ints (7 V: the region,
   a work list, the region's marks, the moved vertices, a list of patches, the patches' and the
   moved vertices' marks; the marks zero between calls) and flag (5: one per purpose, so that no
   thread can see a later value) are the team's shared scratch. */
static void push_frame(double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                       const SkinPose *sk, const PushMesh *m, double margin, int smooth, int rounds, double depth, int measured,
                       double *before, double *after, double *buf, int32_t *ints, int *flag)
{
    double *d = buf, *nrm = d + V, *need = nrm + 3 * (size_t)V, *req = need + V, *req2 = req + V;
    double *dir = req2 + V, *dir2 = dir + 3 * (size_t)V, *disp = dir2 + 3 * (size_t)V, *tmp = disp + 3 * (size_t)V;
    int32_t *region = ints, *list = ints + V, *moved = ints + 3 * (size_t)V, *plist = ints + 4 * (size_t)V;
    int *mark = (int *)(ints + 2 * (size_t)V), *pmark = (int *)(ints + 5 * (size_t)V), *vmark = (int *)(ints + 6 * (size_t)V);
    int ends[MAX_REGION_RINGS + 1];
    const int follow = m->ring ? m->follow : 0, rings = follow + smooth + 1;
    const int by_patch = m->patch_ptr && !sk;  /* the moved vertices measured again by their patches */
    if (!measured) {
        if (m->patch_ptr) sdf_patches(p, m, ca, cb, radii, C, margin, d, nrm);
        else sdf_points(p, NULL, V, ca, cb, radii, C, d, nrm);
        skin_refine(sk, p, NULL, V, margin, d, nrm);
    }
    #pragma omp single
    {
        int deep = 0;
        for (int v = 0; v < V; ++v) deep += d[v] < -depth;
        *before = (double)deep / V;
        flag[1] = flag[3] = flag[4] = 0;
    }
    for (int r = 0; r < rounds; ++r) {
        #pragma omp single copyprivate(ends)  /* every thread takes the region's ring counts */
        {
            int seeds = 0;
            for (int v = 0; v < V; ++v) {
                need[v] = margin - d[v] > 0.0 ? margin - d[v] : 0.0;
                if (need[v] > 0.0) region[seeds++] = v;
            }
            flag[0] = seeds > 0 ? grow_region(m, V, rings, seeds, region, mark, ends) : 0;
        }
        const int size = flag[0];  /* read after the single's barrier; rewritten only after later barriers */
        if (!size) break;
        #pragma omp for schedule(static)
        for (int i = 0; i < size; ++i) {
            const int v = region[i];
            const int hit = need[v] > 0.0;
            req[v] = req2[v] = need[v];
            for (int k = 0; k < 3; ++k) dir[3 * v + k] = dir2[3 * v + k] = hit ? nrm[3 * v + k] : 0.0;
        }
        for (int f = 1; f <= follow; ++f) {  /* the follow: a max-plus Jacobi pass per ring */
            #pragma omp for schedule(static)
            for (int i = 0; i < ends[f]; ++i) {
                const int u = region[i];
                const int32_t *nb = m->ring + (size_t)u * m->width;
                const double *drop = m->ring_drop + (size_t)u * m->width;
                double best = req[u];
                int from = -1;
                for (int j = 0; j < m->width; ++j) {
                    const double cand = req[nb[j]] - drop[j];
                    if (cand > best) { best = cand; from = nb[j]; }
                }
                req2[u] = best;
                const double *src = dir + 3 * (size_t)(from >= 0 ? from : u);
                for (int k = 0; k < 3; ++k) dir2[3 * u + k] = src[k];
            }
            double *swap = req; req = req2; req2 = swap;  /* each thread swaps its own pointers alike */
            swap = dir; dir = dir2; dir2 = swap;
        }
        #pragma omp for schedule(static)
        for (int i = 0; i < size; ++i) {
            const int v = region[i];
            for (int k = 0; k < 3; ++k) { disp[3 * v + k] = req[v] * dir[3 * v + k]; tmp[3 * v + k] = 0.0; }
        }
        for (int s = 1; s <= smooth; ++s) {
            #pragma omp for schedule(static)
            for (int i = 0; i < ends[follow + s]; ++i) {
                const int v = region[i];
                double x = 0.0, y = 0.0, z = 0.0;
                for (int j = m->indptr[v]; j < m->indptr[v + 1]; ++j) {
                    const double w = m->weights[j], *q = disp + 3 * (size_t)m->indices[j];
                    x += w * q[0]; y += w * q[1]; z += w * q[2];
                }
                if (req[v] > 0.0) {
                    const double *nv = dir + 3 * (size_t)v;
                    double shortfall = req[v] - (x * nv[0] + y * nv[1] + z * nv[2]);
                    shortfall = shortfall > 0.0 ? shortfall : 0.0;
                    x += shortfall * nv[0]; y += shortfall * nv[1]; z += shortfall * nv[2];
                }
                tmp[3 * v] = x; tmp[3 * v + 1] = y; tmp[3 * v + 2] = z;
            }
            double *swap = disp; disp = tmp; tmp = swap;
        }
        #pragma omp single
        {
            int n = 0, total = flag[3], patches = 0;
            for (int i = 0; i < ends[follow + smooth]; ++i) {
                const int v = region[i];
                const double *q = disp + 3 * (size_t)v;
                if (q[0] != 0.0 || q[1] != 0.0 || q[2] != 0.0) {
                    p[3 * v] += q[0]; p[3 * v + 1] += q[1]; p[3 * v + 2] += q[2];
                    list[n++] = v;
                    if (!vmark[v]) { vmark[v] = 1; moved[total++] = v; }
                    const int patch_of_v = m->patch_ptr ? m->vertex_patch[v] : -1;
                    if (patch_of_v >= 0 && !pmark[patch_of_v]) { pmark[patch_of_v] = 1; plist[patches++] = patch_of_v; }
                }
            }
            for (int k = 0; k < patches; ++k) pmark[plist[k]] = 0;
            flag[1] = n;
            flag[3] = total;
            flag[4] = patches;
            if (m->ring)
                for (int i = 0; i < size; ++i) mark[region[i]] = 0;
        }
        /* the moved patches measured again, culled as at first (a capsule left out is more than the
           margin from every vertex of the patch where it lies now): a push moves a few hundred vertices,
           each measured against every capsule it was twice the first measurement's work. Against the
           skin only the vertices that moved: a vertex of a moved patch that did not move needed no
           push (its distance at least the margin), and measured again it would be the same, at the
           skin's cost (a third of its calls) */
        if (by_patch) {
            sdf_patch_list(p, m, plist, flag[4], ca, cb, radii, C, margin, d, nrm);
        } else {
            sdf_points(p, list, flag[1], ca, cb, radii, C, d, nrm);
            skin_refine(sk, p, list, flag[1], margin, d, nrm);
        }
    }
    for (int it = 0; it < 4; ++it) {
        #pragma omp single
        {
            /* only a vertex measured again since its distance was at least the margin can be inside:
               at first those of the last round's moved patches (its moved vertices, list, without
               patches), then those the projection before moved (list, filtered in place) */
            int n = 0, total = flag[3];
            if (it == 0 && by_patch) {
                for (int k = 0; k < flag[4]; ++k)
                    for (int i = m->patch_ptr[plist[k]]; i < m->patch_ptr[plist[k] + 1]; ++i)
                        take_if_inside(m->patch_idx[i], d, list, &n, vmark, moved, &total);
            } else {
                const int count = it == 0 ? flag[1] : flag[2];
                for (int k = 0; k < count; ++k) take_if_inside(list[k], d, list, &n, vmark, moved, &total);
            }
            flag[2] = n;
            flag[3] = total;
        }
        const int n = flag[2];
        if (n == 0) break;
        #pragma omp for schedule(static)
        for (int i = 0; i < n; ++i) {
            const int v = list[i];
            for (int k = 0; k < 3; ++k) p[3 * v + k] += (margin - d[v]) * nrm[3 * v + k];
        }
        sdf_points(p, list, n, ca, cb, radii, C, d, nrm);
        skin_refine(sk, p, list, n, margin, d, nrm);
    }
    #pragma omp single
    {
        int deep = 0;
        for (int v = 0; v < V; ++v) deep += d[v] < -depth;
        *after = (double)deep / V;
        for (int k = 0; k < flag[3]; ++k) vmark[moved[k]] = 0;
    }
}

/* The push-out's strain limit as the kernel takes it (hrr_garment.native.body.StrainLimit): the
   garment's E edges (vertex pairs), rest lengths, colours (no two edges of a colour share a vertex)
   with each colour's offset in an E-long array (colour_ptr, colours + 1 entries) and each vertex's
   edges (CSR ve_ptr, ve_idx); the strain an edge may reach, the slack over a stretch the push did
   not make, at most `iterations` passes, which stop once no edge is more than tol over its limit,
   over-relaxed by omega. rest_row (NULL: one rest for every frame): frame t's garment rests in row
   rest_row[t] of rest (E doubles a row), where the frames' bodies differ (a crowd's). */
typedef struct {
    const int32_t *edges;
    const double *rest;
    const uint8_t *colour;
    const int32_t *colour_ptr, *ve_ptr, *ve_idx;
    int E, colours, iterations;
    double max_strain, slack, tol, omega;
    const int64_t *rest_row;
} StrainArgs;

/* Frame t's strain limit: s with its body's rest lengths. */
static inline StrainArgs frame_limit(const StrainArgs *s, int t)
{
    StrainArgs own = *s;
    if (s->rest_row) own.rest = s->rest + (size_t)s->rest_row[t] * (size_t)s->E;
    return own;
}

enum { MAX_EDGE_COLOURS = 256 };

/* Edge e's limit: max_strain times its rest length, or its length in the unpushed frame u plus
   slack times its rest length where that is longer (the push never has to undo a stretch it did
   not make, and may lengthen an edge the decoder stretched by a little). Squared lengths: a square
   root only where the unpushed edge is longer than allowed, which nearly no edge is. */
static inline double edge_limit(const StrainArgs *s, const double *u, int e)
{
    const int i = s->edges[2 * e], j = s->edges[2 * e + 1];
    const double ux = u[3 * j] - u[3 * i], uy = u[3 * j + 1] - u[3 * i + 1], uz = u[3 * j + 2] - u[3 * i + 2];
    const double before2 = ux * ux + uy * uy + uz * uz, allowed = s->max_strain * s->rest[e], extra = s->slack * s->rest[e];
    const double unslacked = allowed - extra;  /* an unpushed edge longer than this sets its own limit */
    return unslacked > 0.0 && before2 <= unslacked * unslacked ? allowed
           : (sqrt(before2) + extra > allowed ? sqrt(before2) + extra : allowed);
}

/* One frame's scratch for the strain limit: the limits of the edges measured (E doubles; known
   where lmark is set), the edges found over their limit (active, E ints), each colour's edges to
   measure (bucket: E ints, colour c's from colour_ptr[c], count[c] of them), emark (E bytes: listed
   in a bucket), lmark (E bytes), carved from one block. */
typedef struct {
    double *limit;
    int32_t *active, *bucket, *count;
    unsigned char *emark, *lmark;
} LimitScratch;

static size_t limit_scratch_bytes(int E)
{
    return sizeof(double) * (size_t)E + sizeof(int32_t) * (2 * (size_t)E + MAX_EDGE_COLOURS) + 2 * (size_t)E + 64;
}

static LimitScratch limit_scratch(unsigned char *block, int E)
{
    LimitScratch w;
    w.limit = (double *)block;
    w.active = (int32_t *)(w.limit + E);
    w.bucket = w.active + E;
    w.count = w.bucket + E;
    w.emark = (unsigned char *)(w.count + MAX_EDGE_COLOURS);
    w.lmark = w.emark + E;
    memset(w.emark, 0, (size_t)E);  /* the mark starts clear and is left clear */
    return w;
}

/* Lists edge f in its colour's bucket (once), its limit known. */
static inline void list_edge(const double *u, const StrainArgs *s, LimitScratch *w, int f)
{
    if (w->emark[f]) return;
    w->emark[f] = 1;
    const int c = s->colour[f];
    w->bucket[s->colour_ptr[c] + w->count[c]++] = f;
    if (!w->lmark[f]) { w->limit[f] = edge_limit(s, u, f); w->lmark[f] = 1; }
}

/* The strain limit's passes on one frame p (V, 3), its unpushed frame u: Gauss-Seidel passes of
   edge-length projection, a colour of edges after another (no two edges of a colour share a
   vertex, so within a colour the order does not matter: the result is the reference's, which
   projects each colour's edges at once). An edge longer than its limit moves its two ends toward
   each other by omega times half its excess each. Only edges that can be over their limit are
   measured: those listed by the caller (the n_active edges of w->active it found over, every
   other edge being within its limit) and the edges of every vertex a projection moved since the
   edge was last measured: listed for this pass where their colour comes later, for the next one
   otherwise (an edge whose ends stayed keeps its length, within its limit). A pass over a torn
   neighbourhood costs its size, not the mesh's. Stops after a pass whose worst excess is at most
   tol. Leaves the marks clear. */
static void limit_frame(double *p, const double *u, const StrainArgs *s, LimitScratch *w, int n_active)
{
    const int32_t *edges = s->edges;
    memset(w->lmark, 0, (size_t)s->E);  /* the limits known: those of the edges listed (measure_edge) */
    memset(w->count, 0, sizeof(int32_t) * (size_t)s->colours);
    for (int k = 0; k < n_active; ++k) w->lmark[w->active[k]] = 1;
    for (int k = 0; k < n_active; ++k) list_edge(u, s, w, w->active[k]);
    for (int it = 0; it < s->iterations; ++it) {
        double worst = 0.0;
        for (int c = 0; c < s->colours; ++c) {
            const int32_t *mine = w->bucket + s->colour_ptr[c];
            const int n = w->count[c];
            w->count[c] = 0;  /* edges of this colour listed from here on are for the next pass */
            for (int k = 0; k < n; ++k) {
                const int e = mine[k];
                w->emark[e] = 0;
                const int i = edges[2 * e], j = edges[2 * e + 1];
                const double dx = p[3 * j] - p[3 * i], dy = p[3 * j + 1] - p[3 * i + 1], dz = p[3 * j + 2] - p[3 * i + 2];
                const double length = sqrt(dx * dx + dy * dy + dz * dz), excess = length - w->limit[e];
                if (excess <= 0.0) continue;
                if (excess > worst) worst = excess;
                const double f = s->omega * 0.5 * excess / (length > 1e-12 ? length : 1e-12);
                p[3 * i] += f * dx; p[3 * i + 1] += f * dy; p[3 * i + 2] += f * dz;
                p[3 * j] -= f * dx; p[3 * j + 1] -= f * dy; p[3 * j + 2] -= f * dz;
                for (int end = 0; end < 2; ++end) {  /* their other edges (none of this colour but e) */
                    const int v = end ? j : i;
                    for (int q = s->ve_ptr[v]; q < s->ve_ptr[v + 1]; ++q)
                        if (s->ve_idx[q] != e) list_edge(u, s, w, s->ve_idx[q]);
                }
            }
        }
        if (worst <= s->tol) break;
    }
    for (int c = 0; c < s->colours; ++c)
        for (int k = 0; k < w->count[c]; ++k) w->emark[w->bucket[s->colour_ptr[c] + k]] = 0;
}

/* Lists edge e in w->active when it is longer than its limit (which it then knows); *over when by
   more than a millionth. An edge within max_strain of its rest length is within its limit, which is
   at least that: its unpushed length is not read. */
static inline void measure_edge(const double *p, const double *u, const StrainArgs *s, int e, LimitScratch *w,
                                int *n_long, int *over)
{
    const int i = s->edges[2 * e], j = s->edges[2 * e + 1];
    const double dx = p[3 * j] - p[3 * i], dy = p[3 * j + 1] - p[3 * i + 1], dz = p[3 * j + 2] - p[3 * i + 2];
    const double length2 = dx * dx + dy * dy + dz * dz, allowed = s->max_strain * s->rest[e];
    if (length2 <= allowed * allowed) return;
    const double lim = w->limit[e] = edge_limit(s, u, e);
    if (length2 > lim * lim) {
        w->active[(*n_long)++] = e;
        *over |= length2 > lim * lim * ((1.0 + 1e-6) * (1.0 + 1e-6));
    }
}

/* The strain limit on one frame p against its unpushed frame u: the edges over their limit found,
   then the passes where one is over by more than a millionth. moved (NULL: every edge is
   measured): the n_moved vertices the push moved, whose edges are the only ones that can be over
   (an edge with both ends where they were unpushed is within its limit, which is at least its
   unpushed length): the same edges found, the same result. Returns whether the frame was torn. */
static int limit_one(double *p, const double *u, int V, const StrainArgs *s, const int32_t *moved, int n_moved,
                     LimitScratch *w)
{
    int over = 0, n_long = 0;
    if (!moved) {
        for (int e = 0; e < s->E; ++e) measure_edge(p, u, s, e, w, &n_long, &over);
    } else {
        for (int k = 0; k < n_moved; ++k)
            for (int q = s->ve_ptr[moved[k]]; q < s->ve_ptr[moved[k] + 1]; ++q) {
                const int e = s->ve_idx[q];
                if (w->emark[e]) continue;  /* an edge of two moved vertices, measured already */
                w->emark[e] = 1;
                measure_edge(p, u, s, e, w, &n_long, &over);
            }
        for (int k = 0; k < n_moved; ++k)
            for (int q = s->ve_ptr[moved[k]]; q < s->ve_ptr[moved[k] + 1]; ++q) w->emark[s->ve_idx[q]] = 0;
    }
    if (over) limit_frame(p, u, s, w, n_long);
    return over;
}

/* T frames of pushed points p (T, V, 3), limited in place against the unpushed frames (T, V, 3).
   torn[t]: whether frame t had an edge over its limit (by more than a millionth of it) before.
   Frames in parallel. Returns 0, or -1 when the scratch memory could not be had (nothing changed). */
int hrr_limit_strain(double *p, const double *unpushed, int T, int V, const StrainArgs *s, int threads,
                     unsigned char *torn)
{
    if (T <= 0) return 0;
    if (threads < 1) threads = 1;
    if (threads > T) threads = T;
    const size_t per = limit_scratch_bytes(s->E);
    unsigned char *scratch = malloc(per * threads);
    if (!scratch) return -1;
    #pragma omp parallel num_threads(threads)
    {
        LimitScratch w = limit_scratch(scratch + per * (size_t)omp_get_thread_num(), s->E);
        #pragma omp for schedule(dynamic)
        for (int t = 0; t < T; ++t) {
            const StrainArgs own = frame_limit(s, t);
            torn[t] = (unsigned char)limit_one(p + (size_t)t * V * 3, unpushed + (size_t)t * V * 3, V, &own, NULL, 0, &w);
        }
    }
    free(scratch);
    return 0;
}

/* The push in the garment's subspace (hrr_garment.inference.subspace_push, its reference): the
   first k principal components of the fast decoder, vertex-major (V, 3, k) in float32 as the
   decoder stores them (half the memory a frame streams; sums in float64), the first-order edge
   stretch per pair of them (k, k), the stretch's weight, the ridge per vertex near the body, the
   clearance past the margin aimed for, and the solves a frame. blocks: the same basis for the move,
   component-major by blocks of MOVE_BLOCK vertices (block b's (k, 3 MOVE_BLOCK) floats, the
   coordinates of its vertices in order, zero past the last vertex), so that the move runs down the
   components with a vector of coordinates at a time instead of summing each coordinate across them. */
typedef struct {
    const float *basis, *blocks;
    const double *stretch;
    int k, iterations;
    double strain_weight, ridge, clearance;
} SubspaceArgs;

/* In place: A (k, k) symmetric positive definite -> its Cholesky factor (lower), then x = A^-1 b
   in b. Returns 0, or -1 where A is not positive definite (b left as it is). */
static int cholesky_solve(double *A, double *b, int k)
{
    for (int j = 0; j < k; ++j) {
        double diag = A[j * k + j];
        for (int q = 0; q < j; ++q) diag -= A[j * k + q] * A[j * k + q];
        if (!(diag > 0.0)) return -1;
        diag = sqrt(diag);
        A[j * k + j] = diag;
        for (int i = j + 1; i < k; ++i) {
            double x = A[i * k + j];
            for (int q = 0; q < j; ++q) x -= A[i * k + q] * A[j * k + q];
            A[i * k + j] = x / diag;
        }
    }
    for (int i = 0; i < k; ++i) {  /* L y = b */
        double x = b[i];
        for (int q = 0; q < i; ++q) x -= A[i * k + q] * b[q];
        b[i] = x / A[i * k + i];
    }
    for (int i = k - 1; i >= 0; --i) {  /* L^T x = y */
        double x = b[i];
        for (int q = i + 1; q < k; ++q) x -= A[q * k + i] * b[q];
        b[i] = x / A[i * k + i];
    }
    return 0;
}

/* A team's scratch for push_and_limit: buf (20 V doubles) and ints (3 V ints, zero between calls)
   and flag (3 ints) as push_frame takes them, the frame in float64 (p, 3 V doubles) and as it came
   (u, 3 V; with a limit), the vertices the push moved (moved, V ints) and the limit's scratch. */
typedef struct {
    double *buf, *p, *u, *solve;  /* solve: the subspace push's k (k + 2) doubles */
    int32_t *ints, *moved;
    int *flag;
    LimitScratch limit;
    SkinPose skin; /* the frame's skin with its columns */
    SkinColumns columns;
} PushTeam;

/* vertices a block of the subspace move (its rows of the basis stay in cache); SubspaceMove.BLOCK
   in hrr_garment/native/body.py lays the blocks out */
enum { MOVE_BLOCK = 64, MOVE_LANES = 32 };  /* 32 coordinates: independent sums enough to hide the multiply-adds' latency */

/* The subspace move of block b's vertices (v0 = b MOVE_BLOCK up to v1) of frame p: each by coef
   over the k components (blocks, see SubspaceArgs), turned into the world by turn. Each coordinate's
   sum runs over the components in order, MOVE_LANES coordinates at a time. One function, never
   inlined, for the frame-by-frame and the batched paths alike: the same machine code, so the same
   bits. */
static __attribute__((noinline)) void subspace_move(double *p, int v0, int v1, const float *blocks, int k,
                                                    const double *coef, const double *turn)
{
    const float *block = blocks + (size_t)(v0 / MOVE_BLOCK) * k * 3 * MOVE_BLOCK;
    double local[3 * MOVE_BLOCK];
    for (int i0 = 0; i0 < 3 * (v1 - v0); i0 += MOVE_LANES) {
        double acc[MOVE_LANES] = {0.0};
        for (int c = 0; c < k; ++c) {
            const float *row = block + (size_t)c * 3 * MOVE_BLOCK + i0;
            const double w = coef[c];
            #pragma omp simd
            for (int l = 0; l < MOVE_LANES; ++l) acc[l] += w * row[l];
        }
        memcpy(local + i0, acc, sizeof acc);  /* past v1's coordinates: the padding's zeros, unused */
    }
    for (int v = v0; v < v1; ++v) {
        const double *q = local + 3 * (v - v0);
        for (int i = 0; i < 3; ++i) p[3 * v + i] += turn[3 * i] * q[0] + turn[3 * i + 1] * q[1] + turn[3 * i + 2] * q[2];
    }
}

/* One solve of the subspace push on frame p (V, 3), its body frame turned by turn (3 x 3, body ->
   world): the vertices within margin + clearance of the body (team->moved) give the normal
   equations of the coefficients (k, into coef) that take them to margin + clearance along their
   normals, each weighted from 0 where it enters to 1 at the margin, with the stretch and the ridge
   added. Returns whether there was a move to make. Called by every thread of the innermost parallel
   region (the distances shared, the solve on one); d and nrm are push_frame's scratch. */
static int subspace_solve(const double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                          const SkinPose *sk, const PushMesh *m, double margin, const SubspaceArgs *sp, const double *turn,
                          PushTeam *team, double *coef)
{
    const int k = sp->k;
    const double reach = margin + sp->clearance;
    double *d = team->buf, *nrm = d + V, *A = team->solve, *row = A + (size_t)k * k;
    if (m->patch_ptr) sdf_patches(p, m, ca, cb, radii, C, reach, d, nrm);
    else sdf_points(p, NULL, V, ca, cb, radii, C, d, nrm);
    skin_refine(sk, p, NULL, V, reach, d, nrm);  /* against the skin: its columns were built for the reach */
    #pragma omp single
    {
        int n = 0;
        for (int v = 0; v < V; ++v)
            if (d[v] < reach) team->moved[n++] = v;
        team->flag[2] = 0;
        if (n > 0) {
            double total = 0.0;
            for (int i = 0; i < k * k; ++i) A[i] = sp->strain_weight * sp->stretch[i];
            for (int i = 0; i < k; ++i) coef[i] = 0.0;
            for (int q = 0; q < n; ++q) {
                const int v = team->moved[q];
                const double *nv = nrm + 3 * (size_t)v;
                const float *bv = sp->basis + (size_t)v * 3 * k;
                double local[3];
                for (int j = 0; j < 3; ++j) local[j] = nv[0] * turn[j] + nv[1] * turn[3 + j] + nv[2] * turn[6 + j];
                const double depth = reach - d[v], weight = depth < sp->clearance ? depth / sp->clearance : 1.0;
                total += weight;
                for (int c = 0; c < k; ++c) row[c] = local[0] * bv[c] + local[1] * bv[k + c] + local[2] * bv[2 * k + c];
                for (int i = 0; i < k; ++i) {  /* the lower triangle: the solve reads no other */
                    const double ri = weight * row[i];
                    for (int j = 0; j <= i; ++j) A[i * k + j] += ri * row[j];
                    coef[i] += ri * depth;
                }
            }
            for (int i = 0; i < k; ++i) A[i * k + i] += sp->ridge * total;
            team->flag[2] = cholesky_solve(A, coef, k) == 0;
        }
    }
    return team->flag[2];
}

/* The subspace push on one frame p, `iterations` solves and moves (stopping where one has nothing
   to move), shared by the threads of the innermost parallel region. */
static void subspace_push(double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                          const SkinPose *sk, const PushMesh *m, double margin, const SubspaceArgs *sp, const double *turn,
                          PushTeam *team)
{
    double *coef = team->solve + (size_t)sp->k * (sp->k + 1);
    for (int it = 0; it < sp->iterations; ++it) {
        if (!subspace_solve(p, V, ca, cb, radii, C, sk, m, margin, sp, turn, team, coef)) break;
        #pragma omp for schedule(static)
        for (int v0 = 0; v0 < V; v0 += MOVE_BLOCK)
            subspace_move(p, v0, v0 + MOVE_BLOCK < V ? v0 + MOVE_BLOCK : V, sp->blocks, sp->k, coef, turn);
    }
}

/* Point x's signed distance to the body as the push measures it within `margin`: the capsules'
   (or hulls': they hold the skin) past the margin of every one, else, against the skin,
   skin_measure's (the skin's distance, or the broad phase's FAR_AWAY). As PosedSkin.frame_distance
   (hrr_garment/inference/visible_push.py). */
static double point_distance(const double *x, const double *ca, const double *cb, const double *radii, int C,
                             const SkinPose *sk, double margin)
{
    double d, nrm[3];
    sdf_soa(x, x + 1, x + 2, NULL, 0, 1, ca, cb, radii, C, &d, nrm);  /* strided: one point, its x y z */
    if (d >= margin || !sk) return d;
    skin_measure(sk, margin, x, &d, nrm);
    return d;
}

/* The take-back of hrr_garment/inference/take_back.py for one frame, before its push: each vertex
   nearer than the margin to the body (or inside) whose addition (p - base) is not nothing gets the
   least share of it, found by `halvings` halvings, that going back along it clears the body (where
   base is not clear: the whole if base is the shallower, else none); the shares spread over the
   mesh by `passes` Jacobi passes of share = max(share, mean operator . share); every vertex goes
   back by its share. came: the
   fraction of the frame as it came deeper than `depth` (the report's before). d, nrm, share,
   share2: scratch (V, 3V, V, V doubles). Called by every thread of the team. */
static void take_back_frame(double *p, const float *base, int V, const double *ca, const double *cb, const double *radii,
                            int C, const SkinPose *sk, const PushMesh *m, double margin, double depth, int halvings,
                            int passes, double *d, double *nrm, double *share, double *share2, double *came)
{
    /* as push_frame's first pass: the patches' distances where there are patches (the same wherever
       they are within the margin, all that is read of them here and by the push, which takes them) */
    if (m->patch_ptr) sdf_patches(p, m, ca, cb, radii, C, margin, d, nrm);
    else sdf_points(p, NULL, V, ca, cb, radii, C, d, nrm);
    skin_refine(sk, p, NULL, V, margin, d, nrm);
    #pragma omp single
    {
        int deep = 0;
        for (int v = 0; v < V; ++v) deep += d[v] < -depth;
        *came = (double)deep / V;
    }
    #pragma omp for schedule(dynamic, 16)
    for (int v = 0; v < V; ++v) {
        share[v] = 0.0;
        if (!(d[v] < margin)) continue;
        double add[3], x[3];
        for (int k = 0; k < 3; ++k) add[k] = p[3 * v + k] - (double)base[3 * v + k];
        if (sqrt(add[0] * add[0] + add[1] * add[1] + add[2] * add[2]) <= TAKE_BACK_MOVED) continue;
        for (int k = 0; k < 3; ++k) x[k] = p[3 * v + k] - add[k];
        const double under = point_distance(x, ca, cb, radii, C, sk, margin);
        double hi = under > d[v] ? 1.0 : 0.0;  /* the regression not clear either: back where it is the shallower */
        if (under >= margin) {
            double lo = 0.0;
            hi = 1.0;
            for (int i = 0; i < halvings; ++i) {
                const double mid = 0.5 * (lo + hi);
                for (int k = 0; k < 3; ++k) x[k] = p[3 * v + k] - mid * add[k];
                if (point_distance(x, ca, cb, radii, C, sk, margin) >= margin) hi = mid;
                else lo = mid;
            }
        }
        share[v] = hi;
    }
    for (int pass = 0; pass < passes; ++pass) {  /* each thread swaps its own pointers, alike */
        #pragma omp for schedule(static)
        for (int v = 0; v < V; ++v) {
            double acc = 0.0;
            for (int j = m->indptr[v]; j < m->indptr[v + 1]; ++j) acc += m->weights[j] * share[m->indices[j]];
            share2[v] = acc > share[v] ? acc : share[v];
        }
        double *t = share; share = share2; share2 = t;
    }
    #pragma omp for schedule(static)
    for (int v = 0; v < V; ++v)
        if (share[v] > 0.0)
            for (int k = 0; k < 3; ++k) p[3 * v + k] -= share[v] * (p[3 * v + k] - (double)base[3 * v + k]);
}

/* One frame, in (V, 3) float32, or float64 with in_double -> out float32: with sp, moved in the garment's subspace first
   (subspace_push, its body frame turned by turn); pushed as push_frame does, in float64, then with
   a strain limit s, limited against the frame as the push got it, measuring only the edges of the
   vertices the push moved, while the frame is in cache. Called by every thread of the innermost parallel region,
   which share the conversions and the push; the limit runs on one of them. */
static void push_and_limit(const void *in, int in_double, float *out, int V, const double *ca, const double *cb,
                           const double *radii,
                           int C, const SkinPose *sk, const PushMesh *m, const PushArgs *args, const StrainArgs *s, const SubspaceArgs *sp,
                           const double *turn, const float *base, double *before, double *after,
                           unsigned char *torn, PushTeam *team)
{
    double *p = team->p, *u = team->u;
    if (in_double) {
        #pragma omp for schedule(static)
        for (int k = 0; k < 3 * V; ++k) p[k] = ((const double *)in)[k];
    } else {
        #pragma omp for schedule(static)
        for (int k = 0; k < 3 * V; ++k) p[k] = ((const float *)in)[k];
    }
    if (sk && sk->cell > 0.0) {  /* the frame's broad phase against the skin, here where frames run in
                                    parallel, its columns in the team's copy of the frame's struct; built
                                    for the subspace push's reach where there is one (a column then lists
                                    more triangles than the margin needs: the same answers) */
        #pragma omp single
        {
            team->skin = *sk;
            skin_columns(sk->grid, sk->posed, args->margin + (sp ? sp->clearance : 0.0), sk->cell, &team->columns,
                         &team->skin);
        }
        sk = &team->skin;
    }
    double came = 0.0;
    int measured = 0;  /* push_frame's d and nrm already hold every vertex's distance */
    if (base) {
        /* the frame as it came: the take-back's strain limit's reference (it stretches no edge past the
           limit either), and what tells the vertices it moved */
        #pragma omp for schedule(static)
        for (int k = 0; k < 3 * V; ++k) u[k] = p[k];
        /* push_frame's scratch, free until it starts: d, nrm (as push_frame's own), then two V-long
           rows for the shares */
        take_back_frame(p, base, V, ca, cb, radii, C, sk, m, args->margin, args->depth, TAKE_BACK_HALVINGS, TAKE_BACK_PASSES,
                        team->buf, team->buf + V, team->buf + 4 * (size_t)V, team->buf + 5 * (size_t)V, &came);
        if (s) {
            #pragma omp single
            *torn = (unsigned char)limit_one(p, u, V, s, NULL, 0, &team->limit);
        }
        if (!sp) {  /* the take-back measured the frame as it came: only what it (or its limit) moved is
                       measured again for the push, as push_frame's first pass would (a subspace push
                       moves every vertex after it) */
            int32_t *list = team->ints + V;  /* push_frame's work list, free until it starts */
            #pragma omp single
            {
                int n = 0;
                for (int v = 0; v < V; ++v)
                    if (p[3 * v] != u[3 * v] || p[3 * v + 1] != u[3 * v + 1] || p[3 * v + 2] != u[3 * v + 2]) list[n++] = v;
                team->flag[2] = n;
            }
            const int n = team->flag[2];
            sdf_points(p, list, n, ca, cb, radii, C, team->buf, team->buf + V);
            skin_refine(sk, p, list, n, args->margin, team->buf, team->buf + V);
            measured = 1;
        }
    }
    if (sp) subspace_push(p, V, ca, cb, radii, C, sk, m, args->margin, sp, turn, team);
    if (s) {  /* the limit's reference: the frame as the mesh push gets it */
        #pragma omp for schedule(static)
        for (int k = 0; k < 3 * V; ++k) u[k] = p[k];
    }
    push_frame(p, V, ca, cb, radii, C, sk, m, args->margin, args->smooth, args->rounds, args->depth, measured, before, after,
               team->buf, team->ints, team->flag);
    if (base) {  /* the report's before: the frame as it came, its additions in it */
        #pragma omp single
        *before = came;
    }
    if (s) {  /* push_frame ends at a barrier: the frame is pushed, team->moved lists what it moved */
        #pragma omp single
        *torn = (unsigned char)(limit_one(p, u, V, s, team->moved, team->flag[3], &team->limit) | (base ? *torn : 0));
    }
    #pragma omp for schedule(static)
    for (int k = 0; k < 3 * V; ++k) out[k] = (float)p[k];
    /* against the skin, a frame the limit moved is measured again here, as it comes out (float), for
       the report: the caller would measure it in numpy against the hulls and then the skin, ten times
       the push's own time on a garment the limit repairs on every frame. Only the vertices that come
       out elsewhere than they came in are measured: push_frame's last distance of any other (its
       buffer d) is of the point it came in at, which it leaves at (floats in, floats out) */
    if (s && sk && sk->measure_after && *torn) {  /* *torn: written in a single, read after its barrier */
        double *d = team->buf, *nrm = d + V;
        int32_t *list = team->ints + V;  /* push_frame's work list, free again */
        #pragma omp single
        {
            int n = 0;
            for (int v = 0; v < V; ++v) {
                const float *was = (const float *)in + 3 * v, *now = out + 3 * v;
                if (in_double || was[0] != now[0] || was[1] != now[1] || was[2] != now[2]) {
                    for (int k = 0; k < 3; ++k) p[3 * v + k] = (double)now[k];
                    list[n++] = v;
                }
            }
            team->flag[2] = n;
        }
        const int n = team->flag[2];
        sdf_points(p, list, n, ca, cb, radii, C, d, nrm);
        skin_refine(sk, p, list, n, args->margin, d, nrm);
        #pragma omp single
        {
            int deep = 0;
            for (int v = 0; v < V; ++v) deep += d[v] < -args->depth;
            *after = (double)deep / V;
        }
    }
}

/* The subspace push of T frames at once (several teams, a frame each): the frames taken into
   float64, then `iterations` times every frame's solve (frames in parallel) and every frame's move
   (vertex blocks in parallel, each block's rows of the basis read once for all the frames): the
   same arithmetic as subspace_push frame by frame (subspace_move is one function), the same bits.
   Returns the moved frames (T x 3V doubles, the caller frees them), or NULL when out of memory. */
static double *batched_subspace(const void *in, int in_double, int T, int V, const double *a, const double *b,
                            const double *radii, int C, int radii_step, const PushMesh *m, const PushArgs *args,
                            const SubspaceArgs *sp, const double *turn, int teams, PushTeam *team)
{
    const int k = sp->k;
    const size_t step = (size_t)V * 3;
    double *frames = malloc(sizeof(double) * step * T), *coefs = malloc(sizeof(double) * (size_t)k * T);
    unsigned char *active = malloc((size_t)T);
    if (!frames || !coefs || !active) {
        free(frames);
        free(coefs);
        free(active);
        return NULL;
    }
    memset(active, 1, (size_t)T);
    #pragma omp parallel num_threads(teams)
    {
        PushTeam *mine = team + omp_get_thread_num();
        #pragma omp for schedule(static)
        for (int t = 0; t < T; ++t)
            for (size_t q = 0; q < step; ++q)
                frames[t * step + q] = in_double ? ((const double *)in)[t * step + q] : ((const float *)in)[t * step + q];
        for (int it = 0; it < sp->iterations; ++it) {
            #pragma omp for schedule(dynamic)
            for (int t = 0; t < T; ++t) {
                if (!active[t]) continue;
                int solved = 0;
                #pragma omp parallel num_threads(1)  /* this frame's own one-thread team */
                solved = subspace_solve(frames + t * step, V, a + (size_t)t * 3 * C, b + (size_t)t * 3 * C,
                                        radii + (size_t)t * radii_step, C, NULL, m, args->margin, sp, turn + 9 * t, mine,
                                        coefs + (size_t)k * t);
                active[t] = (unsigned char)solved;
            }
            #pragma omp for schedule(static)
            for (int v0 = 0; v0 < V; v0 += MOVE_BLOCK)
                for (int t = 0; t < T; ++t)
                    if (active[t])
                        subspace_move(frames + t * step, v0, v0 + MOVE_BLOCK < V ? v0 + MOVE_BLOCK : V, sp->blocks, k,
                                      coefs + (size_t)k * t, turn + 9 * t);
        }
    }
    free(coefs);
    free(active);
    return frames;
}

/* T frames in (T, V, 3) float32, or float64 with in_double -> pushed out (T, V, 3) float32, in
   float64 between: one frame at
   a time shared by the team (a stream's single frame), or several frames in parallel, each in its
   own one-thread team (offline). radii_step: 0 where every frame has the same radii, C where each
   frame has its own (a crowd's characters of different bodies). ring, ring_drop, width, follow:
   the neighbour-follow (ring NULL: none); patch_ptr, patch_idx, patches: the culled distances
   (patch_ptr NULL: none). limit (NULL: none): the strain limit, each frame limited right after its
   push (torn[t]: whether frame t was; before and after are the push's). subspace (NULL: none): the
   subspace push before the mesh push, each frame's body frame turned by turn (T, 3, 3). base
   (NULL: none): (T, V, 3) float32, the regression under a mode's additions, taken back first where
   they carry the cloth into the body (take_back_frame; before is then of the frame as it came). NaN fractions when out of memory or where k > SUBSPACE_MAXK. */
void hrr_push_out(const void *in, int in_double, float *out, int T, int V, const double *a, const double *b, const double *radii, int C,
                  int radii_step, const int32_t *indptr, const int32_t *indices, const double *weights,
                  const int32_t *ring, const double *ring_drop, int width, int follow, const int32_t *patch_ptr,
                  const int32_t *patch_idx, int patches, const PushArgs *args, const StrainArgs *limit,
                  const SubspaceArgs *subspace, const double *turn, const SkinPose *skin, const float *base, int threads,
                  double *before, double *after, unsigned char *torn)
{
    enum { MAX_TEAMS = 64, BUF = 26, SUBSPACE_MAXK = 512 };  /* BUF: push_frame's 20 V doubles, then p and u */
    if (T <= 0) return;
    if (threads > MAX_TEAMS) threads = MAX_TEAMS;
    if (threads < 1) threads = 1;
    const int teams = T < threads ? T : threads, shared = T < threads;  /* shared: one team per frame */
    const int team_count = shared ? 1 : teams;
    const size_t per_limit = limit ? limit_scratch_bytes(limit->E) : 0;
    const size_t solve = subspace ? (size_t)subspace->k * (subspace->k + 2) : 0;
    double *buf = malloc(sizeof(double) * ((size_t)V * BUF + solve) * team_count);
    int32_t *ints = calloc((size_t)V * 7 * team_count, sizeof(int32_t));  /* the marks start at zero */
    int32_t *vertex_patch = patch_ptr ? malloc(sizeof(int32_t) * (size_t)V) : NULL;
    unsigned char *limit_block = limit ? malloc(per_limit * team_count) : NULL;
    int flags[5 * MAX_TEAMS];
    PushTeam team[MAX_TEAMS];
    if (!buf || !ints || (patch_ptr && !vertex_patch) || (limit && !limit_block) ||
        follow + args->smooth + 1 > MAX_REGION_RINGS || (subspace && (subspace->k < 1 || subspace->k > SUBSPACE_MAXK))) {
        for (int t = 0; t < T; ++t) before[t] = after[t] = NAN;  /* the caller raises */
        free(buf);
        free(ints);
        free(vertex_patch);
        free(limit_block);
        return;
    }
    for (int q = 0; patch_ptr && q < patches; ++q)
        for (int i = patch_ptr[q]; i < patch_ptr[q + 1]; ++i) vertex_patch[patch_idx[i]] = q;
    const PushMesh mesh = {indptr, indices, weights, ring, ring_drop, width, follow, patch_ptr, patch_idx, patches,
                           vertex_patch};
    for (int k = 0; k < team_count; ++k) {
        double *mine = buf + ((size_t)V * BUF + solve) * k;
        team[k] = (PushTeam){mine, mine + (size_t)V * 20, mine + (size_t)V * 23, mine + (size_t)V * BUF,
                             ints + (size_t)V * 7 * k, ints + (size_t)V * 7 * k + 3 * (size_t)V, flags + 5 * k, {0},
                             {0}, {0}};
        if (limit) team[k].limit = limit_scratch(limit_block + per_limit * k, limit->E);
    }
    const size_t step = (size_t)V * 3;
    /* several frames: their subspace push batched first, where there is one (and the memory), against
       capsules (against the skin each frame's push measures its own skin, in push_and_limit) */
    double *moved = !shared && subspace && !skin && !base
        ? batched_subspace(in, in_double, T, V, a, b, radii, C, radii_step, &mesh, args, subspace, turn, teams, team) : NULL;
    if (moved) {
        in = moved;
        in_double = 1;
        subspace = NULL;
    }
    #define FRAME_IN(t) (in_double ? (const void *)((const double *)in + (t) * step) : (const void *)((const float *)in + (t) * step))
    if (shared) {
        #pragma omp parallel num_threads(threads)
        for (int t = 0; t < T; ++t) {
            const StrainArgs own = limit ? frame_limit(limit, t) : (StrainArgs){0};
            push_and_limit(FRAME_IN(t), in_double, out + t * step, V, a + (size_t)t * 3 * C, b + (size_t)t * 3 * C,
                           radii + (size_t)t * radii_step, C, skin ? skin + t : NULL, &mesh, args, limit ? &own : NULL, subspace,
                           turn ? turn + 9 * t : NULL, base ? base + t * step : NULL, before + t, after + t,
                           torn + t, team);
        }
    } else {
        #pragma omp parallel for num_threads(teams) schedule(dynamic)
        for (int t = 0; t < T; ++t) {
            PushTeam *mine = team + omp_get_thread_num();
            const StrainArgs own = limit ? frame_limit(limit, t) : (StrainArgs){0};
            #pragma omp parallel num_threads(1)  /* this frame's own one-thread team */
            push_and_limit(FRAME_IN(t), in_double, out + t * step, V, a + (size_t)t * 3 * C, b + (size_t)t * 3 * C,
                           radii + (size_t)t * radii_step, C, skin ? skin + t : NULL, &mesh, args, limit ? &own : NULL, subspace,
                           turn ? turn + 9 * t : NULL, base ? base + t * step : NULL, before + t, after + t,
                           torn + t, mine);
        }
    }
    #undef FRAME_IN
    for (int k = 0; k < team_count; ++k) {
        skin_columns_free(&team[k].columns);
    }
    free(moved);
    free(buf);
    free(ints);
    free(vertex_patch);
    free(limit_block);
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
