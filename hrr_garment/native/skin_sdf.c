/* skin_sdf.c: the signed distance to the body the viewer sees, by inverse skinning into one rest grid
   (hrr_garment/body/skin_collider.py is the reference, step for step; hrr_garment/native/skin.py the
   ctypes glue). Per frame, hrr_skin_pose skins the mesh and its vertex normals once; per point,
   hrr_skin_sdf takes the point back to the rest pose from the best joints' rigid guesses by damped
   fixed-point steps r <- r + step M(w(r))^-1 (x - M(w(r)) r - t(w(r))), reads the faces the grid lists
   at each rest point's node and returns the exact signed distance to the nearest of them, posed. */

#include "hrr_native.h"


/* the posed mesh (V, 3) and its unit vertex normals (V, 3), each the area-weighted mean of its faces'
   (mesh_distance.vertex_normals), for the joints' moves rot (J, 3, 3) and trans (J, 3) */
void hrr_skin_pose(const SkinGrid *g, const double *rot, const double *trans, double *posed, double *normals)
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
    memset(normals, 0, sizeof(double) * 3 * g->V);
    for (int f = 0; f < g->F; f++) {
        const int *c = g->faces + 3 * f;
        const double *a = posed + 3 * c[0], *b = posed + 3 * c[1], *d = posed + 3 * c[2];
        const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        const double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        for (int k = 0; k < 3; k++)
            for (int a2 = 0; a2 < 3; a2++) normals[3 * c[k] + a2] += n[a2];
    }
    for (int v = 0; v < g->V; v++) {
        double *n = normals + 3 * v;
        const double len = fmax(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1e-12);
        n[0] /= len, n[1] /= len, n[2] /= len;
    }
}

/* min(max(x, lo), hi) inline (fmin and fmax are library calls where NaN must be honoured) */
static inline double clamp(double x, double lo, double hi) { return x < lo ? lo : (x > hi ? hi : x); }

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

/* the nearest of the faces node lists to x: its distance, signed by the posed vertex normals at the
   nearest point, and the outward normal */
static double skin_nearest_face(const SkinGrid *g, long node, const double *posed, const double *normals,
                                 const double *x, double *normal)
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
    double out[3];
    for (int k = 0; k < 3; k++)
        out[k] = bary_best[0] * normals[3 * c[0] + k] + bary_best[1] * normals[3 * c[1] + k] + bary_best[2] * normals[3 * c[2] + k];
    const int inside = gap[0] * out[0] + gap[1] * out[1] + gap[2] * out[2] < 0.0;
    double n[3];
    if (best > 1e-9)
        for (int k = 0; k < 3; k++) n[k] = (inside ? -gap[k] : gap[k]) / fmax(best, 1e-12);
    else
        memcpy(n, out, sizeof n);
    const double len = fmax(sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1e-12);
    for (int k = 0; k < 3; k++) normal[k] = n[k] / len;
    return inside ? -best : best;
}

static void skin_point(const SkinGrid *g, const double *rot, const double *trans, const double *posed,
                       const double *normals, const double *x, double *distance, double *normal)
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
    double deepest = 0.0, under = 0.0; /* how deep inside the rest mesh a start settled; ended, settled or not */
    for (int s = 0; s < found; s++) {
        double *r = guess[s], M[9], t[3], miss[3], step[3], d = 0.0;
        for (int k = 0; k <= g->iterations; k++) {
            d = skin_blend(g, rot, trans, r, M, t);
            for (int a = 0; a < 3; a++) miss[a] = x[a] - (M[3 * a] * r[0] + M[3 * a + 1] * r[1] + M[3 * a + 2] * r[2]) - t[a];
            if (k == g->iterations) break;
            solve3(M, miss, step);
            for (int a = 0; a < 3; a++) r[a] += g->step * step[a];
        }
        if (sqrt(miss[0] * miss[0] + miss[1] * miss[1] + miss[2] * miss[2]) < g->settled && -d > deepest) deepest = -d;
        if (-d > under) under = -d;
        /* starts that settle in the same node list the same faces: measured once */
        seen[s] = skin_node(g, r);
        int again = 0;
        for (int q = 0; q < s; q++) again |= seen[q] == seen[s];
        if (again) continue;
        double n[3];
        const double signed_d = skin_nearest_face(g, seen[s], posed, normals, x, n);
        if (fabs(signed_d) < best) best = fabs(signed_d), best_signed = signed_d, memcpy(best_normal, n, sizeof n);
    }
    /* a point skinning carries from deep inside the rest mesh is inside, whatever a buried face says,
       so long as that face is no farther than the depth (rest points inside the chest carried off
       with the arm land far from any skin: not inside); the face's normal says inside within
       face_side of it, or of a start's rest depth */
    const int near_face = best_signed >= -g->face_side || (under > g->deep && best_signed >= -(under + g->face_side));
    const int inside = (best_signed < 0.0 && near_face) || (deepest > g->deep && fabs(best_signed) <= deepest + g->deep);
    const int flip = inside != (best_signed < 0.0);
    *distance = flip ? -best_signed : best_signed;
    for (int a = 0; a < 3; a++) normal[a] = flip ? -best_normal[a] : best_normal[a];
}

/* (N,) signed distances and (N, 3) outward normals of points (N, 3) against the mesh posed by
   hrr_skin_pose for the same moves */
void hrr_skin_sdf(const SkinGrid *g, const double *rot, const double *trans, const double *posed,
                  const double *normals, const double *points, int N, double *distance, double *normal)
{
    for (int i = 0; i < N; i++) skin_point(g, rot, trans, posed, normals, points + 3 * i, distance + i, normal + 3 * i);
}
