/* The code space's window step in C (hrr_garment/models/native_codes.py): for each motion window,
   the motion encoder (input layer, GRU, self-attention with layer norm, attention pooling, output
   layer norm and logits), the grouped code (per-group entropy, argmax, the chosen classes'
   embeddings) and the code-space decoder's MLP. Compiled with kernels.c (one library), whose
   dense tiles, exp_nonpositive and denormal helpers it uses (declared in hrr_native.h).

   Why: a stream runs this for one window per frame, and PyTorch spends most of that time between
   operations (about 190 small operator calls, 1.6-3 ms) on 15 MFLOP of arithmetic.

   Threads: window_codes shares its work among the threads of the innermost parallel region
   (orphaned worksharing: dense tiles, rows, heads and groups) and runs a batch of windows in
   lockstep, each layer once for all of them. Every value is computed by one thread in one fixed
   order, the same for a window alone or in a batch, so a stream and an offline causal batch give
   the same bits. */

#include "hrr_native.h"

ALWAYS_INLINE float elu1(float y) { return y > 0.0f ? y : exp_nonpositive(y) - 1.0f; }

ALWAYS_INLINE float sigmoid(float y)
{
    const float e = exp_nonpositive(y > 0.0f ? -y : y);  /* exp(-|y|) */
    return y > 0.0f ? 1.0f / (1.0f + e) : e / (1.0f + e);
}

ALWAYS_INLINE float tanh_(float y)
{
    const float e = exp_nonpositive(y > 0.0f ? -2.0f * y : 2.0f * y);  /* exp(-2|y|) */
    const float m = (1.0f - e) / (1.0f + e);
    return y > 0.0f ? m : -m;
}

/* linear_rows (kernels.c) with its tiles shared among the team: panel-major, so each thread
   streams its own part of the weights. Ends with the team's barrier. */
static void linear_shared(const float *restrict X, int n, int in, const float *restrict Wp, const float *restrict b,
                          int out, float *restrict Y)
{
    const int panels = (out + PANEL - 1) / PANEL, blocks = n / 5 + n % 5;  /* blocks of 5 rows, then single rows */
    #pragma omp for schedule(static)
    for (int k = 0; k < panels * blocks; ++k) {
        const int o = (k / blocks) * PANEL, r = k % blocks;
        const int t = r < n / 5 ? 5 * r : 5 * (n / 5) + (r - n / 5), rows = r < n / 5 ? 5 : 1;
        const int cols = out - o < PANEL ? out - o : PANEL;
        TILES[rows == 5][(cols + 15) / 16 - 1](X + (size_t)t * in, in, Wp + (size_t)o * in, b + o, Y + (size_t)t * out + o,
                                               out, cols);
    }
}

static void elu_shared(float *x, int n)
{
    #pragma omp for simd schedule(static)
    for (int i = 0; i < n; ++i) x[i] = elu1(x[i]);
}

/* Row-wise layer norm of X (n, H) in place (biased variance, as PyTorch), rows shared. */
static void layer_norm(float *X, int n, int H, const float *w, const float *b, float eps)
{
    #pragma omp for schedule(static)
    for (int t = 0; t < n; ++t) {
        float *x = X + (size_t)t * H;
        float mean = 0.0f, var = 0.0f;
        for (int i = 0; i < H; ++i) mean += x[i];
        mean /= (float)H;
        for (int i = 0; i < H; ++i) var += (x[i] - mean) * (x[i] - mean);
        const float inv = 1.0f / sqrtf(var / (float)H + eps);
        for (int i = 0; i < H; ++i) x[i] = (x[i] - mean) * inv * w[i] + b[i];
    }
}

/* Multi-head attention core over several windows: window w's out (nq, H) = per head
   softmax(q k^T / sqrt(d)) v, with q rows of stride qs starting at q + w * q_step, k and v rows of
   stride kvs starting at k, v + w * kv_step, out rows at out + w * out_step; scores_all holds
   windows x nq x heads x nk floats. (window, row, head) triples shared. */
