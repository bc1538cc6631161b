/* skin_sdf.c: the signed distance to the body the viewer sees, by inverse skinning into one rest grid
   (hrr_garment/body/skin_collider.py is the reference, step for step; hrr_garment/native/skin.py the
   ctypes glue). Per frame, hrr_skin_pose skins the mesh once; per point,
   hrr_skin_sdf takes the point back to the rest pose from the best joints' rigid guesses by damped
   fixed-point steps r <- r + step M(w(r))^-1 (x - M(w(r)) r - t(w(r))), reads the faces the grid lists
   at each rest point's node and returns the exact signed distance to the nearest of them, posed.
   The push-out's broad phase (skin_columns, skin_far_by_column) spares it the points a frame's posed
   triangles show farther than the margin from the skin and outside it; hrr_skin_cells is the
   reference's cull (PosedSkin.distance), and hrr_skin_frames poses a batch of frames and grows the
   skin's hulls. */

#include "hrr_native.h"


/* a posed face's unit normal (zero where degenerate; pseudo_normals.py's) */
static void face_unit_normal(const SkinGrid *g, const double *posed, int f, double n[3])
{
    const int *c = g->faces + 3 * f;
    const double *a = posed + 3 * c[0], *b = posed + 3 * c[1], *d = posed + 3 * c[2];
    const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
    n[0] = u[1] * w[2] - u[2] * w[1], n[1] = u[2] * w[0] - u[0] * w[2], n[2] = u[0] * w[1] - u[1] * w[0];
    const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const double s = len > 1e-300 ? len : 1e-300;
    n[0] /= s, n[1] /= s, n[2] /= s;
}

/* a posed vertex's angle-weighted unit normal, its pseudonormal (pseudo_normals.py): its faces' unit
   normals, each weighted by the face's angle at the vertex. Measured where a point's nearest point is
   that vertex, not for every vertex a frame (its faces' angles would cost the pose four times over) */
static void vertex_pseudonormal(const SkinGrid *g, const double *posed, int v, double n[3])
{
    n[0] = n[1] = n[2] = 0.0;
    for (int e = g->corner_start[v]; e < g->corner_start[v + 1]; e++) {
        const int f = g->corner_list[e] / 3, k = g->corner_list[e] % 3;
        const int *c = g->faces + 3 * f;
        const double *o = posed + 3 * c[k], *p1 = posed + 3 * c[(k + 1) % 3], *p2 = posed + 3 * c[(k + 2) % 3];
        const double u[3] = {p1[0] - o[0], p1[1] - o[1], p1[2] - o[2]}, w[3] = {p2[0] - o[0], p2[1] - o[1], p2[2] - o[2]};
        const double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        /* x is the face's normal at any of its corners, |x| the sine of the angle there times the edges */
        const double len = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        const double angle = atan2(len, u[0] * w[0] + u[1] * w[1] + u[2] * w[2]);
        const double s = angle / (len > 1e-300 ? len : 1e-300);
        for (int a = 0; a < 3; a++) n[a] += s * x[a];
    }
    const double len = fmax(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1e-12);
    n[0] /= len, n[1] /= len, n[2] /= len;
}

/* the posed mesh (V, 3) for the joints' moves rot (J, 3, 3) and trans (J, 3) */
void hrr_skin_pose(const SkinGrid *g, const double *rot, const double *trans, double *posed)
{
    for (int v = 0; v < g->V; v++) {
        const double *r = g->rest + 3 * v;
        double *p = posed + 3 * v;
        p[0] = p[1] = p[2] = 0.0;
        for (int k = 0; k < g->vertex_k; k++) {
            const double w = g->vertex_weights[v * g->vertex_k + k];
            if (w == 0.0) continue;
            const int j = g->vertex_joints[v * g->vertex_k + k];
            const double *R = rot + 9 * j, *t = trans + 3 * j;
            for (int a = 0; a < 3; a++) p[a] += w * (R[3 * a] * r[0] + R[3 * a + 1] * r[1] + R[3 * a + 2] * r[2] + t[a]);
        }
    }
}

