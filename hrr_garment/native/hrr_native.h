/* hrr_native.h: what the C sources of hrr_garment/native/ share. They are compiled together as one
   translation unit (in hrr_garment/native/build.py's SOURCES order), so helpers stay static and
   inline across files; this header declares the ones defined in kernels.c that amx_block.c and
   window_codes.c use, and the skin collider of skin_sdf.c, which the push-out (push_frame.c,
   push_out.c; their own header: push_out.h) reads, instead of relying on the order of
   concatenation. Include guard: every source includes it. */

#ifndef HRR_NATIVE_H
#define HRR_NATIVE_H

#ifndef _GNU_SOURCE
#define _GNU_SOURCE /* sched_getcpu and the CPU_* affinity macros (hrr_pin_workers) */
#endif
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <omp.h>

#define ALWAYS_INLINE static inline __attribute__((always_inline))

/* Denormal floats read and produced as zero (flush-to-zero and denormals-are-zero) in the calling
   thread, restored afterwards: trained weights and activations hold some, and every product with
   one takes a slow microcode path. Set in each worker thread, which PyTorch's setting misses. */
#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
ALWAYS_INLINE unsigned denormals_off(void) { const unsigned old = _mm_getcsr(); _mm_setcsr(old | 0x8040); return old; }
ALWAYS_INLINE void denormals_restore(unsigned old) { _mm_setcsr(old); }
#else
ALWAYS_INLINE unsigned denormals_off(void) { return 0; }
ALWAYS_INLINE void denormals_restore(unsigned old) { (void)old; }
#endif

/* How many floats the vector registers hold decides how large a register tile may be: AVX-512 has 32
   registers of 16 floats, AVX2 (AMD Zen 1-3 and most desktop Intel parts) 16 of 8. A tile sized
   for the first (a 5 x 64 dense tile, 16 conv rows of 16 floats) spills on the second: the decoder
   ran 7x slower on a Zen AVX2 machine than it needed to. */
#if defined(__AVX512F__)
#define WIDE_REGISTERS 1
#else
#define WIDE_REGISTERS 0
#endif

typedef float v8sf __attribute__((vector_size(32)));
typedef float v16sf __attribute__((vector_size(64)));

/* exp(y) for y <= 0, vectorisable (kernels.c) */
ALWAYS_INLINE float exp_nonpositive(float y);

/* The register-tiled dense product (kernels.c): weights in panels of PANEL columns, tiles by rows
   (5 or 1) and 16-column vectors (1 to 4). */
enum { PANEL = 64 };
typedef void (*tile_fn)(const float *restrict, int, const float *restrict, const float *restrict, float *restrict,
                        int, int);
static const tile_fn TILES[2][4];

/* The skin collider's grid (skin_sdf.c; hrr_garment/native/skin.py builds it) and one frame of it
   posed, as the push-out reads it: the joints' moves and the mesh skinned
   (hrr_skin_pose). */
#define SKIN_MAX_STARTS 8
#define SKIN_TOP 4 /* skin weights per node (TOP_JOINTS) */

/* one node of the rest grid, in one cache line's half: a point's 22 rigid guesses and its fixed-point
   steps read nodes all over the grid (3.5 MB for an anny body), so each read is one line, not three */
typedef struct {
    float distance;            /* the rest mesh's signed distance */
    float weights[SKIN_TOP];   /* the nearest skin's four largest weights */
    uint8_t joints[SKIN_TOP];  /* and their joints */
    int32_t pad[2];
} SkinNode;

typedef struct {
    const SkinNode *nodes;     /* x-major */
    const int32_t *face_start; /* (nodes + 1,) */
    const int32_t *face_list;
    const int32_t *faces;         /* (F, 3) */
    const int32_t *neighbours;    /* (F, 3) the face across each edge (pseudo_normals.edge_neighbours) */
    const int32_t *corner_start;  /* (V + 1,) each vertex's first entry in corner_list */
    const int32_t *corner_list;   /* its corners, 3 f + k: face f's corner k */
    const double *rest;           /* (V, 3) the rest mesh */
    const int32_t *vertex_joints; /* (V, vertex_k) each vertex's joints, padded with weight 0 */
    const double *vertex_weights; /* (V, vertex_k) */
    int shape[3], V, F, J, vertex_k, starts, iterations;
    double origin[3], voxel, step, settled, deep, off_skin, face_side;
} SkinGrid;

typedef struct {
    const SkinGrid *grid;
    const double *rot, *trans;     /* (J, 3, 3), (J, 3) the joints' moves from the rest pose */
    const double *posed;           /* (V, 3) the mesh posed by them */
    /* the broad phase's column width (skin_columns, which the push-out runs on the frame first, in its
       own copy of the struct; 0: none, every point near a hull is measured: an open mesh) */
    double cell;
    int measure_after; /* the push-out measures a frame the strain limit moved again, for its report */
    /* the frame's columns (skin_columns; col_start NULL: not built): (ny nz + 1) starts, the faces
       listed, each face's record (SKIN_FACE doubles), each column's reach along x (2 doubles), the
       columns' first corner in (y, z) */
    const int32_t *col_start, *col_list;
    const double *col_face, *col_reach;
    int ny, nz;
    double y0, z0;
} SkinPose;

/* A face's record in the columns: its box grown by the margin (lo, hi), then its three corners */
enum { SKIN_FACE = 16 };

/* The columns' arrays, each grown as a frame needs (a team's, kept over its frames, freed by the
   push-out) */
typedef struct {
    int32_t *start, *list;
    double *face, *reach;
    size_t start_cap, list_cap, face_cap, reach_cap;
} SkinColumns;

static void skin_columns(const SkinGrid *g, const double *posed, double margin, double cell, SkinColumns *c,
                         SkinPose *sk);
static void skin_columns_free(SkinColumns *c);
static int skin_far_by_column(const SkinPose *sk, double margin, const double *x);

/* The signed distance and outward normal of point x to the posed skin (skin_sdf.c) */
static void skin_point(const SkinGrid *g, const double *rot, const double *trans, const double *posed,
                       const double *x, double *distance, double *normal);
void hrr_skin_cells(const SkinGrid *g, const double *posed, double margin, double cell, const double *origin,
                    const int *dims, uint8_t *cells);

#endif