static void attend(const float *q, int nq, int qs, const float *k, const float *v, int nk, int kvs, int H, int heads,
                   float *scores_all, float *out, int windows, long q_step, long kv_step, long out_step)
{
    const int d = H / heads;
    const float scale = 1.0f / sqrtf((float)d);
    #pragma omp for schedule(static)
    for (long job = 0; job < (long)windows * nq * heads; ++job) {
        const long w = job / ((long)nq * heads);
        const int t = (int)(job / heads % nq), h = (int)(job % heads);
        const float *qh = q + w * q_step + (size_t)t * qs + h * d, *kw = k + w * kv_step, *vw = v + w * kv_step;
        float *scores = scores_all + (size_t)job * nk, top = -INFINITY, sum = 0.0f;
        for (int s = 0; s < nk; ++s) {
            const float *kh = kw + (size_t)s * kvs + h * d;
            float dot = 0.0f;
            #pragma omp simd reduction(+:dot)
            for (int i = 0; i < d; ++i) dot += qh[i] * kh[i];
            scores[s] = dot * scale;
            top = scores[s] > top ? scores[s] : top;
        }
        for (int s = 0; s < nk; ++s) sum += (scores[s] = exp_nonpositive(scores[s] - top));
        float *o = out + w * out_step + (size_t)t * H + h * d;
        for (int i = 0; i < d; ++i) o[i] = 0.0f;
        for (int s = 0; s < nk; ++s) {
            const float p = scores[s] / sum, *vh = vw + (size_t)s * kvs + h * d;
            #pragma omp simd
            for (int i = 0; i < d; ++i) o[i] += p * vh[i];
        }
    }
}

enum { P_INP_W, P_INP_B, P_IH_W, P_IH_B, P_HH_W, P_HH_B, P_ATT_IN_W, P_ATT_IN_B, P_ATT_OUT_W, P_ATT_OUT_B, P_NORM_W,
       P_NORM_B, P_QUERY, P_POOL_Q_W, P_POOL_Q_B, P_POOL_KV_W, P_POOL_KV_B, P_POOL_OUT_W, P_POOL_OUT_B, P_OUT_NORM_W, P_OUT_NORM_B, P_OUT_W,
       P_OUT_B, P_EMBEDDING, P_EPS, P_DECODER };

/* The GRU's input side of n frames (n, F) -> gates (n, 3H): its input gates ih(elu(inp(x))), a
   function of the frame alone, so a window sliding by one frame needs only its new frame's
   (hrr_frame_gates). a: n x H scratch. A row's bits do not depend on the other rows. */
static void frame_gates(const float *x, int n, int F, int H, const float *const *p, float *a, float *gates)
{
    linear_shared(x, n, F, p[P_INP_W], p[P_INP_B], H, a);
    elu_shared(a, n * H);
    linear_shared(a, n, H, p[P_IH_W], p[P_IH_B], 3 * H, gates);
}

/* The widest input of the decoder's layers (the embedding with the body's and cloth's values, or a hidden layer). */
static long decoder_widest(const int32_t *dims)
{
    long widest = dims[8];
    for (int l = 1; l < dims[7]; ++l) widest = dims[8 + l] > widest ? dims[8 + l] : widest;
    return widest;
}

/* dims: F, W, H, heads, G, K, D, L, then the decoder's L + 1 layer sizes (G * D + nb first), then 1
   where the regression decodes the expected embedding (the mean over each group's softmax), 0
   where it decodes the argmax class's, then nb: how many condition values (the body's measures, then
   the cloth's values) the decoder reads beside the embedding (a model trained across bodies or
   cloths: the last nb features of each window's last frame);
   params: the pointers in the order of the enum above, then L (weight, bias) pairs; every weight
   packed in panels (see linear_rows), the pooling's in-projection split into its query and
   key-value parts; eps holds the two layer norms' epsilons. B windows in lockstep: x (B, W, F)
   standardised features -> entropy (B, mean over groups, nats), argmax (B, G) and, unless latents
   is NULL, the decoder's output (B, last layer size). Every layer runs once for all B windows
   (the GRU one step for all of them at a time), so each weight panel is read once per five rows
   rather than once per window: a crowd's 32 windows read the 7 MB of weights about seven times,
   not 32. A row's value does not depend on the other rows (the tiles keep one accumulator chain
   per row), so a window gives the same bits alone or in a batch. gates (B, W, 3H), or NULL: the
   frames' input gates (frame_gates) where the caller kept them, so that only the GRU's recurrent
   side and what follows run here; x is then (B, 1, F), each window's last frame only (all that is
   read of it: the body's measures). Called by
   every thread of the innermost parallel region, with the same (shared) arguments; work:
   window_codes_work floats. */
