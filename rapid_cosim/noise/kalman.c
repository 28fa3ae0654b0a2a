/* The Kalman filter of timed.py run on residual rows: standardised innovations.

   Why here: the filter's innovations map W is lower triangular with a couple of hundred
   coefficients a row on jittered PMU recordings (the derived ROCOF's window in the state),
   so a sparse product streams megabytes per residual. The filter itself carries a state of
   d = kp + L + kf numbers whose transition is diagonal (the OU parts) plus a shift (the
   window of the source's samples), so each sample costs O(d). The gains K and innovation
   variances come from timed.py's filter (built once per noise model and samples); this
   only runs the mean recursion on each row:

       v_k = y_k - h_k . x,   e_k = v_k / sqrt(S_k),   x <- F_j (x + K_k v_k)

   with F_j applied on every grid step j (observed or not). The state layout is timed.py's
   _system: [OU of the recorder (kp) | window of the source (L), oldest first | OU of the
   source (kf)]; the window's newest sample is predicted by the source's OU parts.

   Rows go through in blocks of 4, each state element held for the 4 rows side by side
   (the loops over them vectorise), the rest one by one; the window is a sliding slice of one buffer, so a
   step shifts it by moving its start. */

#include <stdlib.h>
#include <string.h>

#define EXPORT __attribute__((visibility("default")))
#define BMAX 4

/* One block of nb <= B rows from row r0 (B a constant where it is called: each call site
   is compiled for its own B). */
static inline __attribute__((always_inline)) void block(
    const int B, int r0, int nb, int n, int steps, const long long *at, int kp, int L, int kf,
    const double *a, const double *b, const double *H, const double *K, const double *rinv,
    const double *y, double *e, double *own, double *win)
{
    const int d = kp + L + kf, z0 = kp + L;
    double *xf = own + (size_t)kp * B;
    memset(own, 0, sizeof(double) * (size_t)(kp + kf) * B);
    memset(win, 0, sizeof(double) * (size_t)(L + 1) * B);
    int k = 0;
    for (int j = 0; j < steps && k < n; ++j) {
        double *w = win + (size_t)j * B; /* the window at step j, oldest first */
        if (at[k] == j) {
            const double *h = H + (size_t)k * d, *g = K + (size_t)k * d;
            double v[BMAX];
            for (int r = 0; r < B; ++r) v[r] = r < nb ? y[(size_t)(r0 + r) * n + k] : 0.0;
            for (int i = 0; i < kp; ++i)
                for (int r = 0; r < B; ++r) v[r] -= h[i] * own[i * B + r];
            for (int l = 0; l < L; ++l)
                for (int r = 0; r < B; ++r) v[r] -= h[kp + l] * w[l * B + r];
            for (int r = 0; r < nb; ++r) e[(size_t)(r0 + r) * n + k] = v[r] * rinv[k];
            for (int i = 0; i < kp; ++i)
                for (int r = 0; r < B; ++r) own[i * B + r] += g[i] * v[r];
            for (int l = 0; l < L; ++l)
                for (int r = 0; r < B; ++r) w[l * B + r] += g[kp + l] * v[r];
            for (int c = 0; c < kf; ++c)
                for (int r = 0; r < B; ++r) xf[c * B + r] += g[z0 + c] * v[r];
            if (++k == n) break;
        }
        const double *aj = a + (size_t)j * kp, *bj = b + (size_t)j * kf;
        for (int i = 0; i < kp; ++i)
            for (int r = 0; r < B; ++r) own[i * B + r] *= aj[i];
        if (L) {
            double *newest = w + (size_t)L * B; /* the window at step j + 1 ends here */
            for (int r = 0; r < B; ++r) newest[r] = 0.0;
            for (int c = 0; c < kf; ++c)
                for (int r = 0; r < B; ++r) {
                    newest[r] += bj[c] * xf[c * B + r];
                    xf[c * B + r] *= bj[c];
                }
        }
    }
}

EXPORT int rc_kalman_whiten(int rows, int n, int steps, const long long *at, int kp, int L, int kf,
                            const double *a, const double *b, const double *H, const double *K,
                            const double *rinv, const double *y, double *e)
{
    /* per block: the OU states (kp + kf) x B, the window buffer (steps + L + 1) x B */
    double *own = malloc((size_t)(kp + kf + 1) * BMAX * sizeof(double));
    double *win = malloc((size_t)(steps + L + 1) * BMAX * sizeof(double));
    if (!own || !win) {
        free(own);
        free(win);
        return 1;
    }
    int r0 = 0;
    for (; r0 + BMAX <= rows; r0 += BMAX)
        block(BMAX, r0, BMAX, n, steps, at, kp, L, kf, a, b, H, K, rinv, y, e, own, win);
    for (; r0 < rows; ++r0)
        block(1, r0, 1, n, steps, at, kp, L, kf, a, b, H, K, rinv, y, e, own, win);
    free(own);
    free(win);
    return 0;
}
