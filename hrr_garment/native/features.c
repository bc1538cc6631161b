/* Forward kinematics and causal motion features in C, compiled with the other kernels by
   hrr_garment/native/__init__.py and called through it from hrr_garment/motion/ (motion.py, features.py). The numpy
   forms (motion/skeleton.py forward_kinematics, motion/features.py motion_features,
   motion/rotations.py matrix_to_axis_angle) are the reference: the same formulas in the same
   order, in double precision, tested equal. Why: a stream computes one pose's kinematics and
   features per frame, about 50 small numpy calls (0.6-1 ms) for some microseconds of arithmetic. */

#include "hrr_native.h"

/* T frames of J joints: local rotations (T, J, 3, 3) float32, root positions (T, 3), bone
   offsets (J, 3), parents (J, -1 for the root) -> global rotations (T, J, 3, 3), positions (T, J, 3). */
void hrr_forward_kinematics(const float *local, const double *root, int T, int J, const double *offsets,
                            const int32_t *parents, double *g_rot, double *g_pos)
{
    for (int t = 0; t < T; ++t)
        for (int j = 0; j < J; ++j) {
            const float *l = local + ((size_t)t * J + j) * 9;
            double *g = g_rot + ((size_t)t * J + j) * 9, *p = g_pos + ((size_t)t * J + j) * 3;
            const int par = parents[j];
            if (par < 0) {
                for (int k = 0; k < 9; ++k) g[k] = l[k];
                for (int k = 0; k < 3; ++k) p[k] = root[(size_t)t * 3 + k];
                continue;
            }
            const double *gp = g_rot + ((size_t)t * J + par) * 9, *pp = g_pos + ((size_t)t * J + par) * 3;
            const double *o = offsets + (size_t)j * 3;
            for (int r = 0; r < 3; ++r) {
                for (int c = 0; c < 3; ++c)
                    g[r * 3 + c] = gp[r * 3] * l[c] + gp[r * 3 + 1] * l[3 + c] + gp[r * 3 + 2] * l[6 + c];
                p[r] = pp[r] + (gp[r * 3] * o[0] + gp[r * 3 + 1] * o[1] + gp[r * 3 + 2] * o[2]);
            }
        }
}

static void normalize4(double *q)
{
    const double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (n > 1e-8)
        for (int k = 0; k < 4; ++k) q[k] /= n;
}

/* rotations.matrix_to_axis_angle: Shepperd's quaternion (the candidate with the largest
   denominator), w >= 0, then axis times angle. */
static void matrix_to_axis_angle(const double *m, double *aa)
{
    const double m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5], m20 = m[6], m21 = m[7],
                 m22 = m[8];
    const double four[4] = {1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22};
    double q_abs[4];
    int best = 0;
    for (int k = 0; k < 4; ++k) {
        q_abs[k] = sqrt(four[k] > 1e-12 ? four[k] : 1e-12);
        best = q_abs[k] > q_abs[best] ? k : best;
    }
    const double rows[4][4] = {{q_abs[0] * q_abs[0], m21 - m12, m02 - m20, m10 - m01},
                               {m21 - m12, q_abs[1] * q_abs[1], m10 + m01, m02 + m20},
                               {m02 - m20, m10 + m01, q_abs[2] * q_abs[2], m12 + m21},
                               {m10 - m01, m20 + m02, m21 + m12, q_abs[3] * q_abs[3]}};
    double q[4];
    for (int k = 0; k < 4; ++k) q[k] = rows[best][k] / (2.0 * q_abs[best]);
    normalize4(q);
    if (q[0] < 0)
        for (int k = 0; k < 4; ++k) q[k] = -q[k];
    normalize4(q);  /* quat_to_axis_angle normalises again */
    const double s = sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    const double angle = 2.0 * atan2(s, q[0]);
    const double ratio = s < 1e-6 ? 2.0 / q[0] : angle / s;
    for (int k = 0; k < 3; ++k) aa[k] = q[k + 1] * ratio;
}