/* min(max(x, lo), hi) inline (fmin and fmax are library calls where NaN must be honoured) */
static inline double clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* T frames posed at once, frames in parallel (`threads`): each frame's mesh (hrr_skin_pose) for its
   joints' moves rot (T, J, 3, 3), trans (T, J, 3), and where pieces are given (P > 0) its hulls' radii
   (T, C): each capsule (ends a, b (T, C, 3), radius radii (C,)) grown by the farthest any of its
   pieces' points lies outside it, never narrower than it
   (hrr_garment/body/skin_envelope.py's growth and PosedSkin.of_frames, the reference): point p lies
   on the face of vertices corners (P, 3) at barycentric bary (P, 3), its piece held by capsule
   capsule[p]. Posing and growing a 64-frame batch in numpy, one thread, was a tenth of the push */
void hrr_skin_frames(const SkinGrid *g, int T, const double *rot, const double *trans, double *posed,
                     const double *a, const double *b, const double *radii, int C, const int32_t *corners,
                     const double *bary, const int32_t *capsule, int P, double *hull, int threads)
{
    #pragma omp parallel for num_threads(threads) schedule(static)
    for (int t = 0; t < T; t++) {
        double *pt = posed + (size_t)t * 3 * g->V;
        hrr_skin_pose(g, rot + (size_t)t * 9 * g->J, trans + (size_t)t * 3 * g->J, pt);
        if (P <= 0) continue;
        const double *at = a + (size_t)t * 3 * C, *bt = b + (size_t)t * 3 * C;
        double *h = hull + (size_t)t * C;
        for (int c = 0; c < C; c++) h[c] = -INFINITY;
        for (int q = 0; q < P; q++) {
            const int32_t *v = corners + 3 * q;
            const double *w = bary + 3 * q;
            const int c = capsule[q];
            double rel[3], axis[3], dot = 0.0, len2 = 0.0;
            for (int k = 0; k < 3; k++) {
                const double x = w[0] * pt[3 * v[0] + k] + w[1] * pt[3 * v[1] + k] + w[2] * pt[3 * v[2] + k];
                axis[k] = bt[3 * c + k] - at[3 * c + k], rel[k] = x - at[3 * c + k];
                dot += rel[k] * axis[k], len2 += axis[k] * axis[k];
            }
            const double s = clamp(dot / (len2 > 1e-12 ? len2 : 1e-12), 0.0, 1.0);
            double gap2 = 0.0;
            for (int k = 0; k < 3; k++) gap2 += (rel[k] - s * axis[k]) * (rel[k] - s * axis[k]);
            const double out = sqrt(gap2) - radii[c];
            if (out > h[c] || out != out) h[c] = out;  /* a NaN stays, as numpy's maximum keeps it */
        }
        for (int c = 0; c < C; c++) {
            const double grown = radii[c] + h[c];
            h[c] = grown > radii[c] || grown != grown ? grown : radii[c];
        }
    }
}


static inline long skin_node(const SkinGrid *g, const double *r)
{
    long idx[3];
    for (int a = 0; a < 3; a++) idx[a] = (long)clamp(nearbyint((r[a] - g->origin[a]) / g->voxel), 0.0, g->shape[a] - 1);
    return (idx[0] * g->shape[1] + idx[1]) * g->shape[2] + idx[2];
}

/* the blended move M(w), t(w) of the skin weights at rest point r (trilinear over eight nodes) and
   the rest distance there */
static double skin_blend(const SkinGrid *g, const double *rot, const double *trans, const double *r, double *M,
                         double *t)
{
    double w[256]; /* J <= 255: the joints are bytes */
    memset(w, 0, sizeof(double) * g->J);
    long base[3];
    double frac[3], dist = 0.0;
    for (int a = 0; a < 3; a++) {
        const double top = g->shape[a] - 1;
        const double x = clamp((r[a] - g->origin[a]) / g->voxel, 0.0, top);
        const double last = top - 1.0 > 0.0 ? top - 1.0 : 0.0;
        base[a] = (long)(floor(x) < last ? floor(x) : last);
        frac[a] = x - base[a];
    }
    for (int corner = 0; corner < 8; corner++) {
        long c[3];
        double share = 1.0;
        for (int a = 0; a < 3; a++) {
            const int bit = (corner >> (2 - a)) & 1;
            c[a] = base[a] + (bit < g->shape[a] - 1 ? bit : g->shape[a] - 1);
            share *= bit ? frac[a] : 1.0 - frac[a];
        }
        const SkinNode *node = g->nodes + (c[0] * g->shape[1] + c[1]) * g->shape[2] + c[2];
        for (int k = 0; k < SKIN_TOP; k++) w[node->joints[k]] += share * (double)node->weights[k];
        dist += share * (double)node->distance;
    }
    for (int a = 0; a < 9; a++) M[a] = 0.0;
    t[0] = t[1] = t[2] = 0.0;
    for (int j = 0; j < g->J; j++) {
        if (w[j] == 0.0) continue;
        for (int a = 0; a < 9; a++) M[a] += w[j] * rot[9 * j + a];
        for (int a = 0; a < 3; a++) t[a] += w[j] * trans[3 * j + a];
    }
    return dist;
}

/* M^-1 b by the adjugate (a blend of rotations: far from singular where skin is) */
static inline void solve3(const double *M, const double *b, double *x)
{
    const double c00 = M[4] * M[8] - M[5] * M[7], c01 = M[5] * M[6] - M[3] * M[8], c02 = M[3] * M[7] - M[4] * M[6];
    const double inv = 1.0 / (M[0] * c00 + M[1] * c01 + M[2] * c02);
    const double c10 = M[2] * M[7] - M[1] * M[8], c11 = M[0] * M[8] - M[2] * M[6], c12 = M[1] * M[6] - M[0] * M[7];
    const double c20 = M[1] * M[5] - M[2] * M[4], c21 = M[2] * M[3] - M[0] * M[5], c22 = M[0] * M[4] - M[1] * M[3];
    x[0] = (c00 * b[0] + c10 * b[1] + c20 * b[2]) * inv;
    x[1] = (c01 * b[0] + c11 * b[1] + c21 * b[2]) * inv;
    x[2] = (c02 * b[0] + c12 * b[1] + c22 * b[2]) * inv;
}

/* the barycentric coordinates of the point of triangle (a, b, c) nearest to p (Ericson 5.1.5) */
static void closest_bary(const double *p, const double *a, const double *b, const double *c, double *bary)
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    for (int k = 0; k < 3; k++) ab[k] = b[k] - a[k], ac[k] = c[k] - a[k], ap[k] = p[k] - a[k], bp[k] = p[k] - b[k], cp[k] = p[k] - c[k];
#define DOT(u, v) (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])
    const double d1 = DOT(ab, ap), d2 = DOT(ac, ap), d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
#undef DOT
    const double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0) { bary[0] = 1, bary[1] = 0, bary[2] = 0; return; }
    if (d3 >= 0 && d4 <= d3) { bary[0] = 0, bary[1] = 1, bary[2] = 0; return; }
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        const double t = d1 / (d1 != d3 ? d1 - d3 : 1.0);
        bary[0] = 1 - t, bary[1] = t, bary[2] = 0; return;
    }
    if (d6 >= 0 && d5 <= d6) { bary[0] = 0, bary[1] = 0, bary[2] = 1; return; }
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        const double t = d2 / (d2 != d6 ? d2 - d6 : 1.0);
        bary[0] = 1 - t, bary[1] = 0, bary[2] = t; return;
    }
    if (va <= 0 && d4 >= d3 && d5 >= d6) {
        const double den = (d4 - d3) + (d5 - d6), t = (d4 - d3) / (den != 0 ? den : 1.0);
        bary[0] = 0, bary[1] = 1 - t, bary[2] = t; return;
    }
    const double total = va + vb + vc, s = total != 0 ? total : 1.0;
    bary[1] = vb / s, bary[2] = vc / s, bary[0] = 1.0 - bary[1] - bary[2];
}

