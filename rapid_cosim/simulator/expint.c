/* rapid-cosim exponential runner: a model driven by a recorded input, at about one model
 * evaluation per input sample.
 *
 * Why: a governor model has 3 to 12 states and, between two samples of its piecewise
 * linear input, is a smooth and mostly linear ODE. CVODE (runner.c) must restart at every
 * kink of a noisy recorded input: some ten right-hand sides and a Jacobian update per
 * sample. This path integrates from sample to sample with an exponential multistep
 * formula instead, exact for the linear part of the model, and falls back to CVODE (the
 * same code as runner.c, which this file includes) wherever its own error estimate says it
 * is not accurate, or wherever it does not apply.
 *
 * The scheme (exponential time differencing, ETD-AB2, with a frozen linearisation):
 *   x' = f(t, x, u(t)) = A x + c(t),  c = f - A x,
 * A = df/dx (and B = df/du) by forward differences at the start of a set (n + m
 * evaluations). Over a step of length h from t_k, with c(t_k + s) taken linear, c_k + s v_k,
 * the variation-of-constants formula is exact:
 *   x_{k+1} = x_k + S1(h) f_k + S2(h) v_k,
 *   S1(h) = int_0^h e^{sA} ds,  S2(h) = int_0^h (h - s) e^{sA} ds   (h phi_1(hA), h^2 phi_2(hA)).
 * c = B u + g splits into the input's part, linear on the step and known exactly (the next
 * row of the table), and the remainder g = f - A x - B u, constant for a linear model and
 * slowly varying for a mostly linear one, extrapolated from the previous step (the
 * Adams-Bashforth part): v_k = B (u_{k+1} - u_k) / h + (g_k - g_{k-1}) / h_{k-1}. A linear
 * model driven by a piecewise-linear input is thus integrated exactly (to rounding and the
 * finite-difference error of A, whatever the noise), stiff parts included, with one
 * evaluation of the model per step: at the new point, where the next step needs f and the
 * caller needs the outputs. Both come from one fmi2GetReal of the derivatives and the
 * outputs where the FMU gives the derivatives that way, bit for bit as
 * fmi2GetDerivatives does (checked on the first set; else two calls).
 *
 * Error control: that evaluation also gives the slope c actually had over the step, w_k;
 * the corrector x_k + S1 f_k + S2 w_k (the exponential trapezoidal rule) minus the
 * predictor, S2 (w_k - v_k), estimates the step's local error (Milne's device) at no cost.
 * Within EX_TOL times CVODE's tolerance (rtol |x| + atol, per state) the predictor is
 * kept. Past it the corrected state is evaluated and kept when the estimate was within
 * EX_ACCEPT_CORRECTED of the bound (the corrector's own error being about a fifth of the
 * predictor's) and the correction converged; otherwise CVODE integrates that step, at
 * EX_TOL times its tolerance (at its own it was the larger error of the two: 6e-5 pu on
 * GGOV1 staged tests). Misses that cluster (EX_MISS_RELIN in the last 8 steps) mean the
 * frozen linearisation no longer describes the model (a limit engaged, a rate limit
 * binding): A and B are computed again at the current point, and the remainder's slope
 * with them. A set that keeps re-linearising (more than EX_RELIN_BASE + steps /
 * EX_RELIN_PER times: a model switching regime every few samples) goes on with CVODE to
 * its end, at CVODE's tolerance. The allowance takes in bursts of misses (GGOV1's gate
 * hops on the input's noise at first; cutting them short costs more than it saves: a
 * tighter rule, or one on the steps left to CVODE, sent GGOV1's sets to CVODE within the
 * first second, 4 times slower). Where misses go on all along (GGOV1's gate held by its
 * load limiter in noise) this path is up to 1.4 times slower than CVODE alone. No decision
 * depends on the clock, so a set repeats bit for bit.
 *
 * Irregular time stamps: S1, S2 and e^{hA} are computed (Taylor series with scaling and
 * squaring) for a ladder of step sizes h_r spaced dh apart over the grid's steps (those
 * up to twice the median), built once per linearisation by the addition formulas
 *   e^{(a+b)A} = e^{aA} e^{bA},  S1(a+b) = S1(a) + e^{aA} S1(b),
 *   S2(a+b) = S2(a) + b S1(a) + e^{aA} S2(b);
 * a step of length h_r + delta is the rung's matrices corrected by the series in delta to
 * third order,
 *   S1(h) = S1_r + Phi_r S1(delta),  S2(h) = S2_r + delta S1_r + Phi_r S2(delta),
 * one product with an n x 5n matrix per step. dh is chosen so that the first neglected
 * term, Phi_r A^3 delta^4 / 24, stays below EX_RUNG_EPS of the step's increment (a few
 * rungs for PMU jitter of 3 ms at 20 ms). Other steps (the first, those beside a time
 * event, mixed output and input rates) get their matrices computed directly, and the last
 * EX_DIRECT of them are kept.
 *
 * Where it does not apply, a whole set runs through runner.c's CVODE path, unchanged: an
 * FMU with event indicators (state events) or without states, and a set whose
 * linearisation fails (the model cannot be evaluated beside its initial point, or A is not
 * finite).
 *
 * Events and semantics are those of run_set in runner.c: outputs at the given times, time
 * events (the FMU's nextEventTime, steps of the input table: a time written twice) taken
 * exactly, values at an event being those after it, the input held at its value before a
 * step while integrating towards it; statuses and messages for failures, time-outs and
 * non-finite outputs. After an event the multistep history restarts (the first step
 * extrapolates g as constant).
 *
 * Chosen by measurement (2 cores, FrequencyInput, 120 s at 50 frames/s, 3 ms jitter, 1 mHz
 * noise): one fmi2SetTime + fmi2SetReal + fmi2SetContinuousStates + fmi2GetDerivatives on
 * the embedded TG Type I costs about 36 ns, with the outputs in the same fmi2GetReal 54 ns
 * (GGOV1: 180 and 250 ns), so a scheme's cost is its evaluations per sample. A two-stage
 * Rosenbrock (W-) method at the input rate needs two; the linearly implicit trapezoidal
 * rule with the same Adams-Bashforth remainder (IMEX CN-AB2) needs one, like this one, but
 * is not exact for the linear part: 2e-7 to 2e-6 pu from the tight reference where this
 * scheme is within 1e-8, an error its remainder estimate cannot see, and it rings on stiff
 * modes (GGOV1's 5 ms lag at 20 ms steps). The kernels below are specialised for up to
 * EX_NMAX states and none, one or two inputs (two: a recorded-frequency bench's f_dev and
 * rocof; on the generic kernel the second input cost 60 % more per simulation, TGOV1 on a
 * 60 s event); this file's own work per step is about twice the model's (the n x 5n
 * product, the slope of c, the bookkeeping).
 */
#include "runner.c"

#define EX_TOL 0.1               /* local error bound: this fraction of CVODE's tolerance, per step */
#define EX_ACCEPT_CORRECTED 4.0  /* keep the corrected state when the predictor missed by at most this */
#define EX_MISS_RELIN 3          /* misses in the last 8 steps that call for a new linearisation */
#define EX_RELIN_BASE 16         /* re-linearisations a set may make before going on with CVODE ... */
#define EX_RELIN_PER 64          /* ... plus one per this many steps */
#define EX_RUNG_EPS 1e-6         /* truncation of the delta series, relative to a step's increment */
#define EX_RUNG_MAX 256          /* rungs of the step-size ladder */
#define EX_CLOCK_EVERY 64        /* steps between two looks at the clock */
#define EX_DIRECT 4              /* steps off the ladder whose matrices are kept */

enum { EX_SETS, EX_SETS_CVODE, EX_SWITCHED, EX_STEPS, EX_EVALS, EX_MISSES, EX_CORRECTED, EX_FALLBACKS, EX_RELINS,
       EX_N_COUNTERS };