static void window_codes(const float *x, const float *gates, int B, const int32_t *dims, const float *const *p, float *work,
                         float *entropy, int64_t *argmax, float *latents)
{
    const int F = dims[0], W = dims[1], H = dims[2], heads = dims[3], G = dims[4], K = dims[5], D = dims[6],
              L = dims[7];
    const int32_t *sizes = dims + 8;
    const int expected = dims[9 + L];  /* the regression decodes the expected embedding, else the argmax's */
    const int nb = dims[10 + L];  /* body and cloth values after the embedding in the decoder's input */
    const long BW = (long)B * W, widest = decoder_widest(dims);
    const int x_frames = gates ? 1 : W;  /* frames of x per window: with the gates, its last only */
    float *a = work, *gi = a + BW * H, *hs = gi + BW * 3 * H, *gh = hs + BW * H, *state = gh + (long)B * 3 * H,
          *qkv = state + 2L * B * H, *att = qkv + BW * 3 * H, *scores = att + BW * H, *q = scores + BW * W * heads,
          *pooled = q + H, *logits = pooled + (long)B * H, *group_entropy = logits + (long)B * G * K,
          *h0 = group_entropy + (long)B * G, *spare = h0 + B * widest;

    if (gates) gi = (float *)gates;  /* the frames' input gates, computed as they came (read only below) */
    else frame_gates(x, (int)BW, F, H, p, a, gi);  /* input side of every step at once */
    for (int t = 0; t < W; ++t) {  /* one GRU step for every window; rows of hs: window-major */
        const float *prev = t ? state + (long)((t - 1) % 2) * B * H : NULL;
        float *cur = state + (long)(t % 2) * B * H;
        if (prev) linear_shared(prev, B, H, p[P_HH_W], p[P_HH_B], 3 * H, gh);
        else {
            #pragma omp single
            for (int b = 0; b < B; ++b) memcpy(gh + (long)b * 3 * H, p[P_HH_B], sizeof(float) * 3 * H);  /* h_0 = 0 */
        }
        #pragma omp for schedule(static)
        for (long b = 0; b < B; ++b) {  /* by window, each window's H gates in vectors (scalar: 1.2 of 4.5 ms) */
            const float *restrict g = gi + (b * W + t) * 3 * H, *restrict gg = gh + b * 3 * H;
            const float *restrict before = prev ? prev + b * H : NULL;
            float *restrict now = cur + b * H, *restrict out = hs + (b * W + t) * H;
            #pragma omp simd
            for (int i = 0; i < H; ++i) {
                const float r = sigmoid(g[i] + gg[i]), z = sigmoid(g[H + i] + gg[H + i]);
                const float n = tanh_(g[2 * H + i] + r * gg[2 * H + i]);
                now[i] = out[i] = (1.0f - z) * n + z * (before ? before[i] : 0.0f);
            }
        }
    }
    /* self-attention over each window's GRU states, residual, layer norm */
    linear_shared(hs, (int)BW, H, p[P_ATT_IN_W], p[P_ATT_IN_B], 3 * H, qkv);
    attend(qkv, W, 3 * H, qkv + H, qkv + 2 * H, W, 3 * H, H, heads, scores, att, B, (long)W * 3 * H, (long)W * 3 * H,
           (long)W * H);
    linear_shared(att, (int)BW, H, p[P_ATT_OUT_W], p[P_ATT_OUT_B], H, a);
    #pragma omp for schedule(static)
    for (long i = 0; i < BW * H; ++i) a[i] += hs[i];
    layer_norm(a, (int)BW, H, p[P_NORM_W], p[P_NORM_B], p[P_EPS][0]);
    /* attention pooling with the learned query (keys and values into qkv's first 2H columns) */
    linear_shared(p[P_QUERY], 1, H, p[P_POOL_Q_W], p[P_POOL_Q_B], H, q);
    linear_shared(a, (int)BW, H, p[P_POOL_KV_W], p[P_POOL_KV_B], 2 * H, qkv);
    attend(q, 1, H, qkv, qkv + H, W, 2 * H, H, heads, scores, att, B, 0, (long)W * 2 * H, H);
    linear_shared(att, B, H, p[P_POOL_OUT_W], p[P_POOL_OUT_B], H, pooled);
    layer_norm(pooled, B, H, p[P_OUT_NORM_W], p[P_OUT_NORM_B], p[P_EPS][1]);
    linear_shared(pooled, B, H, p[P_OUT_W], p[P_OUT_B], G * K, logits);
    /* per window and group: entropy of the softmax, first argmax, the regression's embedding */
    #pragma omp for schedule(static)
    for (long j = 0; j < (long)B * G; ++j) {
        const int g = (int)(j % G);
        const float *l = logits + j * K;
        int best = 0;
        for (int k = 1; k < K; ++k) best = l[k] > l[best] ? k : best;
        float sum = 0.0f, weighted = 0.0f;
        for (int k = 0; k < K; ++k) {
            const float e = exp_nonpositive(l[k] - l[best]);
            sum += e;
            weighted += e * (l[k] - l[best]);
        }
        group_entropy[j] = logf(sum) - weighted / sum;  /* -sum p log p, p = e / sum */
        argmax[j] = best;
        const float *embedding = p[P_EMBEDDING] + (size_t)g * K * D;
        float *row = h0 + (j / G) * sizes[0] + (long)g * D;
        if (expected) {  /* the embedding averaged over the group's softmax */
            for (int d = 0; d < D; ++d) row[d] = 0.0f;
            for (int k = 0; k < K; ++k) {
                const float weight = exp_nonpositive(l[k] - l[best]) / sum;
                for (int d = 0; d < D; ++d) row[d] += weight * embedding[(size_t)k * D + d];
            }
        } else {
            memcpy(row, embedding + (size_t)best * D, sizeof(float) * D);
        }
    }
    #pragma omp for schedule(static)
    for (int b = 0; b < B; ++b) {
        float total = 0.0f;  /* in group order, whatever the threads */
        for (int g = 0; g < G; ++g) total += group_entropy[(long)b * G + g];
        entropy[b] = total / (float)G;
    }
    if (!latents) return;
    if (nb) {  /* the body's and the cloth's values after each window's embedding */
        #pragma omp for schedule(static)
        for (int b = 0; b < B; ++b)
            memcpy(h0 + (long)b * sizes[0] + (long)G * D, x + ((long)b * x_frames + x_frames - 1) * F + F - nb,
                   sizeof(float) * nb);
    }
    float *in = h0;  /* (B, G * D + nb); h0 and spare hold B rows of the widest layer each */
    for (int l = 0; l < L; ++l) {
        float *y = l == L - 1 ? latents : spare;
        linear_shared(in, B, sizes[l], p[P_DECODER + 2 * l], p[P_DECODER + 2 * l + 1], sizes[l + 1], y);
        if (l < L - 1) {
            elu_shared(y, B * sizes[l + 1]);
            spare = in;
            in = y;
        }
    }
}