/* the nearest of the faces node lists to x: its distance, signed by the pseudonormal of the nearest
   point's face, edge or vertex (pseudo_normals.py: the face's normal, the two faces' across an edge,
   the vertex's angle-weighted normal), and the outward normal */
static double skin_nearest_face(const SkinGrid *g, long node, const double *posed, const double *x, double *normal)
{
    double best = INFINITY, gap[3] = {0}, bary_best[3] = {0};
    int face = -1;
    for (int e = g->face_start[node]; e < g->face_start[node + 1]; e++) {
        const int f = g->face_list[e];
        const int *c = g->faces + 3 * f;
        const double *a = posed + 3 * c[0], *b = posed + 3 * c[1], *d = posed + 3 * c[2];
        double bary[3], q[3];
        closest_bary(x, a, b, d, bary);
        for (int k = 0; k < 3; k++) q[k] = x[k] - (bary[0] * a[k] + bary[1] * b[k] + bary[2] * d[k]);
        const double len = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (len < best) best = len, face = f, memcpy(gap, q, sizeof gap), memcpy(bary_best, bary, sizeof bary_best);
    }
    const int *c = g->faces + 3 * face;
    const int zeros = (bary_best[0] == 0.0) + (bary_best[1] == 0.0) + (bary_best[2] == 0.0);
    double out[3];
    if (zeros == 2) {  /* at a corner: the vertex's */
        const int k = bary_best[0] != 0.0 ? 0 : (bary_best[1] != 0.0 ? 1 : 2);
        vertex_pseudonormal(g, posed, c[k], out);
    } else {
        face_unit_normal(g, posed, face, out);
        if (zeros == 1) {  /* on the edge opposite the corner of no weight: the face across it too */
            const int k = bary_best[0] == 0.0 ? 0 : (bary_best[1] == 0.0 ? 1 : 2);
            double across[3];
            face_unit_normal(g, posed, g->neighbours[3 * face + (k + 1) % 3], across);
            for (int a = 0; a < 3; a++) out[a] += across[a];
        }
    }
    const int inside = gap[0] * out[0] + gap[1] * out[1] + gap[2] * out[2] < 0.0;
    double n[3];
    if (best > 1e-9)
        for (int k = 0; k < 3; k++) n[k] = (inside ? -gap[k] : gap[k]) / best;  /* best > 1e-9 > 1e-12 */
    else
        memcpy(n, out, sizeof n);
    const double norm = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    const double len = norm > 1e-12 ? norm : 1e-12;  /* fmax's answer, NaN included, without its call */
    for (int k = 0; k < 3; k++) normal[k] = n[k] / len;
    return inside ? -best : best;
}

