/* push_frame.c: one frame's collision push-out (hrr_garment/inference/collision.py is its
   reference): the capsules' signed distance (the body's, or the hulls' that hold its skin), each
   garment patch against only the capsules near it, the skin measured where a hull comes near, and
   the push itself, spread and projected. */

#include "push_out.h"

/* Signed distance of points to the union of C capsules (one frame's capsule ends ca, cb (C, 3),
   radii (C)): for n points (px, py, pz; at most SDF_CHUNK), entries i0 .. i0 + n - 1 of the point
   list idx (NULL: 0, 1, ...), point k = idx[i], writes dist[k] (negative inside) and the nearest
   capsule's outward unit normal normal[k]. Capsules outer, points inner in structure-of-arrays
   form, so the inner loop has no division and vectorises across points. */
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

/* skin_measure (push_out.h) of the entries of the list idx (NULL: 0 .. n - 1) whose distance d is
   within the margin of a hull (sk NULL: the capsules' distances stand) */
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

/* Every vertex of frame p measured into d and nrm, as the push's first pass measures it: the
   patches' distances where there are patches (the same wherever they are within the margin, all
   that the push, the take-back and the subspace solve, whose margin is its reach, read of them),
   the skin's near a hull. */
static void measure_frame(const double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                          const SkinPose *sk, const PushMesh *m, double margin, double *d, double *nrm)
{
    if (m->patch_ptr) sdf_patches(p, m, ca, cb, radii, C, margin, d, nrm);
    else sdf_points(p, NULL, V, ca, cb, radii, C, d, nrm);
    skin_refine(sk, p, NULL, V, margin, d, nrm);
}

/* The n vertices of `list` measured again into d and nrm (against every capsule or hull, then the
   skin near a hull), the others' distances left: what a push, a projection or the take-back moved */
static void measure_listed(const double *p, const int32_t *list, int n, const double *ca, const double *cb,
                           const double *radii, int C, const SkinPose *sk, double margin, double *d, double *nrm)
{
    sdf_points(p, list, n, ca, cb, radii, C, d, nrm);
    skin_refine(sk, p, list, n, margin, d, nrm);
}

/* The fraction of the V distances d deeper than `depth` into *out, by one thread of the team (the
   others read it after the single's barrier): a report's before or after */
static void deep_fraction(const double *d, int V, double depth, double *out)
{
    #pragma omp single
    {
        int deep = 0;
        for (int v = 0; v < V; ++v) deep += d[v] < -depth;
        *out = (double)deep / V;
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
   distances (measure_frame; `measured`: d and nrm, buf's first 4 V doubles, hold them already);
   `rounds` times: each vertex needing to move (within `margin` of the
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
    if (!measured) measure_frame(p, V, ca, cb, radii, C, sk, m, margin, d, nrm);
    deep_fraction(d, V, depth, before);
    #pragma omp single
    flag[1] = flag[3] = flag[4] = 0;
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
            measure_listed(p, list, flag[1], ca, cb, radii, C, sk, margin, d, nrm);
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
        measure_listed(p, list, n, ca, cb, radii, C, sk, margin, d, nrm);
    }
    deep_fraction(d, V, depth, after);
    #pragma omp single
    for (int k = 0; k < flag[3]; ++k) vmark[moved[k]] = 0;
}
