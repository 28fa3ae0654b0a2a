/* e = W y for residual rows y, where W is the exact whitener of timed.py: sparse, lower
   triangular, each row a contiguous run of columns ending on the diagonal (a couple of
   hundred coefficients a row on jittered PMU recordings).

   Why here: scipy's CSR product with several rows adds each coefficient's products into
   the output in memory, one row of W at a time; a steam unit spent a fifth of its time
   there. This computes every output element as the same sum in the same order (0, then
   + w_0 x_0, + w_1 x_1, ... over the row's coefficients as stored, each product and sum
   rounded as written: built with -ffp-contract=off, so no fused multiply-add), so the
   numbers are scipy's bit for bit (band.py checks that on the machine before using it),
   but keeps the sums in registers and runs several of them side by side:
   - one residual row: four rows of W at a time, each its own sum;
   - several: the residual rows transposed (samples, rows), two of them a vector lane
     pair, up to sixteen sums held at once for each row of W. */

#include <stddef.h>
#ifdef __SSE2__
#include <emmintrin.h>
typedef __m128d pair;
#define ZERO() _mm_setzero_pd()
#define SPLAT(a) _mm_set1_pd(a)
#define LOAD(p) _mm_loadu_pd(p)
#define STORE(p, v) _mm_storeu_pd(p, v)
#define MADD(c, a, x) _mm_add_pd(c, _mm_mul_pd(a, x))
#else /* the same arithmetic, two lanes by hand */
typedef struct { double lo, hi; } pair;
static inline pair ZERO(void) { pair p = {0.0, 0.0}; return p; }
static inline pair SPLAT(double a) { pair p = {a, a}; return p; }
static inline pair LOAD(const double *x) { pair p = {x[0], x[1]}; return p; }
static inline void STORE(double *o, pair v) { o[0] = v.lo; o[1] = v.hi; }
static inline pair MADD(pair c, pair a, pair x) {
    pair p = {c.lo + a.lo * x.lo, c.hi + a.hi * x.hi};
    return p;
}
#endif

#define EXPORT __attribute__((visibility("default")))

/* one row of W (w, len) on 2 NB columns of xT (rows of m, from x) into o */
#define BLOCK(NB)                                                                               \
    static inline void block_##NB(const double *w, int len, const double *x, size_t m, double *o) { \
        pair c[NB];                                                                             \
        _Pragma("GCC unroll 8") for (int v = 0; v < NB; ++v) c[v] = ZERO();                      \
        for (int j = 0; j < len; ++j) {                                                         \
            const pair a = SPLAT(w[j]);                                                         \
            const double *xj = x + (size_t)j * m;                                               \
            _Pragma("GCC unroll 8") for (int v = 0; v < NB; ++v) c[v] = MADD(c[v], a, LOAD(xj + 2 * v)); \
        }                                                                                       \
        _Pragma("GCC unroll 8") for (int v = 0; v < NB; ++v) STORE(o + 2 * v, c[v]);             \
    }
BLOCK(8)
BLOCK(4)
BLOCK(2)
BLOCK(1)

static inline void block_single(const double *w, int len, const double *x, size_t m, double *o)
{
    double c = 0.0;
    for (int j = 0; j < len; ++j) c += w[j] * x[(size_t)j * m];
    *o = c;
}

#define CHUNK 128 /* residual rows a pass over W: their samples within a row's reach stay in cache */

/* several residual rows: xT, eT (n, m) row-major */
EXPORT void rc_band_rows(int m, int n, const long long *ptr, const int *first, const double *a, const double *xT,
                         double *eT)
{
    for (int c0 = 0; c0 < m; c0 += CHUNK) {
        const int c1 = c0 + CHUNK < m ? c0 + CHUNK : m;
        for (int i = 0; i < n; ++i) {
            const double *w = a + ptr[i], *x = xT + (size_t)first[i] * m;
            const int len = (int)(ptr[i + 1] - ptr[i]);
            double *o = eT + (size_t)i * m;
            int c = c0;
            for (; c + 16 <= c1; c += 16) block_8(w, len, x + c, m, o + c);
            if (c + 8 <= c1) { block_4(w, len, x + c, m, o + c); c += 8; }
            if (c + 4 <= c1) { block_2(w, len, x + c, m, o + c); c += 4; }
            if (c + 2 <= c1) { block_1(w, len, x + c, m, o + c); c += 2; }
            if (c < c1) block_single(w, len, x + c, m, o + c);
        }
    }
}

/* one residual row y (n) -> e (n): four rows of W at a time, over their common length,
   then each one's own remaining coefficients, in order */
EXPORT void rc_band_row(int n, const long long *ptr, const int *first, const double *a, const double *y, double *e)
{
    int i = 0;
    for (; i + 4 <= n; i += 4) {
        const double *w[4], *x[4];
        int len[4], common;
        double c[4] = {0.0, 0.0, 0.0, 0.0};
        for (int k = 0; k < 4; ++k) {
            w[k] = a + ptr[i + k];
            len[k] = (int)(ptr[i + k + 1] - ptr[i + k]);
            x[k] = y + first[i + k];
        }
        common = len[0];
        for (int k = 1; k < 4; ++k)
            if (len[k] < common) common = len[k];
        for (int j = 0; j < common; ++j) {
            c[0] += w[0][j] * x[0][j];
            c[1] += w[1][j] * x[1][j];
            c[2] += w[2][j] * x[2][j];
            c[3] += w[3][j] * x[3][j];
        }
        for (int k = 0; k < 4; ++k) {
            for (int j = common; j < len[k]; ++j) c[k] += w[k][j] * x[k][j];
            e[i + k] = c[k];
        }
    }
    for (; i < n; ++i) {
        const double *w = a + ptr[i], *x = y + first[i];
        const int len = (int)(ptr[i + 1] - ptr[i]);
        double c = 0.0;
        for (int j = 0; j < len; ++j) c += w[j] * x[j];
        e[i] = c;
    }
}