static void skin_point(const SkinGrid *g, const double *rot, const double *trans, const double *posed,
                       const double *x, double *distance, double *normal)
{
    /* the starts: the joints whose rigid guess lands nearest to skin of their own (ties: lowest index) */
    int order[SKIN_MAX_STARTS];
    double rank[SKIN_MAX_STARTS], guess[SKIN_MAX_STARTS][3];
    const int S = g->starts < g->J ? g->starts : g->J;
    int found = 0;
    /* every joint's rigid guess first, its node fetched ahead: the reads land all over the grid */
    double rigid[256][3];
    long at_node[256];
    for (int j = 0; j < g->J; j++) {
        const double *R = rot + 9 * j, *t = trans + 3 * j;
        const double y[3] = {x[0] - t[0], x[1] - t[1], x[2] - t[2]};
        for (int a = 0; a < 3; a++) rigid[j][a] = R[a] * y[0] + R[3 + a] * y[1] + R[6 + a] * y[2]; /* R^T y */
        at_node[j] = skin_node(g, rigid[j]);
        __builtin_prefetch(g->nodes + at_node[j]);
    }
    for (int j = 0; j < g->J; j++) {
        const double *r = rigid[j];
        const SkinNode *node = g->nodes + at_node[j];
        double own = 0.0;
        for (int k = 0; k < SKIN_TOP; k++)
            if (node->joints[k] == j) own += (double)node->weights[k];
        const double score = fabs((double)node->distance) + (1.0 - own) * g->off_skin;
        if (found == S && score >= rank[S - 1]) continue;
        int at = found < S ? found++ : S - 1;
        while (at > 0 && rank[at - 1] > score) {
            rank[at] = rank[at - 1], order[at] = order[at - 1], memcpy(guess[at], guess[at - 1], sizeof guess[0]);
            at--;
        }
        rank[at] = score, order[at] = j, memcpy(guess[at], r, sizeof guess[0]);
    }
    double best = INFINITY, best_signed = 0.0, best_normal[3] = {0};
    long seen[SKIN_MAX_STARTS];
    double signed_at[SKIN_MAX_STARTS];
    /* how deep inside the rest mesh a start settled whose own nearest face puts x inside too; how deep
       a start ended, settled or not */
    double own_deep = 0.0, under = 0.0;
    /* the starts' fixed points in step: each step of one start a chain of dependent reads (its nodes,
       a division, the next rest point), so the starts' steps taken side by side overlap (each start's
       arithmetic as alone; 2.5 -> 2.1 us a point of one core) */
    double miss[SKIN_MAX_STARTS][3], rest_d[SKIN_MAX_STARTS];
    for (int k = 0; k <= g->iterations; k++)
        for (int s = 0; s < found; s++) {
            double *r = guess[s], M[9], t[3], step[3];
            rest_d[s] = skin_blend(g, rot, trans, r, M, t);
            for (int a = 0; a < 3; a++) miss[s][a] = x[a] - (M[3 * a] * r[0] + M[3 * a + 1] * r[1] + M[3 * a + 2] * r[2]) - t[a];
            if (k == g->iterations) continue;
            solve3(M, miss[s], step);
            for (int a = 0; a < 3; a++) r[a] += g->step * step[a];
        }
    for (int s = 0; s < found; s++) {
        const double *r = guess[s], *m = miss[s], d = rest_d[s];
        if (-d > under) under = -d;
        /* starts that settle in the same node list the same faces: measured once */
        seen[s] = skin_node(g, r);
        int again = -1;
        for (int q = 0; q < s; q++)
            if (again < 0 && seen[q] == seen[s]) again = q;
        if (again >= 0) {
            signed_at[s] = signed_at[again];
        } else {
            double n[3];
            signed_at[s] = skin_nearest_face(g, seen[s], posed, x, n);
            if (fabs(signed_at[s]) < best) best = fabs(signed_at[s]), best_signed = signed_at[s], memcpy(best_normal, n, sizeof n);
        }
        if (sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]) < g->settled && signed_at[s] < 0.0 && -d > own_deep) own_deep = -d;
    }
    /* the side rules (skin_collider.side_rules): a point skinning carries from deep inside the rest
       mesh, whose own nearest face agrees, is inside whatever a buried face says, so long as that face
       is no farther than the depth; the face's normal says inside within face_side of it, or of a
       start's rest depth */
    const int near_face = best_signed >= -g->face_side || (under > g->deep && best_signed >= -(under + g->face_side));
    const int inside = (best_signed < 0.0 && near_face) || (own_deep > g->deep && fabs(best_signed) <= own_deep + g->deep);
    const int flip = inside != (best_signed < 0.0);
    *distance = flip ? -best_signed : best_signed;
    for (int a = 0; a < 3; a++) normal[a] = flip ? -best_normal[a] : best_normal[a];
}

/* (N,) signed distances and (N, 3) outward normals of points (N, 3) against the mesh posed by
   hrr_skin_pose for the same moves */
void hrr_skin_sdf(const SkinGrid *g, const double *rot, const double *trans, const double *posed,
                  const double *points, int N, double *distance, double *normal)
{
    for (int i = 0; i < N; i++) skin_point(g, rot, trans, posed, points + 3 * i, distance + i, normal + 3 * i);
}

/* (a . b), summed in the order numpy's reference sums it */
#define DOT3(u, w) ((u)[0] * (w)[0] + (u)[1] * (w)[1] + (u)[2] * (w)[2])

/* triangle v's unit normal nh and plane offset po (nh . x = po on it), and each edge e's outward unit
   normal in the plane m[e] (edge e runs from v[e] to v[e + 1]) with its offset o[e] = m[e] . v[e];
   all zero for a degenerate triangle (hrr_garment/body/skin_cells.py computes the same, op for op) */