enum { LOCKSTEP = 64 };  /* windows per lockstep pass: bounds the scratch memory of a long clip */

/* Scratch floats window_codes needs for B windows of these dims. */
static long window_codes_work(const int32_t *dims, long B)
{
    const long W = dims[1], H = dims[2], heads = dims[3], G = dims[4], K = dims[5];
    return B * (W * H * 9 + 3 * H + 2 * H + W * W * heads + H + G * K + G + 2 * decoder_widest(dims)) + H;
}

/* Scratch floats hrr_window_codes allocates for one pass (diagnostics). */
long hrr_window_codes_work(const int32_t *dims) { return window_codes_work(dims, LOCKSTEP); }

/* n standardised frames (n, F) -> their GRU input gates (n, 3H), the bits window_codes computes for
   them inside any window. Returns 0, or -1 where scratch memory could not be allocated. */
int hrr_frame_gates(const float *x, int n, const int32_t *dims, const float *const *params, int threads, float *gates)
{
    const int F = dims[0], H = dims[2];
    if (n <= 0) return 0;
    float *scratch = malloc(sizeof(float) * (size_t)n * H);
    if (!scratch) return -1;
    #pragma omp parallel num_threads(threads)
    {
        const unsigned csr = denormals_off();
        frame_gates(x, n, F, H, params, scratch, gates);
        denormals_restore(csr);
    }
    free(scratch);
    return 0;
}

/* B windows (B, W, F) and their frames' gates (B, W, 3H) or NULL (with gates, x is each window's
   last frame only: (B, 1, F)) -> entropy (B), argmax (B, G),
   latents (B, last layer size) or NULL, in lockstep passes of up to LOCKSTEP windows, the team
   sharing each pass. Returns 0, or -1 where scratch memory could not be allocated. */
int hrr_window_codes(const float *x, const float *gates, int B, const int32_t *dims, const float *const *params,
                     int threads, float *entropy, int64_t *argmax, float *latents)
{
    const int F = dims[0], W = dims[1], H = dims[2], G = dims[4], L = dims[7], x_frames = gates ? 1 : W;
    const long out = dims[8 + L];
    if (B <= 0) return 0;
    float *scratch = malloc(sizeof(float) * (size_t)window_codes_work(dims, B < LOCKSTEP ? B : LOCKSTEP));
    if (!scratch) return -1;
    #pragma omp parallel num_threads(threads)
    {
        const unsigned csr = denormals_off();
        for (int b = 0; b < B; b += LOCKSTEP) {  /* every thread takes every pass; the layers share out the work */
            const int n = B - b < LOCKSTEP ? B - b : LOCKSTEP;
            window_codes(x + (size_t)b * x_frames * F, gates ? gates + (size_t)b * W * 3 * H : NULL, n, dims, params, scratch,
                         entropy + b, argmax + (size_t)b * G, latents ? latents + (size_t)b * out : NULL);
            #pragma omp barrier
        }
        denormals_restore(csr);
    }
    free(scratch);
    return 0;
}
