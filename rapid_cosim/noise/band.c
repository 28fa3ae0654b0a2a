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
     pair, up to sixteen sums held at once for each row of W;
   - several, where the processor has AVX-512 or AVX2 (checked at the first call; built with
     target attributes, so the library runs on any x86-64): four rows of W at a time over
     up to 32 (AVX-512) or 8 (AVX2) residual rows, each sample of the residuals loaded
     once for the four (rows of W overlap on all but a few samples), in vectors of 8 or 4
     lanes, the last one masked. Each sum still takes its terms in the row's order (the
     row's own first samples, then those the four share, then its last ones), so the
     numbers are the same: band.py checks every way this processor has against scipy.
     About twice as quick as the pairs with AVX-512 on 8 to 300 residual rows of a
     3,600-sample band of 200 coefficients a row (make bench's whitening section). */

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

/* several residual rows: xT, eT (n, m) row-major; in pairs of lanes, on any processor */
static void rc_band_rows_pairs(int m, int n, const long long *ptr, const int *first, const double *a,
                               const double *xT, double *eT)
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

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#define WIDE 1
/* The two vector kits: AVX-512 (z, 8 lanes, a mask register) and AVX2 (y, 4 lanes, a
   mask vector). A masked-off lane is loaded as 0 and never stored. */
#define TARGET_z "avx512f"
#define V_z __m512d
#define M_z __mmask8
#define LANES_z 8
#define FULL_z() ((__mmask8)0xFF)
#define PART_z(k) ((__mmask8)((1u << (k)) - 1u))
#define ZERO_z() _mm512_setzero_pd()
#define SET1_z(x) _mm512_set1_pd(x)
#define MADD_z(c, a, x) _mm512_add_pd(c, _mm512_mul_pd(a, x))
#define LOAD_z(mk, p) _mm512_maskz_loadu_pd(mk, p)
#define STORE_z(p, mk, v) _mm512_mask_storeu_pd(p, mk, v)
#define TARGET_y "avx2"
#define V_y __m256d
#define M_y __m256i
#define LANES_y 4
#define FULL_y() _mm256_set1_epi64x(-1)
#define PART_y(k) _mm256_setr_epi64x(-((k) > 0), -((k) > 1), -((k) > 2), -((k) > 3))
#define ZERO_y() _mm256_setzero_pd()
#define SET1_y(x) _mm256_set1_pd(x)
#define MADD_y(c, a, x) _mm256_add_pd(c, _mm256_mul_pd(a, x))
#define LOAD_y(mk, p) _mm256_maskload_pd(p, mk)
#define STORE_y(p, mk, v) _mm256_maskstore_pd(p, mk, v)

/* rows i..i+3 of W on NB vectors of residual rows from lane c (the last vector masked by
   `last`): each row's head (its samples before the four's common run), the common run
   with each sample loaded once for the four, then each row's tail */
#define TILE(K, NB)                                                                                        \
    __attribute__((target(TARGET_##K))) static void tile_##K##NB(const long long *ptr, const int *first,    \
                                                                const double *a, int i, const double *xT,  \
                                                                size_t m, int c, M_##K last, double *eT)   \
    {                                                                                                      \
        V_##K s[4][NB];                                                                                    \
        const double *w[4];                                                                                \
        int f[4], e[4], k0 = 0, k1 = 1 << 30;                                                              \
        M_##K mk[NB];                                                                                      \
        _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v) mk[v] = v == NB - 1 ? last : FULL_##K();      \
        for (int r = 0; r < 4; ++r) {                                                                      \
            w[r] = a + ptr[i + r];                                                                         \
            f[r] = first[i + r];                                                                           \
            e[r] = f[r] + (int)(ptr[i + r + 1] - ptr[i + r]);                                              \
            if (f[r] > k0) k0 = f[r];                                                                      \
            if (e[r] < k1) k1 = e[r];                                                                      \
            _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v) s[r][v] = ZERO_##K();                     \
        }                                                                                                  \
        if (k1 < k0) k1 = k0; /* no common run: each row whole as head and tail */                         \
        for (int r = 0; r < 4; ++r)                                                                        \
            for (int k = f[r]; k < (e[r] < k0 ? e[r] : k0); ++k) {                                         \
                const V_##K aa = SET1_##K(w[r][k - f[r]]);                                                 \
                const double *xk = xT + (size_t)k * m + c;                                                 \
                _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v) s[r][v] =                             \
                    MADD_##K(s[r][v], aa, LOAD_##K(mk[v], xk + LANES_##K * v));                            \
            }                                                                                              \
        for (int k = k0; k < k1; ++k) {                                                                    \
            const double *xk = xT + (size_t)k * m + c;                                                     \
            V_##K x[NB];                                                                                   \
            _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v) x[v] = LOAD_##K(mk[v], xk + LANES_##K * v); \
            _Pragma("GCC unroll 4") for (int r = 0; r < 4; ++r) {                                          \
                const V_##K aa = SET1_##K(w[r][k - f[r]]);                                                 \
                _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v) s[r][v] = MADD_##K(s[r][v], aa, x[v]); \
            }                                                                                              \
        }                                                                                                  \
        for (int r = 0; r < 4; ++r) {                                                                      \
            for (int k = f[r] > k1 ? f[r] : k1; k < e[r]; ++k) {                                           \
                const V_##K aa = SET1_##K(w[r][k - f[r]]);                                                 \
                const double *xk = xT + (size_t)k * m + c;                                                 \
                _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v) s[r][v] =                             \
                    MADD_##K(s[r][v], aa, LOAD_##K(mk[v], xk + LANES_##K * v));                            \
            }                                                                                              \
            _Pragma("GCC unroll 4") for (int v = 0; v < NB; ++v)                                           \
                STORE_##K(eT + (size_t)(i + r) * m + c + LANES_##K * v, mk[v], s[r][v]);                   \
        }                                                                                                  \
    }