static void unit_normal(const double *const v[3], double nh[3], double m[3][3], double o[3], double *po)
{
    const double u[3] = {v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]};
    const double w[3] = {v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]};
    const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    const double len = sqrt(DOT3(n, n));
    for (int k = 0; k < 3; k++) nh[k] = len > 0.0 ? n[k] / len : 0.0;
    *po = DOT3(nh, v[0]);
    for (int e = 0; e < 3; e++) {
        const double *s = v[e], *t = v[(e + 1) % 3];
        const double d[3] = {t[0] - s[0], t[1] - s[1], t[2] - s[2]};
        const double q[3] = {d[1] * nh[2] - d[2] * nh[1], d[2] * nh[0] - d[0] * nh[2], d[0] * nh[1] - d[1] * nh[0]};
        const double ql = sqrt(DOT3(q, q));
        for (int k = 0; k < 3; k++) m[e][k] = ql > 0.0 ? q[k] / ql : 0.0;
        o[e] = DOT3(m[e], s);
    }
}

/* grows *a (of *cap int32s) to hold at least `need` */
static int grow_ints(int32_t **a, size_t *cap, size_t need)
{
    if (need <= *cap) return 1;
    const size_t want = need > 2 * *cap ? need : 2 * *cap;
    int32_t *b = realloc(*a, sizeof(int32_t) * want);
    if (!b) return 0;
    *a = b, *cap = want;
    return 1;
}

/* The cells of a uniform grid over one posed frame (cell size `cell`, first corner origin, dims
   cells x-major; hrr_garment/body/skin_cells.py the reference, which also picks the box) that lie
   farther than `margin` from every triangle of the posed mesh and outside it: the reference's cull
   (PosedSkin.distance), cell for cell (the push-out's own is skin_columns, below). cells (zeroed here): 1 where a triangle may come within the margin of the cell, 2 the
   free cells the grid's border reaches through free cells (6-neighbours), 0 the other free cells.
   Why it holds, for a closed mesh (every edge shared by two faces, as the caller checks):
   - a point of a cell within `margin` of a triangle puts the cell's centre within r = margin + h of
     it (h: half the cell's diagonal), so a cell whose centre is farther than r from every
     triangle (the test below takes no fewer cells) is farther than the margin from the skin;
   - the box reaches margin + 2 cells past the skin's, so every border cell is free and outside;
   - a closed mesh's winding number is constant on a connected set that does not touch it: the free
     cells the border reaches are outside (winding 0) however the posed mesh overlaps itself.
   Points in the band and in the free cells the flood does not reach (inside the body, or pockets
   the band closes off) are left to the exact tests. */
