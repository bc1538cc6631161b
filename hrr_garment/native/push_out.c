/* push_out.c: the push-out's driver (hrr_push_out): frames in teams, each frame's additions taken
   back (hrr_garment/inference/take_back.py is that step's reference), its subspace push, its mesh
   push (push_frame.c) and its strain limit (strain_limit.c), while the frame is in cache. */

#include "push_out.h"

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
    measure_frame(p, V, ca, cb, radii, C, sk, m, margin, d, nrm);  /* as push_frame's first pass, which takes them */
    deep_fraction(d, V, depth, came);
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
            measure_listed(p, list, n, ca, cb, radii, C, sk, args->margin, team->buf, team->buf + V);
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
        measure_listed(p, list, n, ca, cb, radii, C, sk, args->margin, d, nrm);
        deep_fraction(d, V, args->depth, after);
    }
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
