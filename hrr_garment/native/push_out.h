/* push_out.h: what the push-out's sources share (push_frame.c, strain_limit.c, subspace_push.c,
   push_out.c, compiled in the one translation unit with the others: hrr_native.h): the settings and
   scratch they pass, and the static functions one of them defines and another calls, declared here
   instead of relying on the order of concatenation. Include guard: each of them includes it. */

#ifndef HRR_PUSH_OUT_H
#define HRR_PUSH_OUT_H

#include "hrr_native.h"

enum { SDF_CHUNK = 256, SDF_MAXC = 64 };  /* sdf_soa's points a call (push_frame.c), capsules a body at most */

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

/* One frame's scratch for the strain limit: the limits of the edges measured (E doubles; known
   where lmark is set), the edges found over their limit (active, E ints), each colour's edges to
   measure (bucket: E ints, colour c's from colour_ptr[c], count[c] of them), emark (E bytes: listed
   in a bucket), lmark (E bytes), carved from one block. */
typedef struct {
    double *limit;
    int32_t *active, *bucket, *count;
    unsigned char *emark, *lmark;
} LimitScratch;

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

/* Against the skin (sk not NULL) the capsules are its hulls, each covering its piece of the posed
   mesh (hrr_garment/body/skin_envelope.py), so the skin lies inside their union and a vertex farther
   than the margin from every hull is farther than that from the skin: its hull distance stands (all
   the push reads of it is that it needs no push). The others, within the margin of a hull or inside
   one, are measured against the skin itself (skin_point, ~3 us), but for those the frame's broad
   phase shows farther than the margin from the skin and outside it (skin_far_by_column: its
   column's triangles and a ray; most of a garment inside the hulls, which hold the skin
   loosely): FAR_AWAY, as a patch no capsule comes near. */
static inline void skin_measure(const SkinPose *sk, double margin, const double *x, double *d, double *nrm)
{
    if (sk->col_start && skin_far_by_column(sk, margin, x)) {
        *d = FAR_AWAY;
        nrm[0] = nrm[1] = nrm[2] = 0.0;
    } else {
        skin_point(sk->grid, sk->rot, sk->trans, sk->posed, x, d, nrm);
    }
}

/* push_frame.c */
static void sdf_soa(const double *px, const double *py, const double *pz, const int32_t *idx, int i0, int n,
                    const double *ca, const double *cb, const double *radii, int C, double *dist, double *normal);
static void measure_frame(const double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                          const SkinPose *sk, const PushMesh *m, double margin, double *d, double *nrm);
static void measure_listed(const double *p, const int32_t *list, int n, const double *ca, const double *cb,
                           const double *radii, int C, const SkinPose *sk, double margin, double *d, double *nrm);
static void deep_fraction(const double *d, int V, double depth, double *out);
static void push_frame(double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                       const SkinPose *sk, const PushMesh *m, double margin, int smooth, int rounds, double depth, int measured,
                       double *before, double *after, double *buf, int32_t *ints, int *flag);
/* strain_limit.c */
static size_t limit_scratch_bytes(int E);
static LimitScratch limit_scratch(unsigned char *block, int E);
static int limit_one(double *p, const double *u, int V, const StrainArgs *s, const int32_t *moved, int n_moved,
                     LimitScratch *w);
/* subspace_push.c */
static void subspace_push(double *p, int V, const double *ca, const double *cb, const double *radii, int C,
                          const SkinPose *sk, const PushMesh *m, double margin, const SubspaceArgs *sp, const double *turn,
                          PushTeam *team);
static double *batched_subspace(const void *in, int in_double, int T, int V, const double *a, const double *b,
                                const double *radii, int C, int radii_step, const PushMesh *m, const PushArgs *args,
                                const SubspaceArgs *sp, const double *turn, int teams, PushTeam *team);

#endif