static void skin_band_cells(const SkinGrid *g, const double *posed, double margin, double cell, const double *origin,
                            const int *dims, uint8_t *cells)
{
    const long nx = dims[0], ny = dims[1], nz = dims[2], count = nx * ny * nz;
    const double r = margin + 0.5 * sqrt(3.0) * cell;
    memset(cells, 0, (size_t)count);
    for (int f = 0; f < g->F; f++) {
        const int *c = g->faces + 3 * f;
        const double *v[3] = {posed + 3 * c[0], posed + 3 * c[1], posed + 3 * c[2]};
        long lo[3], hi[3];
        for (int k = 0; k < 3; k++) {  /* the cells whose centres lie in the triangle's box grown by r */
            const double mn = fmin(v[0][k], fmin(v[1][k], v[2][k])), mx = fmax(v[0][k], fmax(v[1][k], v[2][k]));
            lo[k] = (long)fmax(ceil((mn - r - origin[k]) / cell - 0.5), 0.0);
            hi[k] = (long)fmin(floor((mx + r - origin[k]) / cell - 0.5), (double)(dims[k] - 1));
        }
        /* a cell is taken where its centre x is within r of the triangle's plane and of the inner side
           of each edge's line (m_e . x - o_e <= r, m_e the edge's outward unit normal in the plane):
           every point within r of the triangle is, so the test takes every cell the band needs (and
           a few more about the corners), at four dot products a cell */
        double nh[3], m[3][3], o[3], po = 0.0;
        unit_normal(v, nh, m, o, &po);
        const int flat = nh[0] == 0.0 && nh[1] == 0.0 && nh[2] == 0.0;  /* degenerate: its whole box */
        /* only the cells near the plane: along the axis a the normal is largest on, each column of
           the box holds an interval of them (widened past rounding) */
        int a = fabs(nh[0]) >= fabs(nh[1]) ? 0 : 1;
        a = fabs(nh[2]) > fabs(nh[a]) ? 2 : a;
        const int p1 = (a + 1) % 3, p2 = (a + 2) % 3;
        const long stride[3] = {ny * nz, nz, 1};
        const double inv_cell = 1.0 / cell, inv_n = flat ? 0.0 : inv_cell / nh[a], spread = flat ? 0.0 : r * fabs(inv_n);
        for (long i = lo[p1]; i <= hi[p1]; i++)
            for (long j = lo[p2]; j <= hi[p2]; j++) {
                long k0 = lo[a], k1 = hi[a];
                double x[3];
                x[p1] = origin[p1] + (i + 0.5) * cell, x[p2] = origin[p2] + (j + 0.5) * cell;
                if (!flat) {  /* nh . x - po within +-r: an interval of x_a (in cells: products, no divisions) */
                    const double mid = (po - nh[p1] * x[p1] - nh[p2] * x[p2]) * inv_n - origin[a] * inv_cell - 0.5;
                    const double from = floor(mid - spread - 1e-6), to = ceil(mid + spread + 1e-6);
                    if (from > k0) k0 = (long)from;
                    if (to < k1) k1 = (long)to;
                }
                for (long k = k0; k <= k1; k++) {
                    const long at = i * stride[p1] + j * stride[p2] + k * stride[a];
                    if (cells[at]) continue;
                    x[a] = origin[a] + (k + 0.5) * cell;
                    if (flat || (fabs(DOT3(nh, x) - po) <= r && DOT3(m[0], x) - o[0] <= r && DOT3(m[1], x) - o[1] <= r &&
                                 DOT3(m[2], x) - o[2] <= r))
                        cells[at] = 1;
                }
            }
    }
    /* the flood from the border: every border cell is free (the box's padding) and outside, marked 2;
       the flood then runs on the inner cells only, each pushed once (marked 2 as it is pushed), whose
       six neighbours all lie in the grid: no bounds to check, no index to divide out */
    int32_t *stack = malloc(sizeof(int32_t) * (size_t)count);
    if (!stack) {  /* no memory: no cell is known outside, every point is measured */
        memset(cells, 1, (size_t)count);
        return;
    }
    long top = 0;
    const long step[3] = {ny * nz, nz, 1}, size[3] = {nx, ny, nz};
    for (long i = 0; i < nx; i++)
        for (long j = 0; j < ny; j++)
            for (long k = 0; k < nz; k++) {
                const long idx[3] = {i, j, k}, at = (i * ny + j) * nz + k;
                int border = 0;
                for (int a = 0; a < 3; a++) border |= idx[a] == 0 || idx[a] == size[a] - 1;
                if (!border) {
                    k = k < nz - 2 ? nz - 2 : k;  /* an inner row: on to its last cell */
                    continue;
                }
                cells[at] = 2;
                for (int a = 0; a < 3; a++) {  /* the inner neighbour across each border face */
                    const long in = idx[a] == 0 ? at + step[a] : (idx[a] == size[a] - 1 ? at - step[a] : -1);
                    const long ia = idx[a] == 0 ? 1 : size[a] - 2;
                    int inner = in >= 0 && ia > 0 && ia < size[a] - 1;
                    for (int e = 0; e < 3; e++)
                        if (e != a) inner &= idx[e] > 0 && idx[e] < size[e] - 1;
                    if (inner && !cells[in]) {
                        cells[in] = 2;
                        stack[top++] = (int32_t)in;
                    }
                }
            }
    while (top > 0) {
        const long at = stack[--top];
        for (int a = 0; a < 3; a++)
            for (int s = -1; s <= 1; s += 2) {
                uint8_t *next = cells + at + s * step[a];
                if (*next) continue;
                *next = 2;
                stack[top++] = (int32_t)(next - cells);
            }
    }
    free(stack);
}

/* hrr_garment.native.skin's SkinKernel.cells (the reference's cull) */
void hrr_skin_cells(const SkinGrid *g, const double *posed, double margin, double cell, const double *origin,
                    const int *dims, uint8_t *cells)
{
    skin_band_cells(g, posed, margin, cell, origin, dims, cells);
}

/* The crossing of the ray from x along +x with triangle v (vertex indices c): +1 where it leaves
   through the triangle (the triangle's normal along +x), -1 where it enters, 0 where it misses, and
   the crossing's x in *hit. Watertight: each edge's function in the (y, z) plane is evaluated from
   its lower-indexed end, so two triangles sharing the edge see exactly opposite values, and a ray
   through the edge itself goes to one side of it by a fixed rule (the edge's direction): a ray
   through a shared edge crosses exactly one of the two faces, or, at a silhouette, both or
   neither, which cancel. The function is the cross product of the ends' offsets from x, so that it
   is exactly 0 where the ray runs through either end, however the compiler fuses its products (from
   the lower end to x it was (t - s) x (x - s): where x is t, the fused product's rounding left it a
   hair off 0, of either sign, and a ray through a vertex crossed its faces more or less than once). */