typedef struct Plan {
    /* the grid of the batch: every output time and input row in (start, end], increasing */
    int n_grid;
    double *g;
    unsigned char *g_out; /* an output time */
    double *g_u;          /* n_grid x m: the input there (before the step, at a step's time) */
    double h_lo, h_hi;    /* smallest and largest grid step */
    /* the model */
    int n, m, n_out;
    int combined;   /* derivatives and outputs from one fmi2GetReal */
    int checked;    /* combined was checked against fmi2GetDerivatives */
    fmi2ValueReference *eval_vrs; /* derivative vrs then output vrs */
    /* linear model and the ladder */
    double *A, *B;
    double dh, h0;
    int n_rungs, rung_cap;
    int ld;            /* n rounded up to even: the column length of the matrices below */
    double *rungs;     /* n_rungs x 5n columns of ld: [S1 | S2 | Phi | Phi A | Phi A^2] */
    double *Ac;        /* A by columns of ld */
    double *rung_norm; /* n_rungs x 3: max row sums of S1, S2, Phi */
    double *direct, direct_norm[EX_DIRECT][3], direct_h[EX_DIRECT]; /* steps off the ladder */
    int direct_next;
    double h_med;      /* the grid's median step */
    double *mats;      /* work matrices for building rungs: 12 x n x n */
    /* the current point and its history */
    double t, *x, *u, *gdot;
    double *slot[3];   /* [f | outputs] of the current point, the new point, a spare */
    int has_prev;
    double t_prev, *x_prev, *f_prev; /* the previous point (f_prev: a slot too) */
    int y_valid;       /* slot[0]'s outputs are those of the current point */
    unsigned miss_bits;
    long steps, relins; /* this set's */
    /* scratch */
    double *su, *su_next; /* the input's slope over the last step; the next one's */
    double reach;      /* largest |delta| a rung serves */
    double inv_dh;
    const double *atol; /* CVODE's absolute tolerances */
    N_Vector abstol_tight; /* EX_TOL times them, for CVODE over a step */
    Sundials *sun;      /* to free it */
    int (*kernel)(Runner *, struct Plan *, double, const double *, int); /* ex_step_n for n, m */
    int (*march)(Runner *, struct Plan *, double, double *, int *, int *); /* ex_march_n for n, m */
    double tol_floor;  /* the smallest of the step tolerances */
    double *xp, *xc, *z, *zero, *v, *bs, *w, *dx, *e, *col, *uu, *ut, *tol;
    double *kv, *kw, *kbs, *kdx, *kz; /* the generic kernel's vectors (see ex_step_any) */
    long long counters[EX_N_COUNTERS];
} Plan;

static double *ex_alloc(size_t n) { return calloc(n ? n : 1, sizeof(double)); }

/* the k-th smallest of a[0..n) (a is reordered): Hoare's selection, O(n) on average,
 * where sorting a recorded event's 6000 steps took most of a plan's time */
static double select_kth(double *a, int n, int k) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        double pivot = a[lo + (hi - lo) / 2], t;
        int i = lo, j = hi;
        while (i <= j) {
            while (a[i] < pivot) i++;
            while (a[j] > pivot) j--;
            if (i <= j) { t = a[i]; a[i] = a[j]; a[j] = t; i++; j--; }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
    return a[k];
}

static void ex_kernels(struct Plan *p);

RC_EXPORT void rc_plan_free(Plan *p) {
    int i;
    if (!p) return;
    if (p->abstol_tight) p->sun->N_VDestroy(p->abstol_tight);
    free(p->g); free(p->g_out); free(p->g_u); free(p->eval_vrs);
    free(p->A); free(p->Ac); free(p->B); free(p->rungs); free(p->rung_norm); free(p->direct); free(p->mats);
    free(p->x); free(p->u); free(p->gdot);
    for (i = 0; i < 3; i++) free(p->slot[i]);
    free(p->x_prev); free(p->f_prev); free(p->su_next);
    free(p->xp); free(p->xc); free(p->z); free(p->zero); free(p->v); free(p->bs); free(p->w); free(p->dx); free(p->e);
    free(p->col); free(p->uu); free(p->ut); free(p->tol); free(p->su);
    free(p->kv); free(p->kw); free(p->kbs); free(p->kdx); free(p->kz);
    free(p);
}

/* Input values at t by the table's rule (runner.c's input_at without its clamp). */
static void table_at(const Batch *b, double t, int *cursor, double *u) {
    const double *tt = b->input_time;
    int n = b->n_rows, k = b->n_inputs, i = *cursor, j;
    if (tt[i] <= t) {
        while (i + 1 < n && tt[i + 1] <= t) i++;
    } else {
        while (i > 0 && tt[i] > t) i--;
    }
    *cursor = i;
    if (tt[i] > t || i == n - 1) {
        memcpy(u, b->input_values + (size_t)i * k, k * sizeof(double));
        return;
    }
    {
        double w = (t - tt[i]) / (tt[i + 1] - tt[i]);
        const double *a = b->input_values + (size_t)i * k, *c = b->input_values + (size_t)(i + 1) * k;
        for (j = 0; j < k; j++) u[j] = a[j] + w * (c[j] - a[j]);
    }
}

/* The plan of a batch shape: its grid and the work space. der_vrs: the value references
 * of the derivatives in state order (NULL: read them with fmi2GetDerivatives only). */
RC_EXPORT Plan *rc_plan_new(Runner *r, const Batch *b, const fmi2ValueReference *der_vrs, char *err, int err_len) {
    Plan *p = calloc(1, sizeof(Plan));
    int n = r->n_states, m = b->n_inputs, i, j, k, cursor = 0, all_real = 1;
    double t0 = b->start_time, t_end = b->times[b->n_times - 1];
    size_t cap;
    err[0] = 0;
    if (!p) { snprintf(err, err_len, "out of memory"); return NULL; }
    p->n = n;
    p->m = m;
    ex_kernels(p);
    p->sun = &r->sun;
    p->abstol_tight = r->sun.N_VNew_Serial(r->n_dim, r->ctx);
    if (!p->abstol_tight) goto oom;
    {
        const double *a = r->sun.N_VGetArrayPointer(r->abstol);
        double *b2 = r->sun.N_VGetArrayPointer(p->abstol_tight);
        for (i = 0; i < r->n_dim; i++) b2[i] = EX_TOL * a[i];
    }
    p->n_out = b->n_out;
    for (k = 0; k < b->n_out; k++) all_real &= b->out_types[k] == 0;
    p->combined = der_vrs != NULL && all_real && n > 0;
    /* grid: merge the output times and the input rows in (t0, t_end] */
    cap = (size_t)b->n_times + (size_t)(m ? b->n_rows : 0) + 1;
    p->g = ex_alloc(cap);
    p->g_out = calloc(cap, 1);
    p->g_u = ex_alloc(cap * (size_t)(m ? m : 1));
    p->eval_vrs = calloc((size_t)n + b->n_out + 1, sizeof(fmi2ValueReference));
    if (!p->g || !p->g_out || !p->g_u || !p->eval_vrs) goto oom;
    i = 0; /* output times */
    j = 0; /* input rows */
    if (m) while (j < b->n_rows && b->input_time[j] <= t0) j++;
    k = 0;
    while (i < b->n_times || (m && j < b->n_rows && b->input_time[j] <= t_end)) {
        double to = i < b->n_times ? b->times[i] : INFINITY;
        double ti = (m && j < b->n_rows && b->input_time[j] <= t_end) ? b->input_time[j] : INFINITY;
        double tg = to < ti ? to : ti;
        if (tg > t0) {
            if (k > 0 && p->g[k - 1] == tg) k--; /* the same time again (a step's second row) */
            p->g[k] = tg;
            p->g_out[k] |= to == tg;
            k++;
        }
        if (to == tg) i++;
        if (ti == tg) j++;
    }
    p->n_grid = k;
    /* inputs at the grid points: before the step at a step's time (the clamp of runner.c) */
    for (k = 0; k < p->n_grid && m; k++) {
        int row = -1;
        for (j = cursor; j + 1 < b->n_rows; j++) {
            if (b->input_time[j] > p->g[k]) break;
            if (b->input_time[j] == p->g[k] && b->input_time[j + 1] == p->g[k]) { row = j; break; }
        }
        if (row >= 0) {
            memcpy(p->g_u + (size_t)k * m, b->input_values + (size_t)row * m, m * sizeof(double));
        } else {
            table_at(b, p->g[k], &cursor, p->g_u + (size_t)k * m);
        }
    }
    /* the ladder's range: the grid's steps up to twice their median, short ones included
     * (an output grid mixed with jittered input rows leaves steps from ~0 to the median:
     * computed directly, they made such a set 4.6 times slower than on regular rows);
     * longer ones (a gap, the first step) get their matrices computed directly */
    {
        double *steps = ex_alloc((size_t)p->n_grid), med;
        int n_steps = 0;
        if (!steps) goto oom;
        for (k = 0; k < p->n_grid; k++) {
            double h = p->g[k] - (k ? p->g[k - 1] : t0);
            if (h > 0) steps[n_steps++] = h;
        }
        med = n_steps ? select_kth(steps, n_steps, n_steps / 2) : (t_end > t0 ? t_end - t0 : 1.0);
        p->h_lo = INFINITY;
        p->h_hi = 0.0;
        for (k = 0; k < n_steps; k++) {
            if (steps[k] > 2.0 * med) continue;
            if (steps[k] < p->h_lo) p->h_lo = steps[k];
            if (steps[k] > p->h_hi) p->h_hi = steps[k];
        }
        if (!(p->h_lo <= p->h_hi)) p->h_lo = p->h_hi = med;
        p->h_med = med;
        free(steps);
    }
    for (k = 0; k < n && p->combined; k++) p->eval_vrs[k] = der_vrs[k];
    for (k = 0; k < b->n_out; k++) p->eval_vrs[n + k] = b->out_vrs[k];
    /* work space */
    {
        size_t nn = (size_t)(n ? n : 1), mm = (size_t)(m ? m : 1), row = nn + b->n_out + 1;
        p->A = ex_alloc(nn * nn);
        p->B = ex_alloc(nn * mm);
        size_t rs = 5 * nn * (size_t)((n + 1) & ~1);
        p->ld = (n + 1) & ~1;
        p->rung_cap = 8; /* grown by build_ladder as the rung spacing asks */
        p->rungs = ex_alloc((size_t)p->rung_cap * rs);
        p->rung_norm = ex_alloc((size_t)p->rung_cap * 3);
        p->direct = ex_alloc(EX_DIRECT * rs);
        p->Ac = ex_alloc(nn * (size_t)p->ld);
        p->mats = ex_alloc(12 * nn * nn);
        p->x = ex_alloc(nn); p->u = ex_alloc(mm); p->gdot = ex_alloc(nn);
        for (i = 0; i < 3; i++) p->slot[i] = ex_alloc(row);
        p->x_prev = ex_alloc(nn); p->f_prev = ex_alloc(row); p->su_next = ex_alloc(mm);
        p->xp = ex_alloc(nn); p->xc = ex_alloc(nn); p->z = ex_alloc(5 * nn); p->zero = ex_alloc(nn);
        p->v = ex_alloc(nn); p->bs = ex_alloc(nn); p->w = ex_alloc(nn); p->dx = ex_alloc(nn); p->e = ex_alloc(nn);
        p->col = ex_alloc(row); p->uu = ex_alloc(mm); p->ut = ex_alloc(mm); p->tol = ex_alloc(nn);
        p->su = ex_alloc(mm);
        p->kv = ex_alloc(nn); p->kw = ex_alloc(nn); p->kbs = ex_alloc(nn); p->kdx = ex_alloc(nn);
        p->kz = ex_alloc(5 * nn);
        if (!p->kv || !p->kw || !p->kbs || !p->kdx || !p->kz) goto oom;
        if (!p->A || !p->Ac || !p->B || !p->rungs || !p->rung_norm || !p->direct || !p->mats || !p->x || !p->u
            || !p->gdot || !p->slot[0] || !p->slot[1] || !p->slot[2] || !p->x_prev || !p->f_prev || !p->su_next
            || !p->xp || !p->xc || !p->z || !p->zero || !p->v || !p->bs || !p->w || !p->dx || !p->e || !p->col
            || !p->uu || !p->ut || !p->tol || !p->su)
            goto oom;
    }
    return p;
oom:
    snprintf(err, err_len, "out of memory");
    rc_plan_free(p);
    return NULL;
}

