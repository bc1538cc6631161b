/* mesh_probe.c: which points lie inside a closed triangle mesh, and which lie within a distance of it,
   for frames of a posed mesh, on the push-out's columns (skin_sdf.c: skin_columns, skin_column_walk).
   hrr_garment/body/mesh_inside.py is the reference (its numpy count of a ray's crossings, a few
   milliseconds a frame; this, about a thirtieth of that) and hrr_garment/native/mesh_probe.py the
   ctypes glue. hrr-eval measures every held-out frame's cloth against the body the viewer sees with
   it, and a garment's dressing its clearance from the body's mesh. */

#include "hrr_native.h"

/* Point x against one frame's columns: its winding number (the signed crossings of its ray along +x)
   and whether a face lies within the margin of it. Beyond the columns, or before or past every box of
   its column along x, nothing is within the margin and the ray's crossings past x sum to 0 (a closed
   mesh's line crosses in and out alike); a NaN point is neither inside nor near. */
static void mesh_probe_point(const SkinPose *sk, double margin, const double *x, int32_t *winding, uint8_t *near)
{
    *winding = 0, *near = 0;
    const long col = skin_column_of(sk, x);
    if (col < 0 || x[0] < sk->col_reach[2 * col] || x[0] > sk->col_reach[2 * col + 1]) return;
    int close;
    *winding = skin_column_walk(sk, margin, x, col, 0, &close);
    *near = (uint8_t)close;
}

/* T frames of a closed mesh (faces (F, 3) of V vertices, posed (T, V, 3)) and of N points each
   (points (T, N, 3); where (T, N), NULL: every point): winding (T, N), each point's winding number,
   and near (T, N), 1 where a face lies within `margin` of it; a point `where` leaves out gets 0 and
   0. The columns are `cell` wide. Frames in parallel. Returns 0 where a frame's columns could not be
   built (no memory, a vertex not finite, or a mesh over a thousand cells across): the caller measures
   those frames itself. */
int hrr_mesh_probe(const int32_t *faces, int F, int V, int T, const double *posed, int N, const double *points,
                   const uint8_t *where, double margin, double cell, int32_t *winding, uint8_t *near, int threads)
{
    int ok = 1;
    #pragma omp parallel num_threads(threads) reduction(min : ok)
    {
        SkinColumns c = {0};
        const SkinGrid g = {.faces = faces, .F = F, .V = V};
        #pragma omp for schedule(dynamic)
        for (int t = 0; t < T; t++) {
            const double *frame = posed + (size_t)t * 3 * V;
            SkinPose sk = {.grid = &g, .posed = frame, .cell = cell};
            skin_columns(&g, frame, margin, cell, &c, &sk);
            if (!sk.col_start) {
                ok = 0;
                continue;
            }
            for (int i = 0; i < N; i++) {
                const size_t k = (size_t)t * N + i;
                if (where && !where[k]) {
                    winding[k] = 0, near[k] = 0;
                    continue;
                }
                mesh_probe_point(&sk, margin, points + 3 * k, winding + k, near + k);
            }
        }
        skin_columns_free(&c);
    }
    return ok;
}
