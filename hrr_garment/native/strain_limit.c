/* strain_limit.c: the push-out's strain limit (hrr_garment/inference/strain_limit.py is its
   reference): Gauss-Seidel passes by edge colour over the edges a push stretched past their limit. */

#include "push_out.h"

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