/* ---- matrices ---- */

#ifdef __SSE2__
#include <emmintrin.h>
/* c = a b for n <= 12 known at compile time: a row of c held in registers, two elements a
 * lane pair (and the last alone for odd n), each summed over k in order from 0.0 exactly
 * as the plain loop below sums it, so the same numbers. The products of the matrix
 * exponential were 12 % of a fleet unit's time in the plain loop (mat_mul_plain), which
 * keeps the row in memory and, n known only at run time, is not vectorised at -O2: 3.7
 * times quicker at n = 11, 4.9 at n = 6. */
static inline __attribute__((always_inline)) void mat_mul_pairs(const int n, const double *restrict a,
                                                                const double *restrict b, double *restrict c) {
    const int np = n / 2;
    for (int i = 0; i < n; i++) {
        __m128d acc[6];
        double last = 0.0;
        _Pragma("GCC unroll 6") for (int q = 0; q < np; q++) acc[q] = _mm_setzero_pd();
        for (int k = 0; k < n; k++) {
            const double aik = a[(size_t)i * n + k];
            const __m128d av = _mm_set1_pd(aik);
            const double *bk = b + (size_t)k * n;
            _Pragma("GCC unroll 6") for (int q = 0; q < np; q++)
                acc[q] = _mm_add_pd(acc[q], _mm_mul_pd(av, _mm_loadu_pd(bk + 2 * q)));
            if (n & 1) last += aik * bk[n - 1];
        }
        _Pragma("GCC unroll 6") for (int q = 0; q < np; q++) _mm_storeu_pd(c + (size_t)i * n + 2 * q, acc[q]);
        if (n & 1) c[(size_t)i * n + n - 1] = last;
    }
}
#define EX_MAT_MUL(N)                                                                                  \
    static __attribute__((noinline)) void mat_mul_##N(const double *a, const double *b, double *c) { \
        mat_mul_pairs(N, a, b, c);                                                                     \
    }
EX_MAT_MUL(1) EX_MAT_MUL(2) EX_MAT_MUL(3) EX_MAT_MUL(4) EX_MAT_MUL(5) EX_MAT_MUL(6)
EX_MAT_MUL(7) EX_MAT_MUL(8) EX_MAT_MUL(9) EX_MAT_MUL(10) EX_MAT_MUL(11) EX_MAT_MUL(12)
#endif

static void mat_mul_plain(int n, const double *a, const double *b, double *c) { /* c = a b (c distinct) */
    int i, j, k;
    for (i = 0; i < n; i++) {
        double *ci = c + (size_t)i * n;
        for (j = 0; j < n; j++) ci[j] = 0.0;
        for (k = 0; k < n; k++) {
            double aik = a[(size_t)i * n + k];
            const double *bk = b + (size_t)k * n;
            for (j = 0; j < n; j++) ci[j] += aik * bk[j];
        }
    }
}

static void mat_mul(int n, const double *a, const double *b, double *c) { /* c = a b (c distinct) */
#ifdef __SSE2__
    static void (*const sized[12])(const double *, const double *, double *) = {
        mat_mul_1, mat_mul_2, mat_mul_3, mat_mul_4, mat_mul_5, mat_mul_6,
        mat_mul_7, mat_mul_8, mat_mul_9, mat_mul_10, mat_mul_11, mat_mul_12};
    if (n >= 1 && n <= 12) {
        sized[n - 1](a, b, c);
        return;
    }
#endif
    mat_mul_plain(n, a, b, c);
}

static double row_norm(int n, const double *a) { /* max row sum of |a| */
    int i, j;
    double best = 0.0;
    for (i = 0; i < n; i++) {
        double s = 0.0;
        for (j = 0; j < n; j++) s += fabs(a[(size_t)i * n + j]);
        if (s > best) best = s;
    }
    return best;
}

/* Phi = e^{hA}, S1(h), S2(h) by Taylor series of degree 13 on h / 2^s with ||A h / 2^s|| <=
 * 1/2, then s doublings: Phi(2a) = Phi(a)^2, S1(2a) = S1(a) + Phi(a) S1(a),
 * S2(2a) = S2(a) + a S1(a) + Phi(a) S2(a). work: 3 n x n. */
static void phi_direct(int n, const double *A, double h, double *Phi, double *S1, double *S2, double *work) {
    double *T = work, *P = work + (size_t)n * n, *Q = work + 2 * (size_t)n * n;
    double norm = 0.0, hs = h, fact[16];
    int s = 0, i, j, d;
    size_t nn = (size_t)n * n;
    for (j = 0; j < n; j++) { /* max column sum */
        double c = 0.0;
        for (i = 0; i < n; i++) c += fabs(A[(size_t)i * n + j]);
        if (c > norm) norm = c;
    }
    norm *= fabs(h);
    while (norm > 0.5 && s < 60) { norm *= 0.5; hs *= 0.5; s++; }
    for (i = 0; i < (int)nn; i++) T[i] = A[i] * hs;
    fact[0] = 1.0;
    for (d = 1; d < 16; d++) fact[d] = fact[d - 1] * d;
    /* P = sum_{j=0}^{13} T^j / (j + 2)!  (Horner) */
    for (i = 0; i < (int)nn; i++) P[i] = 0.0;
    for (i = 0; i < n; i++) P[(size_t)i * n + i] = 1.0 / fact[15];
    for (d = 12; d >= 0; d--) {
        mat_mul(n, T, P, Q);
        for (i = 0; i < (int)nn; i++) P[i] = Q[i];
        for (i = 0; i < n; i++) P[(size_t)i * n + i] += 1.0 / fact[d + 2];
    }
    /* S2 = hs^2 P; S1 = hs (I + T P); Phi = I + T (I + T P) */
    mat_mul(n, T, P, Q);
    for (i = 0; i < (int)nn; i++) S2[i] = hs * hs * P[i];
    for (i = 0; i < n; i++) Q[(size_t)i * n + i] += 1.0;  /* Q = I + T P */
    for (i = 0; i < (int)nn; i++) S1[i] = hs * Q[i];
    mat_mul(n, T, Q, Phi);
    for (i = 0; i < n; i++) Phi[(size_t)i * n + i] += 1.0;
    for (d = 0; d < s; d++) {
        mat_mul(n, Phi, S2, P);
        for (i = 0; i < (int)nn; i++) S2[i] = S2[i] + hs * S1[i] + P[i];
        mat_mul(n, Phi, S1, P);
        for (i = 0; i < (int)nn; i++) S1[i] += P[i];
        mat_mul(n, Phi, Phi, P);
        for (i = 0; i < (int)nn; i++) Phi[i] = P[i];
        hs *= 2.0;
    }
}