/* features.motion_features of frames t = 0 .. T-1 from frames t - 1 and t (frame 0 from itself:
   zero velocities), as a stream sees them: global rotations (T, J, 3, 3), positions (T, J, 3),
   the F feature joints' indices -> (T, 6 F + 4) float32 [rotations, velocities, root velocity,
   yaw rate] in the heading frame at t. */
void hrr_causal_features(const double *g_rot, const double *g_pos, int T, int J, const int32_t *joints, int F,
                         double fps, float *out)
{
    const int width = 6 * F + 4;
    double prev_yaw = 0.0;
    for (int t = 0; t < T; ++t) {
        const int before = t ? t - 1 : 0;
        const double *pelvis = g_rot + (size_t)t * J * 9;
        const double yaw = atan2(pelvis[2], pelvis[8]);  /* rotations.yaw_of: the forward axis's column */
        const double c = cos(yaw), s = sin(yaw);
        /* heading rotation h = rotation_about_y(yaw) = [[c, 0, s], [0, 1, 0], [-s, 0, c]]; world -> heading is h^T */
        const double ht[9] = {c, 0.0, -s, 0.0, 1.0, 0.0, s, 0.0, c};
        float *f = out + (size_t)t * width;
        for (int k = 0; k < F; ++k) {
            const double *g = g_rot + ((size_t)t * J + joints[k]) * 9;
            double local[9], aa[3];
            for (int r = 0; r < 3; ++r)
                for (int cc = 0; cc < 3; ++cc)
                    local[r * 3 + cc] = ht[r * 3] * g[cc] + ht[r * 3 + 1] * g[3 + cc] + ht[r * 3 + 2] * g[6 + cc];
            matrix_to_axis_angle(local, aa);
            const double *p = g_pos + ((size_t)t * J + joints[k]) * 3, *q = g_pos + ((size_t)before * J + joints[k]) * 3;
            const double d[3] = {(p[0] - q[0]) * fps, (p[1] - q[1]) * fps, (p[2] - q[2]) * fps};
            for (int r = 0; r < 3; ++r) {
                f[3 * k + r] = (float)aa[r];
                f[3 * F + 3 * k + r] = (float)(ht[r * 3] * d[0] + ht[r * 3 + 1] * d[1] + ht[r * 3 + 2] * d[2]);
            }
        }
        const double *p = g_pos + (size_t)t * J * 3, *q = g_pos + (size_t)before * J * 3;
        const double d[3] = {(p[0] - q[0]) * fps, (p[1] - q[1]) * fps, (p[2] - q[2]) * fps};
        for (int r = 0; r < 3; ++r)
            f[6 * F + r] = (float)(ht[r * 3] * d[0] + ht[r * 3 + 1] * d[1] + ht[r * 3 + 2] * d[2]);
        const double step = t ? yaw - prev_yaw : 0.0;
        f[6 * F + 3] = (float)(atan2(sin(step), cos(step)) * fps);  /* wrapped to (-pi, pi] */
        prev_yaw = yaw;
    }
}

/* Body-frame points to world, as float32 (motion/frame.py world_vertices; from_body_frame is the
   reference): p (T, N, 3) float32, turn (T, 2) the cosine and sine of each frame's yaw, origin
   (T, 3) -> out (T, N, 3), in double like the numpy form. Why: a 32-character crowd's 133
   thousand vertices took 1.8 ms through numpy's strided temporaries. Frames in parallel. */
void hrr_body_to_world(const float *p, int T, int N, const double *turn, const double *origin, int threads, float *out)
{
    #pragma omp parallel for num_threads(threads) schedule(static) if (T > 1 && (long)T * N > 65536)
    for (int t = 0; t < T; ++t) {
        const double c = turn[2 * t], s = turn[2 * t + 1], ox = origin[3 * t], oy = origin[3 * t + 1], oz = origin[3 * t + 2];
        const float *q = p + (size_t)t * N * 3;
        float *o = out + (size_t)t * N * 3;
        for (int n = 0; n < N; ++n) {
            const double x = q[3 * n], y = q[3 * n + 1], z = q[3 * n + 2];
            o[3 * n] = (float)(c * x + s * z + ox);
            o[3 * n + 1] = (float)(y + oy);
            o[3 * n + 2] = (float)(c * z - s * x + oz);
        }
    }
}