static int ray_cross(const double *x, const double *const v[3], const int *c, double *hit)
{
    double e[3];
    int side[3];
    for (int k = 0; k < 3; k++) {  /* edge k from corner k to k + 1; its function is 0 on its line */
        const int flip = c[k] > c[(k + 1) % 3];
        const double *s = flip ? v[(k + 1) % 3] : v[k], *t = flip ? v[k] : v[(k + 1) % 3];
        const double f = (s[1] - x[1]) * (t[2] - x[2]) - (s[2] - x[2]) * (t[1] - x[1]);
        const int tie = t[1] > s[1] || (t[1] == s[1] && t[2] > s[2]) ? 1 : -1;
        e[k] = flip ? -f : f;
        side[k] = (f > 0.0 ? 1 : (f < 0.0 ? -1 : tie)) * (flip ? -1 : 1);
    }
    if (side[0] != side[1] || side[1] != side[2]) return 0;
    const double area = e[0] + e[1] + e[2];  /* twice the (y, z) projection's signed area */
    if (area == 0.0) return 0;  /* edge on to the ray: its neighbours count the crossing */
    /* barycentric weights: each corner's, the function of the edge across from it */
    *hit = (e[1] * v[0][0] + e[2] * v[1][0] + e[0] * v[2][0]) / area;
    return side[0];
}


/* grows *a (of *cap doubles) to hold at least `need` */
static int grow_doubles(double **a, size_t *cap, size_t need)
{
    if (need <= *cap) return 1;
    const size_t want = need > 2 * *cap ? need : 2 * *cap;
    double *b = realloc(*a, sizeof(double) * want);
    if (!b) return 0;
    *a = b, *cap = want;
    return 1;
}

/* The push-out's broad phase against the skin, one frame: the posed triangles listed by columns of a
   grid over the (y, z) plane (cells `cell` wide), each triangle in every column its box grown by the
   margin (and a micrometre for rounding) meets, and each triangle's record (SKIN_FACE doubles: that
   grown box lo, hi, then its three corners), and each column's reach along x (the least lo and the
   greatest hi of its triangles' boxes). A point's column then lists every triangle within the
   margin of it (such a triangle's grown box holds the point) and every triangle the ray from it
   along +x crosses (its (y, z) projection holds the point): skin_far_by_column reads both off it.
   It replaced a 3D grid of 2 cm cells flooded from its border (165,000 cells an anny body, 1.2 ms a
   frame on one core; this: about 1,200 columns and 20 us). Writes the frame's columns into sk
   (col_start NULL where there is no memory or the mesh is not finite: every point is measured). */
static void skin_columns(const SkinGrid *g, const double *posed, double margin, double cell, SkinColumns *c,
                         SkinPose *sk)
{
    sk->col_start = NULL;
    const double reach = margin + 1e-6;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, sum = 0.0;
    if (!grow_doubles(&c->face, &c->face_cap, (size_t)SKIN_FACE * g->F)) return;
    for (int f = 0; f < g->F; f++) {
        double *r = c->face + (size_t)SKIN_FACE * f;
        for (int k = 0; k < 3; k++) {
            const double *v = posed + 3 * g->faces[3 * f + k];
            r[6 + 3 * k] = v[0], r[7 + 3 * k] = v[1], r[8 + 3 * k] = v[2];
            sum += v[0] + v[1] + v[2];
        }
        for (int a = 0; a < 3; a++) {  /* ternaries, not fmin and fmax (library calls): NaN is caught by sum */
            const double p = r[6 + a], q = r[9 + a], t = r[12 + a];
            const double mn = p < q ? (p < t ? p : t) : (q < t ? q : t), mx = p > q ? (p > t ? p : t) : (q > t ? q : t);
            r[a] = mn - reach, r[3 + a] = mx + reach;
            lo[a] = r[a] < lo[a] ? r[a] : lo[a], hi[a] = r[3 + a] > hi[a] ? r[3 + a] : hi[a];
        }
    }
    if (!(sum == sum && hi[1] - lo[1] < 1e3 * cell && hi[2] - lo[2] < 1e3 * cell)) return;  /* not finite, or not a body */
    const int ny = (int)floor((hi[1] - lo[1]) / cell) + 1, nz = (int)floor((hi[2] - lo[2]) / cell) + 1;
    const long count = (long)ny * nz;
    if (!grow_ints(&c->start, &c->start_cap, (size_t)count + 1) || !grow_doubles(&c->reach, &c->reach_cap, 2 * (size_t)count))
        return;
    int32_t *start = c->start;
    double *reach_x = c->reach;
    memset(start, 0, sizeof(int32_t) * ((size_t)count + 1));
    for (long q = 0; q < count; q++) reach_x[2 * q] = INFINITY, reach_x[2 * q + 1] = -INFINITY;
    /* twice over the faces: counted, then listed (each column's start moved up to its end, shifted
       back); a face's columns those its box's corners fall in (the same rounding as a point's) */
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            for (long q = 0; q < count; q++) start[q + 1] += start[q];
            if (!grow_ints(&c->list, &c->list_cap, start[count] > 0 ? (size_t)start[count] : 1)) return;
        }
        for (int f = 0; f < g->F; f++) {
            const double *r = c->face + (size_t)SKIN_FACE * f;
            const int y0 = (int)floor((r[1] - lo[1]) / cell), z0 = (int)floor((r[2] - lo[2]) / cell);
            const int y1 = (int)floor((r[4] - lo[1]) / cell), z1 = (int)floor((r[5] - lo[2]) / cell);
            for (int i = y0 < 0 ? 0 : y0; i <= (y1 < ny ? y1 : ny - 1); i++)
                for (int j = z0 < 0 ? 0 : z0; j <= (z1 < nz ? z1 : nz - 1); j++) {
                    const long q = (long)i * nz + j;
                    if (pass == 0) {
                        start[q + 1]++;
                        if (r[0] < reach_x[2 * q]) reach_x[2 * q] = r[0];
                        if (r[3] > reach_x[2 * q + 1]) reach_x[2 * q + 1] = r[3];
                    } else {
                        c->list[start[q]++] = f;
                    }
                }
        }
    }
    for (long q = count; q > 0; q--) start[q] = start[q - 1];
    start[0] = 0;
    sk->col_start = start, sk->col_list = c->list, sk->col_face = c->face, sk->col_reach = reach_x;
    sk->ny = ny, sk->nz = nz, sk->y0 = lo[1], sk->z0 = lo[2];
}