/* A rung: [S1 | S2 | Phi | Phi A | Phi A^2] by columns of ld (rows past n stay 0), and the
 * norms of S1, S2, Phi. */
static void pack_rung(Plan *p, const double *Phi, const double *S1, const double *S2, double *rung, double *norm) {
    int n = p->n, ld = p->ld, i, j, blk;
    size_t nn = (size_t)n * n;
    double *PA = p->mats + 9 * nn, *PA2 = p->mats + 10 * nn;
    const double *blocks[5];
    mat_mul(n, Phi, p->A, PA);
    mat_mul(n, PA, p->A, PA2);
    blocks[0] = S1; blocks[1] = S2; blocks[2] = Phi; blocks[3] = PA; blocks[4] = PA2;
    for (blk = 0; blk < 5; blk++)
        for (j = 0; j < n; j++)
            for (i = 0; i < n; i++) rung[((size_t)blk * n + j) * ld + i] = blocks[blk][(size_t)i * n + j];
    norm[0] = row_norm(n, S1);
    norm[1] = row_norm(n, S2);
    norm[2] = row_norm(n, Phi);
}

/* The ladder for the current A: rung spacing from the truncation bound, rungs from the
 * first by the addition formulas. Returns 1 if a matrix is not finite. */
static int build_ladder(Plan *p) {
    int n = p->n, r, i, span;
    size_t nn = (size_t)n * n;
    double *Phi = p->mats, *S1 = p->mats + nn, *S2 = p->mats + 2 * nn;
    double *dPhi = p->mats + 3 * nn, *dS1 = p->mats + 4 * nn, *dS2 = p->mats + 5 * nn;
    double *work = p->mats + 6 * nn, *PA3 = p->mats + 11 * nn, nu3, dmax, width = p->h_hi - p->h_lo;
    /* nu3 = ||Phi(h_lo) A^3||: the size of the first neglected term of the delta series */
    phi_direct(n, p->A, p->h_lo, Phi, S1, S2, work);
    pack_rung(p, Phi, S1, S2, p->rungs, p->rung_norm);
    mat_mul(n, p->mats + 10 * nn, p->A, PA3);
    nu3 = row_norm(n, PA3);
    dmax = nu3 > 0 ? pow(24.0 * EX_RUNG_EPS * p->h_lo / nu3, 0.25) : INFINITY;
    if (!isfinite(nu3)) return 1;
    if (width <= 2.0 * dmax) { /* one rung in the middle covers the range */
        p->n_rungs = 1;
        p->dh = 1.0;
        p->inv_dh = 1.0;
        p->reach = dmax;
        p->h0 = 0.5 * (p->h_lo + p->h_hi);
        phi_direct(n, p->A, p->h0, Phi, S1, S2, work);
        pack_rung(p, Phi, S1, S2, p->rungs, p->rung_norm);
    } else {
        span = (int)ceil(width / (2.0 * dmax));
        if (span > EX_RUNG_MAX - 1) span = EX_RUNG_MAX - 1; /* the rest computed directly */
        if (span + 1 > p->rung_cap) {
            size_t rs = (size_t)5 * n * p->ld;
            double *more = realloc(p->rungs, (size_t)(span + 1) * rs * sizeof(double));
            double *norms = more ? realloc(p->rung_norm, (size_t)(span + 1) * 3 * sizeof(double)) : NULL;
            if (more) p->rungs = more;
            if (norms) p->rung_norm = norms;
            if (!more || !norms) return 1;
            memset(p->rungs + (size_t)p->rung_cap * rs, 0, (size_t)(span + 1 - p->rung_cap) * rs * sizeof(double));
            p->rung_cap = span + 1;
        }
        p->n_rungs = span + 1;
        p->h0 = p->h_lo;
        p->dh = width / span;
        if (span == EX_RUNG_MAX - 1) { /* around the median step, at the spacing the bound asks */
            p->dh = 2.0 * dmax;
            p->h0 = fmax(p->h_lo, fmin(p->h_med - 0.5 * span * p->dh, p->h_hi - span * p->dh));
            phi_direct(n, p->A, p->h0, Phi, S1, S2, work);
            pack_rung(p, Phi, S1, S2, p->rungs, p->rung_norm);
        }
        p->reach = 0.5 * p->dh * (1.0 + 1e-9);
        p->inv_dh = 1.0 / p->dh;
        phi_direct(n, p->A, p->dh, dPhi, dS1, dS2, work);
        for (r = 1; r < p->n_rungs; r++) { /* (h_r + dh) from h_r: Phi(a+b) = Phi(a) Phi(b), ... */
            double *P = work, *Q = work + nn;
            mat_mul(n, Phi, dS2, P);
            for (i = 0; i < (int)nn; i++) S2[i] = S2[i] + p->dh * S1[i] + P[i];
            mat_mul(n, Phi, dS1, P);
            for (i = 0; i < (int)nn; i++) S1[i] += P[i];
            mat_mul(n, Phi, dPhi, Q);
            memcpy(Phi, Q, nn * sizeof(double));
            pack_rung(p, Phi, S1, S2, p->rungs + (size_t)r * 5 * nn * p->ld / n, p->rung_norm + 3 * r);
        }
    }
    for (i = 0; i < p->n_rungs * 5 * n * p->ld; i++)
        if (!isfinite(p->rungs[i])) return 1;
    for (i = 0; i < n; i++) /* A by columns, for the kernels */
        for (r = 0; r < n; r++) p->Ac[(size_t)r * p->ld + i] = p->A[(size_t)i * n + r];
    for (i = 0; i < EX_DIRECT; i++) p->direct_h[i] = NAN;
    return 0;
}

/* The matrices of a step of length h off the ladder, computed directly (the last
 * EX_DIRECT kept). */
static __attribute__((noinline)) const double *direct_rung(Plan *p, double h, const double **norm) {
    int n = p->n, c;
    size_t nn = (size_t)n * n, rs = (size_t)5 * n * p->ld;
    for (c = 0; c < EX_DIRECT; c++)
        if (p->direct_h[c] == h) break;
    if (c == EX_DIRECT) {
        double *Phi = p->mats, *S1 = p->mats + nn, *S2 = p->mats + 2 * nn;
        c = p->direct_next;
        p->direct_next = (c + 1) % EX_DIRECT;
        phi_direct(n, p->A, h, Phi, S1, S2, p->mats + 6 * nn);
        pack_rung(p, Phi, S1, S2, p->direct + c * rs, p->direct_norm[c]);
        p->direct_h[c] = h;
    }
    *norm = p->direct_norm[c];
    return p->direct + c * rs;
}

/* The matrices of a step of length h: a rung and delta = h - h_r, or computed directly. */
static inline __attribute__((always_inline)) const double *rung_for(Plan *p, double h, double *delta,
                                                                    const double **norm) {
    long r = 0;
    if (p->n_rungs > 1) {
        double q = (h - p->h0) * p->inv_dh + 0.5;
        r = q >= 0.0 && q < (double)p->n_rungs ? (long)q : -1;
    }
    if (r >= 0) {
        double d = h - (p->n_rungs > 1 ? p->h0 + r * p->dh : p->h0);
        if (fabs(d) <= p->reach) {
            *delta = d;
            *norm = p->rung_norm + 3 * r;
            return p->rungs + (size_t)r * 5 * p->n * p->ld;
        }
    }
    *delta = 0.0;
    return direct_rung(p, h, norm);
}

/* out = S1(h) a + S2(h) b with h = h_r + d: the rung M = [S1 | S2 | Phi | Phi A | Phi A^2]
 * times z = [a + d b; b; d a + d^2/2 b; d^2/2 a + d^3/6 b; d^3/6 a + d^4/24 b] (only the
 * first two blocks when d = 0), column by column on pairs of rows. Inlined with n a
 * constant in the kernels (see ex_step_n). */