TILE(z, 1)
TILE(z, 2)
TILE(z, 3)
TILE(z, 4)
TILE(y, 1)
TILE(y, 2)

/* all rows of W four at a time, NBMAX vectors of residual rows a tile; the last rows of
   W one at a time */
#define ROWS(K, NBMAX, DISPATCH)                                                                           \
    __attribute__((target(TARGET_##K))) static void rows_##K(int m, int n, const long long *ptr,            \
                                                             const int *first, const double *a,             \
                                                             const double *xT, double *eT)                  \
    {                                                                                                      \
        const int span = NBMAX * LANES_##K;                                                                \
        int i = 0;                                                                                         \
        for (; i + 4 <= n; i += 4)                                                                         \
            for (int c = 0; c < m; c += span) {                                                            \
                const int lanes = m - c < span ? m - c : span, nb = (lanes + LANES_##K - 1) / LANES_##K;   \
                const M_##K last = PART_##K(lanes - LANES_##K * (nb - 1));                                 \
                DISPATCH                                                                                   \
            }                                                                                              \
        for (; i < n; ++i)                                                                                 \
            for (int c = 0; c < m; ++c)                                                                    \
                block_single(a + ptr[i], (int)(ptr[i + 1] - ptr[i]), xT + (size_t)first[i] * m + c,        \
                             (size_t)m, eT + (size_t)i * m + c);                                           \
    }
#define ARGS ptr, first, a, i, xT, (size_t)m, c, last, eT
ROWS(z, 4,
     if (nb == 1) tile_z1(ARGS); else if (nb == 2) tile_z2(ARGS); else if (nb == 3) tile_z3(ARGS);
     else tile_z4(ARGS);)
ROWS(y, 2, if (nb == 1) tile_y1(ARGS); else tile_y2(ARGS);)
#else
#define WIDE 0
#endif

/* the ways this processor can take: 1 pairs of lanes (every processor), 2 AVX2, 4 AVX-512 */
EXPORT int rc_band_ways(void)
{
    static int ways = 0;
    if (!ways) {
        int w = 1;
#if WIDE
        __builtin_cpu_init();
        if (__builtin_cpu_supports("avx2")) w |= 2;
        if (__builtin_cpu_supports("avx512f")) w |= 4;
#endif
        ways = w;
    }
    return ways;
}

/* several residual rows by one way (one of rc_band_ways's bits; the pairs for any other,
   or for one this processor has not) */
EXPORT void rc_band_rows_by(int way, int m, int n, const long long *ptr, const int *first, const double *a,
                            const double *xT, double *eT)
{
    if (!(way & rc_band_ways())) way = 1;
#if WIDE
    if (way == 4) {
        rows_z(m, n, ptr, first, a, xT, eT);
        return;
    }
    if (way == 2) {
        rows_y(m, n, ptr, first, a, xT, eT);
        return;
    }
#endif
    rc_band_rows_pairs(m, n, ptr, first, a, xT, eT);
}

/* several residual rows by the widest way this processor has */
EXPORT void rc_band_rows(int m, int n, const long long *ptr, const int *first, const double *a, const double *xT,
                         double *eT)
{
    const int ways = rc_band_ways();
    rc_band_rows_by(ways & 4 ? 4 : ways & 2 ? 2 : 1, m, n, ptr, first, a, xT, eT);
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
