/* subspace_push.c: the push in the garment's subspace before the mesh push
   (hrr_garment/inference/subspace_push.py is its reference), frame by frame or batched across frames. */

#include "push_out.h"

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
    measure_frame(p, V, ca, cb, radii, C, sk, m, reach, d, nrm);  /* the skin's columns were built for the reach */
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