#define EX_NMAX 12 /* the largest model with a specialised kernel */
#define EX_UNROLL _Pragma("GCC unroll 16")

/* Two doubles: the kernels' products run on pairs of rows (SSE2, NEON; plain code elsewhere). */
typedef double ex_v2 __attribute__((vector_size(16), aligned(8)));

static inline __attribute__((always_inline)) ex_v2 ex_load2(const double *a) {
    ex_v2 v;
    memcpy(&v, a, sizeof v);
    return v;
}

static inline __attribute__((always_inline)) void apply_step_n(const double *restrict M, double d,
                                                               const double *restrict a, const double *restrict b,
                                                               double *restrict out, double *restrict z, const int n) {
    const int ld = (n + 1) & ~1, nv = ld / 2, cols = d != 0.0 ? 5 * n : 2 * n;
    int i, j;
    ex_v2 acc[nv], acc2[nv];
    if (d != 0.0) {
        double d2 = d * d * 0.5, d3 = d2 * d * (1.0 / 3.0), d4 = d3 * d * 0.25;
        EX_UNROLL for (j = 0; j < n; j++) {
            double aj = a[j], bj = b[j];
            z[j] = aj + d * bj;
            z[n + j] = bj;
            z[2 * n + j] = d * aj + d2 * bj;
            z[3 * n + j] = d2 * aj + d3 * bj;
            z[4 * n + j] = d3 * aj + d4 * bj;
        }
    } else {
        EX_UNROLL for (j = 0; j < n; j++) {
            z[j] = a[j];
            z[n + j] = b[j];
        }
    }
    /* out = M z by columns, two partial sums (even and odd columns) */
    EX_UNROLL for (i = 0; i < nv; i++) acc[i] = acc2[i] = (ex_v2){0.0, 0.0};
    EX_UNROLL for (j = 0; j + 1 < cols; j += 2) {
        const double *restrict c0 = M + (size_t)j * ld, *restrict c1 = c0 + ld;
        ex_v2 z0 = {z[j], z[j]}, z1 = {z[j + 1], z[j + 1]};
        EX_UNROLL for (i = 0; i < nv; i++) {
            acc[i] += ex_load2(c0 + 2 * i) * z0;
            acc2[i] += ex_load2(c1 + 2 * i) * z1;
        }
    }
    if (cols & 1) {
        const double *restrict c0 = M + (size_t)(cols - 1) * ld;
        ex_v2 z0 = {z[cols - 1], z[cols - 1]};
        EX_UNROLL for (i = 0; i < nv; i++) acc[i] += ex_load2(c0 + 2 * i) * z0;
    }
    EX_UNROLL for (i = 0; i < nv; i++) {
        ex_v2 sum = acc[i] + acc2[i];
        out[2 * i] = sum[0];
        if (2 * i + 1 < n) out[2 * i + 1] = sum[1];
    }
}

static void apply_step(const Plan *p, const double *M, double d, const double *a, const double *b, double *out) {
    apply_step_n(M, d, a, b, out, p->z, p->n);
}

/* ---- the model ---- */

/* f (and the outputs after it, in combined mode, when with_out) at (t, x, u) into buf.
 * Returns 0, or 1 when the model failed or gave a non-finite derivative. */
static int ex_eval(Runner *r, Plan *p, double t, const double *x, const double *u, double *buf, int with_out) {
    int n = p->n, i;
    if (r->fmi.set_time(r->c, t) >= fmi2Error) return 1;
    if (p->m && r->fmi.set_real(r->c, r->b->input_vrs, (size_t)p->m, u) >= fmi2Error) return 1;
    if (r->fmi.set_states(r->c, x, (size_t)n) >= fmi2Error) return 1;
    if (p->combined) {
        if (r->fmi.get_real(r->c, p->eval_vrs, (size_t)(n + (with_out ? p->n_out : 0)), buf) >= fmi2Error) return 1;
    } else if (r->fmi.get_derivatives(r->c, buf, (size_t)n) >= fmi2Error) {
        return 1;
    }
    p->counters[EX_EVALS]++;
    for (i = 0; i < n; i++)
        if (!isfinite(buf[i])) return 1;
    return 0;
}

/* Leave the FMU at the plan's current point (after evaluations elsewhere). */
static void ex_restore(Runner *r, Plan *p) {
    r->fmi.set_time(r->c, p->t);
    if (p->m) r->fmi.set_real(r->c, r->b->input_vrs, (size_t)p->m, p->u);
    r->fmi.set_states(r->c, p->x, (size_t)p->n);
}

/* A = df/dx, B = df/du at the current point by forward differences; then the ladder, and
 * the remainder's slope over the last step again for the new A and B. Returns 1 if the
 * model could not be evaluated or a matrix is not finite. */
static int ex_linearise(Runner *r, Plan *p) {
    int n = p->n, m = p->m, i, j;
    const double *f = p->slot[0];
    double *xx = p->xc, *col = p->col;
    memcpy(xx, p->x, n * sizeof(double));
    for (j = 0; j < n; j++) {
        double e = 1.4901161193847656e-8 * fmax(fabs(p->x[j]), 1.0), keep = xx[j];
        xx[j] = keep + e;
        e = xx[j] - keep; /* the step actually taken */
        if (ex_eval(r, p, p->t, xx, p->u, col, 0)) return 1;
        for (i = 0; i < n; i++) p->A[(size_t)i * n + j] = (col[i] - f[i]) / e;
        xx[j] = keep;
    }
    for (j = 0; j < m; j++) {
        double e, keep = p->u[j];
        memcpy(p->uu, p->u, m * sizeof(double));
        e = 1.4901161193847656e-8 * fmax(fabs(keep), 1.0);
        p->uu[j] = keep + e;
        e = p->uu[j] - keep;
        if (ex_eval(r, p, p->t, p->x, p->uu, col, 0)) return 1;
        for (i = 0; i < n; i++) p->B[(size_t)i * m + j] = (col[i] - f[i]) / e;
    }
    ex_restore(r, p);
    for (i = 0; i < n * n; i++)
        if (!isfinite(p->A[i])) return 1;
    for (i = 0; i < n * m; i++)
        if (!isfinite(p->B[i])) return 1;
    if (build_ladder(p)) return 1;
    p->miss_bits = 0;
    if (p->has_prev && p->t - p->t_prev >= 1e-6 * p->h_lo) {
        /* gdot = (c - c_prev) / h - B s_u with c = f - A x, for the new A and B (not from a
         * sliver beside an event: its chord is rounding noise) */
        double h = p->t - p->t_prev;
        for (i = 0; i < n; i++) {
            double s = f[i] - p->f_prev[i];
            for (j = 0; j < n; j++) s -= p->A[(size_t)i * n + j] * (p->x[j] - p->x_prev[j]);
            p->gdot[i] = s / h;
        }
        for (i = 0; i < n; i++) { /* less B s_u of the last step, with the new B */
            double s = 0.0;
            for (j = 0; j < m; j++) s += p->B[(size_t)i * m + j] * p->su[j];
            p->gdot[i] -= s;
        }
    } else {
        for (i = 0; i < n; i++) p->gdot[i] = 0.0;
    }
    return 0;
}

/* The local error test: |e_i| <= limit * EX_TOL (rtol |x_i| + atol_i). */
static int within(const Plan *p, const double *e, double limit) {
    int i;
    for (i = 0; i < p->n; i++)
        if (fabs(e[i]) > limit * p->tol[i]) return 0;
    return 1;
}

static void set_tolerances(Runner *r, Plan *p, const double *x) {
    int i;
    for (i = 0; i < p->n; i++) p->tol[i] = EX_TOL * (r->rtol * fabs(x[i]) + p->atol[i]);
}

/* CVODE from the current point to tb (runner.c's advance_smooth); the state there into x. */
static int ex_cvode_interval(Runner *r, Plan *p, double tb, double *x) {
    int s;
    double t = p->t;
    p->counters[EX_FALLBACKS]++;
    ex_restore(r, p);
    /* at the integrator's own tolerance (EX_TOL of CVODE's), then CVODE's back */
    if (r->sun.CVodeSVtolerances(r->mem, EX_TOL * r->rtol, p->abstol_tight)) {
        set_message(r, "CVodeSVtolerances failed");
        return RC_SOLVER;
    }
    s = reinit(r, p->t);
    if (!s) s = advance_smooth(r, tb, &t);
    r->sun.CVodeSVtolerances(r->mem, r->rtol, r->abstol);
    if (s) return s;
    FMI(r->fmi.get_states(r->c, x, (size_t)p->n), "fmi2GetContinuousStates");
    return RC_OK;
}