/* The column of point x in sk's columns: its index, or -1 where x lies beyond them (farther than the
   margin from every face in (y, z) alone, and its ray meets nothing), -2 where x is NaN */
static inline long skin_column_of(const SkinPose *sk, const double *x)
{
    const double fy = floor((x[1] - sk->y0) / sk->cell), fz = floor((x[2] - sk->z0) / sk->cell);
    if (fy != fy || fz != fz || x[0] != x[0]) return -2;
    if (fy < 0.0 || fz < 0.0 || fy >= sk->ny || fz >= sk->nz) return -1;
    return (long)fy * sk->nz + (long)fz;
}

/* The faces of column col against point x: the winding number along the ray from x along +x (the
   sum of the column's triangles' crossings past x, ray_cross: watertight), and *near = 1 where a
   triangle comes within the margin of x (closest_bary, as the skin's measure); with `stop`, the walk
   ends at the first such triangle (its winding number then partial). */
static inline int skin_column_walk(const SkinPose *sk, double margin, const double *x, long col, int stop, int *near)
{
    const int32_t *faces = sk->grid->faces;
    int winding = 0;
    *near = 0;
    for (int e = sk->col_start[col]; e < sk->col_start[col + 1]; e++) {
        const int f = sk->col_list[e];
        const double *r = sk->col_face + (size_t)SKIN_FACE * f;
        /* past its box along +x, or beside it: neither within the margin nor crossed past x */
        if (x[0] > r[3] || x[1] < r[1] || x[1] > r[4] || x[2] < r[2] || x[2] > r[5]) continue;
        const double *a = r + 6, *b = r + 9, *d = r + 12;
        if (x[0] >= r[0] && !*near) {
            double bary[3], q2 = 0.0;
            closest_bary(x, a, b, d, bary);
            for (int k = 0; k < 3; k++) {
                const double q = x[k] - (bary[0] * a[k] + bary[1] * b[k] + bary[2] * d[k]);
                q2 += q * q;
            }
            if (q2 <= margin * margin) {
                *near = 1;
                if (stop) return winding;
            }
        }
        const double *v[3] = {a, b, d};
        double hit;
        const int cross = ray_cross(x, v, faces + 3 * f, &hit);
        if (cross && hit > x[0]) winding += cross;
    }
    return winding;
}

/* Whether point x is farther than the margin from sk's skin and outside it (no need to measure it),
   exactly: no triangle of its column comes within the margin of it, and the winding number along
   the ray from x along +x is 0 (skin_column_walk): a closed mesh's winding number is that of the
   far end of the ray, past the mesh, where it is 0. A point beyond the columns is far; a NaN point
   is measured. */
static int skin_far_by_column(const SkinPose *sk, double margin, const double *x)
{
    const long col = skin_column_of(sk, x);
    if (col < 0) return col == -1;
    /* before every box of the column along x (nothing within the margin, nothing crosses the line
       at x's (y, z) short of x: its winding number is that of the line's far end, 0), or past every
       one (nothing within the margin, nothing crossed past x) */
    if (x[0] < sk->col_reach[2 * col] || x[0] > sk->col_reach[2 * col + 1]) return 1;
    int near;
    const int winding = skin_column_walk(sk, margin, x, col, 1, &near);
    return !near && winding == 0;
}

/* The broad phase's answer for N points (N, 3) of one posed frame: far[i] 1 where point i is
   farther than the margin from the skin and outside it (hrr_garment.native.skin's
   SkinKernel.far_outside, which tests it against the exact reference). Returns 0 without memory. */
int hrr_skin_far(const SkinGrid *g, const double *posed, double margin, double cell, const double *points, int N,
                 uint8_t *far)
{
    SkinColumns c = {0};
    SkinPose sk = {.grid = g, .posed = posed, .cell = cell};
    skin_columns(g, posed, margin, cell, &c, &sk);
    const int ok = sk.col_start != NULL;
    for (int i = 0; ok && i < N; i++) far[i] = (uint8_t)skin_far_by_column(&sk, margin, points + 3 * i);
    skin_columns_free(&c);
    return ok;
}

/* frees the columns' arrays */
static void skin_columns_free(SkinColumns *c)
{
    free(c->start);
    free(c->list);
    free(c->face);
    free(c->reach);
}