/* A step whose predictor missed (miss 1: try the corrector; 2: CVODE): the new point
 * into p->xp and p->slot[1], and w, the slope of c over the step. Returns 0 when mended, a
 * status otherwise. */
static __attribute__((noinline)) int ex_mend(Runner *r, Plan *p, double tb, const double *ub, int with_out, int miss,
                                             const double *M, double delta, double inv_h) {
    int n = p->n, i, j, s;
    double *f = p->slot[0], *fb = p->slot[1], *x = p->x, *xp = p->xp;
    if (miss == 1) { /* the corrector x_k + S1 f_k + S2 w, evaluated */
        double *fc = p->slot[2], *t2 = p->col;
        p->counters[EX_CORRECTED]++;
        for (i = 0; i < n; i++) p->xc[i] = xp[i] + p->e[i];
        if (ex_eval(r, p, tb, p->xc, ub, fc, with_out)) {
            miss = 2;
        } else {
            for (i = 0; i < n; i++) {
                const double *Ai = p->A + (size_t)i * n;
                double s2 = 0.0;
                for (j = 0; j < n; j++) s2 += Ai[j] * (p->xc[j] - x[j]);
                p->dx[i] = (fc[i] - f[i] - s2) * inv_h - p->w[i]; /* the slope's change */
            }
            apply_step(p, M, delta, p->zero, p->dx, t2);
            if (within(p, t2, 1.0)) { /* converged: keep the corrected point */
                memcpy(xp, p->xc, n * sizeof(double));
                p->slot[1] = fc;
                p->slot[2] = fb;
                fb = fc;
            } else {
                miss = 2;
            }
        }
    }
    if (miss == 2) { /* CVODE over the step */
        if ((s = ex_cvode_interval(r, p, tb, xp))) return s;
        if (ex_eval(r, p, tb, xp, ub, fb, with_out)) {
            set_message(r, "the model could not be evaluated at t=%g%s%s", tb, r->fmu_log[0] ? ": " : "", r->fmu_log);
            return RC_FMI;
        }
    }
    p->counters[EX_MISSES]++;
    for (i = 0; i < n; i++) {
        const double *Ai = p->A + (size_t)i * n;
        double s2 = 0.0;
        for (j = 0; j < n; j++) s2 += Ai[j] * (xp[j] - x[j]);
        p->w[i] = (fb[i] - f[i] - s2) * inv_h;
    }
    return RC_OK;
}

/* The error estimate S2(h) (w - v) when the cheap bound did not settle it: 0 within the
 * tolerance, 1 within EX_ACCEPT_CORRECTED of it, 2 past that. */
static __attribute__((noinline)) int ex_estimate(Runner *r, Plan *p, const double *M, double delta) {
    set_tolerances(r, p, p->x);
    memcpy(p->col, p->e, p->n * sizeof(double));
    apply_step(p, M, delta, p->zero, p->col, p->e);
    if (within(p, p->e, 1.0)) return 0;
    return within(p, p->e, EX_ACCEPT_CORRECTED) ? 1 : 2;
}

/* One step to tb, where the input is ub; with_out: the outputs are read there too.
 * Returns RC_OK, a status (a CVODE failure of the fallback), or -1: go on with CVODE.
 * Inlined where n and m are constants (the kernels below), with the step's vectors v, w,
 * bs, dx, z on the caller's stack. */
static inline __attribute__((always_inline)) int ex_step_n(Runner *r, Plan *p, double tb, const double *ub,
                                                           int with_out, const int n, const int m,
                                                           double *restrict v, double *restrict w,
                                                           double *restrict bs, double *restrict dx,
                                                           double *restrict z) {
    int i, j, s, miss = 0;
    double h = tb - p->t, inv_h = 1.0 / h, delta, dmax = 0.0, esum = 0.0;
    double *f = p->slot[0], *fb = p->slot[1], *x = p->x, *xp = p->xp, *su = p->su_next;
    const double *M, *norm, *restrict Ac = p->Ac, *restrict B = p->B, *restrict gdot = p->gdot;
    const double *restrict u = p->u;
    /* the input's slope, and the predicted slope of c: v = B s_u + gdot */
    EX_UNROLL for (j = 0; j < m; j++) su[j] = (ub[j] - u[j]) * inv_h;
    EX_UNROLL for (i = 0; i < n; i++) {
        double bsi = 0.0;
        EX_UNROLL for (j = 0; j < m; j++) bsi += B[i * m + j] * su[j];
        bs[i] = bsi;
        v[i] = bsi + gdot[i];
    }
    M = rung_for(p, h, &delta, &norm);
    apply_step_n(M, delta, f, v, dx, z, n);
    EX_UNROLL for (i = 0; i < n; i++) xp[i] = x[i] + dx[i];
    p->steps++;
    p->counters[EX_STEPS]++;
    p->counters[EX_EVALS]++;
    /* the model at the new point */
    if (r->fmi.set_time(r->c, tb) >= fmi2Error
        || (m && r->fmi.set_real(r->c, r->b->input_vrs, (size_t)m, ub) >= fmi2Error)
        || r->fmi.set_states(r->c, xp, (size_t)n) >= fmi2Error
        || (p->combined ? r->fmi.get_real(r->c, p->eval_vrs, (size_t)(n + (with_out ? p->n_out : 0)), fb)
                        : r->fmi.get_derivatives(r->c, fb, (size_t)n)) >= fmi2Error) {
        miss = 2;
    } else {
        /* w: the slope c had over the step; S2 (w - v), the corrector minus the predictor */
        const double *restrict fa = f, *restrict fn = fb;
        ex_v2 ad[(n + 1) / 2];
        EX_UNROLL for (i = 0; i < (n + 1) / 2; i++) ad[i] = (ex_v2){0.0, 0.0};
        EX_UNROLL for (j = 0; j < n; j++) { /* A dx by columns */
            ex_v2 dj = {dx[j], dx[j]};
            EX_UNROLL for (i = 0; i < (n + 1) / 2; i++) ad[i] += ex_load2(Ac + (size_t)j * ((n + 1) & ~1) + 2 * i) * dj;
        }
        EX_UNROLL for (i = 0; i < n; i++) {
            double ei;
            w[i] = (fn[i] - fa[i] - ad[i / 2][i & 1]) * inv_h;
            ei = w[i] - v[i];
            p->e[i] = ei;
            esum += ei;
            ei = fabs(ei);
            dmax = ei > dmax ? ei : dmax;
        }
        if (!isfinite(esum)) { /* a derivative is not finite */
            miss = 2;
        } else if ((norm[1] + fabs(delta) * (norm[0] + norm[2] * fabs(delta))) * dmax > p->tol_floor) {
            /* |S2(h) e| <= (|S2_r| + |delta| (|S1_r| + |delta| |Phi_r|)) max|e|: mostly enough */
            miss = ex_estimate(r, p, M, delta);
        }
    }
    if (miss) {
        if (miss == 1) memcpy(p->w, w, n * sizeof(double));
        if ((s = ex_mend(r, p, tb, ub, with_out, miss, M, delta, inv_h))) return s;
        fb = p->slot[1];
        memcpy(w, p->w, n * sizeof(double));
    }
    p->miss_bits = (p->miss_bits << 1) | (miss != 0);
    /* the remainder's slope over this step, g' = w - B s_u, for the next; not from a
     * sliver beside an event, whose chord is rounding noise */
    if (h >= 1e-6 * p->h_lo) {
        double *restrict gd = p->gdot;
        EX_UNROLL for (i = 0; i < n; i++) gd[i] = w[i] - bs[i];
        p->su_next = p->su;
        p->su = su;
    }
    /* the new point becomes the current one: rotate the buffers */
    p->t_prev = p->t;
    p->t = tb;
    p->xp = p->x_prev;
    p->x_prev = x;
    p->x = xp;
    p->slot[1] = p->f_prev;
    p->f_prev = f;
    p->slot[0] = fb;
    EX_UNROLL for (j = 0; j < m; j++) p->u[j] = ub[j];
    p->has_prev = 1;
    p->y_valid = with_out && p->combined;
    if (miss && __builtin_popcount(p->miss_bits & 0xFFu) >= EX_MISS_RELIN) {
        p->counters[EX_RELINS]++;
        if (++p->relins > EX_RELIN_BASE + p->steps / EX_RELIN_PER) return -1; /* go on with CVODE */
        if (ex_linearise(r, p)) return -1;
    }
    return RC_OK;
}

/* From the current point through the grid, writing the outputs on the way, for as long as
 * no time event is due (before E, within runner.c's reach of an output time): the run of
 * a set between its events without going back to the set's loop. k: the next output;
 * cursor: the next grid point. */
static inline __attribute__((always_inline)) int ex_march_n(Runner *r, Plan *p, double E, double *out, int *k,
                                                            int *cursor, const int n, const int m,
                                                            double *restrict v, double *restrict w,
                                                            double *restrict bs, double *restrict dx,
                                                            double *restrict z) {
    const Batch *b = r->b;
    const double *g = p->g, *times = b->times;
    int kk = *k, j = *cursor, s, n_out = b->n_out;
    while (kk < b->n_times) {
        double tk = times[kk];
        if (!(tk + 1e-12 * (fabs(tk) > 1.0 ? fabs(tk) : 1.0) < E)) break; /* an event first */
        while (p->t < tk) {
            while (g[j] <= p->t) j++;
            s = ex_step_n(r, p, g[j], p->g_u + (size_t)j * m, p->g_out[j], n, m, v, w, bs, dx, z);
            if (s) {
                *k = kk;
                *cursor = j;
                return s;
            }
            if (r->deadline > 0 && p->steps % EX_CLOCK_EVERY == 0 && check_clock(r)) {
                *k = kk;
                *cursor = j;
                set_message(r, "over its %g s wall-clock budget at t=%g", b->timeout, p->t);
                return RC_TIMEOUT;
            }
        }
        if (p->y_valid) {
            double *o = out + (size_t)kk * n_out;
            const double *y = p->slot[0] + n;
            for (s = 0; s < n_out; s++) {
                o[s] = y[s];
                if (!isfinite(y[s])) {
                    *k = kk;
                    *cursor = j;
                    set_message(r, "output %d is %g at t=%g", s, y[s], p->t);
                    return RC_NONFINITE;
                }
            }
        } else {
            break; /* the set's loop reads them */
        }
        kk++;
    }
    *k = kk;
    *cursor = j;
    return RC_OK;
}

/* The kernels: ex_step_n and ex_march_n for the small models this runner is for (loops of
 * known length, unrolled by the compiler), and for any size. */
#define EX_KERNEL(N, M_)                                                                                    \
    static __attribute__((noinline)) int ex_step_##N##_##M_(Runner *r, Plan *p, double tb, const double *ub, \
                                                              int with_out) {                               \
        double v[N], w[N], bs[N], dx[N], z[5 * N];                                                          \
        return ex_step_n(r, p, tb, ub, with_out, N, M_, v, w, bs, dx, z);                                  \
    }                                                                                                       \
    static __attribute__((noinline)) int ex_march_##N##_##M_(Runner *r, Plan *p, double E, double *out, int *k, \
                                                               int *cursor) {                               \
        double v[N], w[N], bs[N], dx[N], z[5 * N];                                                          \
        return ex_march_n(r, p, E, out, k, cursor, N, M_, v, w, bs, dx, z);                                \
    }
EX_KERNEL(1, 0) EX_KERNEL(2, 0) EX_KERNEL(3, 0) EX_KERNEL(4, 0) EX_KERNEL(5, 0) EX_KERNEL(6, 0)
EX_KERNEL(7, 0) EX_KERNEL(8, 0) EX_KERNEL(9, 0) EX_KERNEL(10, 0) EX_KERNEL(11, 0) EX_KERNEL(12, 0)
EX_KERNEL(1, 1) EX_KERNEL(2, 1) EX_KERNEL(3, 1) EX_KERNEL(4, 1) EX_KERNEL(5, 1) EX_KERNEL(6, 1)
EX_KERNEL(7, 1) EX_KERNEL(8, 1) EX_KERNEL(9, 1) EX_KERNEL(10, 1) EX_KERNEL(11, 1) EX_KERNEL(12, 1)
EX_KERNEL(1, 2) EX_KERNEL(2, 2) EX_KERNEL(3, 2) EX_KERNEL(4, 2) EX_KERNEL(5, 2) EX_KERNEL(6, 2)
EX_KERNEL(7, 2) EX_KERNEL(8, 2) EX_KERNEL(9, 2) EX_KERNEL(10, 2) EX_KERNEL(11, 2) EX_KERNEL(12, 2)
#undef EX_KERNEL

/* Any size: the step's vectors in the plan, apart from those ex_mend and ex_estimate use. */
static __attribute__((noinline)) int ex_step_any(Runner *r, Plan *p, double tb, const double *ub, int with_out) {
    return ex_step_n(r, p, tb, ub, with_out, p->n, p->m, p->kv, p->kw, p->kbs, p->kdx, p->kz);
}

static __attribute__((noinline)) int ex_march_any(Runner *r, Plan *p, double E, double *out, int *k, int *cursor) {
    return ex_march_n(r, p, E, out, k, cursor, p->n, p->m, p->kv, p->kw, p->kbs, p->kdx, p->kz);
}

typedef int (*ExStep)(Runner *, Plan *, double, const double *, int);
typedef int (*ExMarch)(Runner *, Plan *, double, double *, int *, int *);

#define EX_TABLE(F, M_) {F##_1_##M_, F##_2_##M_, F##_3_##M_, F##_4_##M_, F##_5_##M_, F##_6_##M_, F##_7_##M_, \
                         F##_8_##M_, F##_9_##M_, F##_10_##M_, F##_11_##M_, F##_12_##M_}

static void ex_kernels(Plan *p) {
    static const ExStep steps[3][EX_NMAX] = {EX_TABLE(ex_step, 0), EX_TABLE(ex_step, 1), EX_TABLE(ex_step, 2)};
    static const ExMarch marches[3][EX_NMAX] = {EX_TABLE(ex_march, 0), EX_TABLE(ex_march, 1),
                                               EX_TABLE(ex_march, 2)};
    if (p->n >= 1 && p->n <= EX_NMAX && p->m <= 2) {
        p->kernel = steps[p->m][p->n - 1];
        p->march = marches[p->m][p->n - 1];
    } else {
        p->kernel = ex_step_any;
        p->march = ex_march_any;
    }
}
#undef EX_TABLE

static int ex_step(Runner *r, Plan *p, double tb, const double *ub, int with_out) {
    return p->kernel(r, p, tb, ub, with_out);
}

/* ---- one set ---- */

/* The current point evaluated afresh (start, events): no history for the next step. */
static int ex_restart(Runner *r, Plan *p) {
    int i;
    if (ex_eval(r, p, p->t, p->x, p->u, p->slot[0], 1)) {
        set_message(r, "the model could not be evaluated at t=%g%s%s", p->t, r->fmu_log[0] ? ": " : "", r->fmu_log);
        return RC_FMI;
    }
    p->y_valid = p->combined;
    p->has_prev = 0;
    for (i = 0; i < p->n; i++) p->gdot[i] = 0.0;
    for (i = 0; i < p->m; i++) p->su[i] = 0.0;
    return RC_OK;
}

/* From the current point to T, through the grid points up to it. Returns RC_OK, a
 * status, or -1: go on with CVODE from the current point. */
static int ex_advance(Runner *r, Plan *p, double T, int *cursor) {
    int s;
    while (p->t < T) {
        int j = *cursor;
        while (j < p->n_grid && p->g[j] <= p->t) j++;
        *cursor = j;
        if (j < p->n_grid && p->g[j] <= T) {
            s = ex_step(r, p, p->g[j], p->g_u + (size_t)j * p->m, p->g_out[j]);
        } else { /* a time event between grid points */
            if (p->m) input_at(r, T, p->ut);
            s = ex_step(r, p, T, p->ut, 0);
        }
        if (s) return s;
        if (r->deadline > 0 && p->steps % EX_CLOCK_EVERY == 0 && check_clock(r)) {
            set_message(r, "over its %g s wall-clock budget at t=%g", r->b->timeout, p->t);
            return RC_TIMEOUT;
        }
    }
    return RC_OK;
}

/* runner.c's handle_event without CVODE: the states after it, and a restart. */
static int ex_event(Runner *r, Plan *p, double t, int *has_event, double *t_event) {
    int s;
    FMI(r->fmi.enter_event_mode(r->c), "fmi2EnterEventMode");
    if (set_inputs(r, t)) { set_message(r, "setting inputs failed at t=%g", t); return RC_FMI; }
    if ((s = update_discrete(r, has_event, t_event))) return s;
    FMI(r->fmi.enter_continuous(r->c), "fmi2EnterContinuousTimeMode");
    FMI(r->fmi.get_states(r->c, p->x, (size_t)p->n), "fmi2GetContinuousStates");
    if (p->m) input_at(r, t, p->u);
    p->t = t;
    return ex_restart(r, p);
}

/* Go on with CVODE from the plan's current point (at its own tolerance: the compiled
 * runner's accuracy for the rest of the set). */
static int ex_to_cvode(Runner *r, Plan *p, double *t) {
    ex_restore(r, p);
    *t = p->t;
    p->counters[EX_SWITCHED]++;
    return reinit(r, p->t);
}

/* run_set (runner.c) with the exponential integrator between events; CVODE from where the
 * integrator gives up (ex_to_cvode). */
static int ex_run_set(Runner *r, Plan *p, const double *params, double *out, double *t_reached) {
    const Batch *b = r->b;
    int has_event = 0, k, i, s, step_row, cvode = 0, cursor = 0, all_real = 1;
    double t_event = 0.0, t = b->start_time, max_step;
    for (k = 0; k < b->n_out; k++) all_real &= b->out_types[k] == 0;
    *t_reached = t;
    if (!r->fresh) FMI(r->fmi.reset(r->c), "fmi2Reset");
    r->fresh = 0;
    r->limit_row = -1;
    r->cursor = 0;
    FMI(r->fmi.setup_experiment(r->c, fmi2False, 0.0, b->start_time, fmi2False, 0.0), "fmi2SetupExperiment");
    FMI(set_parameters(r, b, params), "setting the parameters");
    if (set_inputs(r, t)) { set_message(r, "setting inputs failed at the start"); return RC_FMI; }
    if (p->m) input_at(r, t, p->u); /* the values just set */
    FMI(r->fmi.enter_init(r->c), "fmi2EnterInitializationMode");
    FMI(r->fmi.exit_init(r->c), "fmi2ExitInitializationMode");
    if ((s = update_discrete(r, &has_event, &t_event))) return STOPPED(s, 0, t);
    FMI(r->fmi.enter_continuous(r->c), "fmi2EnterContinuousTimeMode");
    if ((s = fmi3_tolerances(r))) return s;
    if (r->version == 3) { /* the tolerances may have changed: CVODE's over a step with them */
        const double *a = r->sun.N_VGetArrayPointer(r->abstol);
        double *tight = r->sun.N_VGetArrayPointer(p->abstol_tight);
        for (i = 0; i < r->n_dim; i++) tight[i] = EX_TOL * a[i];
    }
    max_step = (b->times[b->n_times - 1] - b->start_time) / 50.0;
    if (r->span[0] != b->start_time || r->span[1] != b->times[b->n_times - 1]) {
        r->sun.CVodeSetMaxStep(r->mem, max_step);
        r->span[0] = b->start_time;
        r->span[1] = b->times[b->n_times - 1];
    }
    step_row = b->n_inputs ? next_input_step(r, t) : -1;
    r->limit_row = step_row;
    p->counters[EX_SETS]++;
    p->steps = p->relins = 0;
    p->miss_bits = 0;
    p->t = t;
    FMI(r->fmi.get_states(r->c, p->x, (size_t)p->n), "fmi2GetContinuousStates");
    if ((s = ex_restart(r, p))) return s;
    if (p->combined && !p->checked) { /* fmi2GetReal must give what fmi2GetDerivatives gives, bit for bit */
        int same = r->fmi.get_derivatives(r->c, p->col, (size_t)p->n) < fmi2Error;
        for (i = 0; i < p->n && same; i++) same = p->col[i] == p->slot[0][i];
        p->checked = 1;
        if (!same) {
            p->combined = 0;
            if ((s = ex_restart(r, p))) return s;
        }
    }
    p->atol = r->sun.N_VGetArrayPointer(r->abstol);
    p->tol_floor = INFINITY;
    for (i = 0; i < p->n; i++) p->tol_floor = fmin(p->tol_floor, EX_TOL * p->atol[i]);
    if (ex_linearise(r, p)) {
        p->counters[EX_SETS_CVODE]++;
        p->counters[EX_SWITCHED]--;
        if ((s = ex_to_cvode(r, p, &t))) return s;
        cvode = 1;
    }
    k = 0;
    while (k < b->n_times) {
        double tk, reach;
        if (!cvode) { /* through the grid until an event is due */
            double ts = step_row >= 0 ? b->input_time[step_row] : INFINITY;
            double te = has_event ? t_event : INFINITY;
            s = p->march(r, p, te < ts ? te : ts, out, &k, &cursor);
            *t_reached = t = p->t;
            if (s == -1) {
                if ((s = ex_to_cvode(r, p, &t))) return s;
                cvode = 1;
            }
            if (s) return s;
            if (k >= b->n_times) break;
        }
        tk = b->times[k];
        reach = tk + 1e-12 * (fabs(tk) > 1.0 ? fabs(tk) : 1.0);
        for (;;) { /* time events up to tk: the FMU's and the input's steps, earliest first */
            double ts = step_row >= 0 ? b->input_time[step_row] : INFINITY;
            double te = has_event ? t_event : INFINITY;
            double next = te < ts ? te : ts;
            if (!(next <= reach)) break;
            if (next > t) {
                if (!cvode) {
                    s = ex_advance(r, p, next, &cursor);
                    t = p->t;
                    if (s == -1) {
                        if ((s = ex_to_cvode(r, p, &t))) return s;
                        cvode = 1;
                    }
                    if (s) return s;
                }
                if (cvode && next > t && (s = advance(r, next, &t, &has_event, &t_event))) return STOPPED(s, k, t);
            }
            if (ts <= next) r->limit_row = step_row = next_input_step(r, ts); /* the step is taken now */
            if (cvode) {
                if ((s = handle_event(r, t, &has_event, &t_event))) return STOPPED(s, k, t);
            } else if ((s = ex_event(r, p, t, &has_event, &t_event))) {
                return STOPPED(s, k, t);
            }
        }
        if (tk > t) {
            if (!cvode) {
                s = ex_advance(r, p, tk, &cursor);
                t = p->t;
                if (s == -1) {
                    if ((s = ex_to_cvode(r, p, &t))) return s;
                    cvode = 1;
                }
                if (s) return s;
            }
            if (cvode && tk > t && (s = advance(r, tk, &t, &has_event, &t_event))) return STOPPED(s, k, t);
        }
        *t_reached = t;
        if (!cvode && p->y_valid) {
            double *o = out + (size_t)k * b->n_out;
            const double *y = p->slot[0] + p->n;
            for (s = 0; s < b->n_out; s++) {
                o[s] = y[s];
                if (!isfinite(y[s])) {
                    set_message(r, "output %d is %g at t=%g", s, y[s], t);
                    return RC_NONFINITE;
                }
            }
        } else {
            if (b->n_inputs && set_inputs(r, t)) { set_message(r, "setting inputs failed at t=%g", t); return RC_FMI; }
            if (all_real) {
                FMI(r->fmi.get_real(r->c, b->out_vrs, (size_t)b->n_out, out + (size_t)k * b->n_out), "fmi2GetReal");
                for (s = 0; s < b->n_out; s++)
                    if (!isfinite(out[(size_t)k * b->n_out + s])) {
                        set_message(r, "output %d is %g at t=%g", s, out[(size_t)k * b->n_out + s], t);
                        return RC_NONFINITE;
                    }
            } else if ((s = read_outputs(r, out + (size_t)k * b->n_out))) {
                return s;
            }
        }
        if (cvode && check_clock(r)) {
            set_message(r, "over its %g s wall-clock budget at t=%g", b->timeout, t);
            return RC_TIMEOUT;
        }
        k++;
    }
    r->fmi.terminate(r->c);
    return RC_OK;
}

/* rc_run with the exponential integrator: same arguments, and the batch's plan. FMUs it
 * does not apply to (event indicators, no states) run every set through rc_run. */
static int exp_set(Runner *r, void *plan, const double *params, double *out, double *t_reached) {
    return ex_run_set(r, (Plan *)plan, params, out, t_reached);
}

RC_EXPORT int rc_run_exp(Runner *r, const Batch *b, Plan *p, double *out, int *status, double *t_reached,
                         char *messages) {
    if (r->n_indicators > 0 || r->n_states == 0) {
        p->counters[EX_SETS_CVODE] += b->n_sets;
        return rc_run(r, b, out, status, t_reached, messages);
    }
    if (b->n_inputs > 64 || b->n_inputs != p->m || r->n_states != p->n) return -2;
    return run_batch(r, b, exp_set, p, out, status, t_reached, messages);
}

/* c = a b by the sized products where they apply (plain = 0) or the plain loop (plain = 1):
 * for the tests, which check the two give the same numbers. */
RC_EXPORT void rc_mat_mul(int n, const double *a, const double *b, double *c, int plain) {
    (plain ? mat_mul_plain : mat_mul)(n, a, b, c);
}

/* The plan's counters (see EX_SETS ...), summed over its calls. */

RC_EXPORT int rc_plan_counters(Plan *p, long long *counters) {
    memcpy(counters, p->counters, sizeof(p->counters));
    return EX_N_COUNTERS;
}
