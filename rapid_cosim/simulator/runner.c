/* rapid-cosim batch runner: many parameter sets through one FMI 2.0 Model Exchange FMU,
 * integrated with CVODE, without returning to Python between sets, steps or samples.
 *
 * Why C: a calibration simulates the same model thousands of times. Driven from
 * Python, every right-hand side is a ctypes callback and every output sample a Python
 * call; here the whole batch is one call.
 *
 * Both libraries are opened with dlopen, so this file links against neither:
 *   - the FMU's shared library (any FMI 2.0 ME binary: the embedded compiler's,
 *     OpenModelica's or another tool's);
 *   - SUNDIALS 7, the build that fmpy ships (the same binary the Python reference loop
 *     uses, so both paths run the same CVODE). Its headers are not shipped, so the few
 *     functions used are declared below from the SUNDIALS 7 API; rc_open checks the
 *     library's major version before using any of them.
 *
 * Per set (the sequence of the Python reference loop, rapid_cosim/simulator/reference.py,
 * so that both take the same solver steps): reset, setupExperiment, parameters, inputs at
 * the start, initialisation, event iteration, continuous-time mode; then for each output
 * time: time events (the FMU's nextEventTime and steps of the input table) up to it,
 * CVODE (BDF, dense LU) to it, outputs read. The states at an output time come from the
 * interpolating polynomial of CVODE's step, evaluated here (advance_smooth): the values
 * CVODE's own dense output gives, up to rounding, at a fraction of the cost.
 * State events: CVODE root-finding on the FMU's event indicators (in CV_NORMAL mode, so
 * roots are sought only up to each output time), then event iteration and
 * re-initialisation as the FMI 2.0 standard describes; a step event requested by
 * fmi2CompletedIntegratorStep too.
 *
 * Inputs: a table (rows of time and values, non-decreasing time) interpolated linearly;
 * a time written twice is a step, taken as a time event. While CVODE integrates towards
 * a step it may evaluate the model past it, so there the input keeps its value before
 * the step (as the FMU's own conditions only switch in event mode).
 *
 * Failures stay with their set: a CVODE failure, an FMI error, a non-finite output or a
 * set over its wall-clock budget gets a status and a message; the instance is reset (or
 * re-instantiated) and the batch goes on. A model that asks to terminate (terminateSimulation
 * at an event or a completed step) ends its set there: the outputs at the times before
 * (and at) that moment stand, the rest are NaN, with the status "terminated"; one that
 * stops at or after the last output time has given every output and its set is ok.
 *
 * FMI 3.0 Model Exchange FMUs run through the same code: rc_open(fmi_version 3) fills the
 * function table with adapters (fmi3_* below) that have FMI 2.0's shape and call the FMI 3.0
 * functions (fmi3_table.h), one indirect call more per FMI call. The instance handle is then
 * the adapter's record. Output types FMI 2.0 has not (Float32, the sized integers) are
 * read through get_typed.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"
#include "fmi3_table.h"

#define RC_EXPORT __attribute__((visibility("default")))

/* ---- SUNDIALS 7 declarations (sunrealtype = double, sunindextype = int64_t) ---- */
typedef void *SUNContext;
typedef void *N_Vector;
typedef void *SUNMatrix;
typedef void *SUNLinearSolver;
typedef int (*CVRhsFn)(double t, N_Vector y, N_Vector ydot, void *user_data);
typedef int (*CVRootFn)(double t, N_Vector y, double *gout, void *user_data);
typedef void (*SUNErrHandlerFn)(int line, const char *func, const char *file, const char *msg, int err_code,
                                void *err_user_data, SUNContext ctx);
#define CV_BDF 2
#define CV_NORMAL 1
#define CV_ONE_STEP 2
#define CV_ROOT_RETURN 2
#define MAX_ORDER 5 /* BDF */
#define MAX_STEPS 5000 /* per output interval, as CVODE's own mxstep in CV_NORMAL mode */

typedef struct {
    int (*SUNDIALSGetVersionNumber)(int *, int *, int *, char *, int);
    int (*SUNContext_Create)(int, SUNContext *);
    int (*SUNContext_Free)(SUNContext *);
    int (*SUNContext_ClearErrHandlers)(SUNContext);
    int (*SUNContext_PushErrHandler)(SUNContext, SUNErrHandlerFn, void *);
    N_Vector (*N_VNew_Serial)(long long, SUNContext);
    int (*N_VEnableFusedOps_Serial)(N_Vector, int);
    double *(*N_VGetArrayPointer)(N_Vector);
    void (*N_VDestroy)(N_Vector);
    SUNMatrix (*SUNDenseMatrix)(long long, long long, SUNContext);
    void (*SUNMatDestroy)(SUNMatrix);
    SUNLinearSolver (*SUNLinSol_Dense)(N_Vector, SUNMatrix, SUNContext);
    int (*SUNLinSolFree)(SUNLinearSolver);
    void *(*CVodeCreate)(int, SUNContext);
    int (*CVodeInit)(void *, CVRhsFn, double, N_Vector);
    int (*CVodeReInit)(void *, double, N_Vector);
    int (*CVodeSVtolerances)(void *, double, N_Vector);
    int (*CVodeSetLinearSolver)(void *, SUNLinearSolver, SUNMatrix);
    int (*CVodeSetMaxStep)(void *, double);
    int (*CVodeSetMaxNumSteps)(void *, long);
    int (*CVodeSetUserData)(void *, void *);
    int (*CVodeRootInit)(void *, int, CVRootFn);
    int (*CVodeGetRootInfo)(void *, int *);
    int (*CVodeSetNoInactiveRootWarn)(void *);
    int (*CVode)(void *, double, N_Vector, double *, int);
    int (*CVodeGetDky)(void *, double, int, N_Vector);
    int (*CVodeGetLastOrder)(void *, int *);
    int (*CVodeGetLastStep)(void *, double *);
    void (*CVodeFree)(void **);
} Sundials;

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2ResetTYPE *reset;
    fmi2TerminateTYPE *terminate;
    fmi2SetRealTYPE *set_real;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_integer;
    fmi2GetBooleanTYPE *get_boolean;
    fmi2SetIntegerTYPE *set_integer; /* FMI 2.0 only (flag parameters); NULL for FMI 3.0 */
    fmi2SetBooleanTYPE *set_boolean;
    fmi2SetTimeTYPE *set_time;
    fmi2SetContinuousStatesTYPE *set_states;
    fmi2GetContinuousStatesTYPE *get_states;
    fmi2GetDerivativesTYPE *get_derivatives;
    fmi2GetEventIndicatorsTYPE *get_event_indicators;
    fmi2GetNominalsOfContinuousStatesTYPE *get_nominals;
    fmi2EnterEventModeTYPE *enter_event_mode;
    fmi2NewDiscreteStatesTYPE *new_discrete_states;
    fmi2EnterContinuousTimeModeTYPE *enter_continuous;
    fmi2CompletedIntegratorStepTYPE *completed_step;
    /* an output of an FMI 3.0 type code (fmi3_table.h; elem: an array element's offset
     * and size) as a double; FMI 3.0 only */
    fmi2Status (*get_typed)(fmi2Component c, int code, fmi2ValueReference vr, const int *elem, double *value);
} Fmi2;

/* Set status codes (mirrored in rapid_cosim/simulator/compiled.py). */
enum { RC_OK = 0, RC_SOLVER = 1, RC_FMI = 2, RC_NONFINITE = 3, RC_TIMEOUT = 4, RC_TERMINATED = 5 };

#define MSG_LEN 256

/* One batch: what rc_run reads. Arrays are row-major. */
typedef struct {
    int n_sets;
    int n_params;
    const fmi2ValueReference *param_vrs;
    const double *param_values; /* n_sets x n_params */
    int n_times;
    const double *times;
    int n_out;
    const fmi2ValueReference *out_vrs;
    const int *out_types; /* 0 Real, 1 Integer, 2 Boolean; FMI 3.0: the codes of fmi3_table.h */
    int n_inputs;
    const fmi2ValueReference *input_vrs;
    int n_rows;
    const double *input_time;   /* n_rows */
    const double *input_values; /* n_rows x n_inputs */
    double start_time;
    double timeout; /* seconds per set; <= 0: none */
    const int *out_elem; /* n_out x 2: an array element's offset and array size (NULL: none) */
    const int *param_types; /* n_params: 0 Real, 1 Integer, 2 Boolean (FMI 2.0 flags); NULL: all Real */
} Batch;

typedef struct {
    Sundials sun;
    Fmi2 fmi;
    Fmi3 fmi3;   /* FMI 3.0: the FMU's functions, which the adapters in fmi call */
    int version; /* 2 or 3 */
    void *fmu_lib;
    void *sun_libs[5];
    fmi2CallbackFunctions callbacks;
    char *instance_name, *guid, *resource_uri;
    fmi2Component c;
    int fresh;
    int n_states, n_dim, n_indicators;
    double rtol;
    SUNContext ctx;
    void *mem;
    N_Vector x, abstol;
    double *px;
    SUNMatrix matrix;
    SUNLinearSolver solver;
    N_Vector dky;
    double span[2];
    /* CVODE has integrated to tn; zn holds the interpolating polynomial of its last step
     * (order q, step hu): y(t) = sum_j zn[j] ((t - tn) / hu)^j on [tn - hu, tn]. */
    double tn, hu;
    int q, has_step;
    double *zn;
    int *root_info;
    double *indicators;
    /* the set being run */
    const Batch *b;
    int limit_row; /* first row of the next input step, -1 if none ahead */
    int cursor;    /* last input row at or before the time of the latest lookup */
    double deadline;
    int timed_out;
    unsigned rhs_calls; /* the clock is read every CLOCK_EVERY right-hand sides, not on each */
    char message[MSG_LEN];
    char fmu_log[MSG_LEN];
    int fmi_failed;
    int rows_done; /* output rows a terminated set gave */
} Runner;

static void set_message(Runner *r, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(r->message, MSG_LEN, fmt, ap);
    va_end(ap);
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- callbacks ---- */

static void fmu_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                       fmi2String message, ...) {
    Runner *r = (Runner *)env;
    va_list ap;
    (void)name; (void)category;
    if (!r || status < fmi2Warning) return;
    va_start(ap, message);
    vsnprintf(r->fmu_log, MSG_LEN, message, ap);
    va_end(ap);
}

static void sundials_error(int line, const char *func, const char *file, const char *msg, int err_code,
                           void *err_user_data, SUNContext ctx) {
    Runner *r = (Runner *)err_user_data;
    (void)line; (void)file; (void)ctx;
    if (r && !r->timed_out) set_message(r, "%s: %s (flag %d)", func ? func : "CVODE", msg ? msg : "", err_code);
}

/* Input values at t, honouring the clamp before the next step (see the file comment).
 * The row is found by walking from the last one looked up: the solver's times move
 * little between calls. */
static void input_at(Runner *r, double t, double *u) {
    const Batch *b = r->b;
    const double *tt = b->input_time;
    int n = b->n_rows, k = b->n_inputs, i = r->cursor, j;
    if (r->limit_row >= 0 && t >= tt[r->limit_row]) {
        memcpy(u, b->input_values + (size_t)r->limit_row * k, k * sizeof(double));
        return;
    }
    if (tt[i] <= t) {
        while (i + 1 < n && tt[i + 1] <= t) i++;
    } else {
        while (i > 0 && tt[i] > t) i--;
    }
    r->cursor = i; /* the last row with time <= t, or row 0 when t is before the table */
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

static int set_inputs(Runner *r, double t) {
    double u[64];
    int k = r->b->n_inputs;
    if (!k) return 0;
    input_at(r, t, u);
    return r->fmi.set_real(r->c, r->b->input_vrs, (size_t)k, u) >= fmi2Error;
}

#define CLOCK_EVERY 32u

static int check_clock(Runner *r) {
    if (r->deadline > 0 && now() > r->deadline) r->timed_out = 1;
    return r->timed_out;
}

static int rhs(double t, N_Vector y, N_Vector ydot, void *user_data) {
    Runner *r = (Runner *)user_data;
    double *dx = r->sun.N_VGetArrayPointer(ydot);
    /* unrecoverable: CVODE returns at once. The clock is read every CLOCK_EVERY calls: read
     * on each, it took 3 % of a fleet unit's time (a deadline is seconds, a call microseconds) */
    if (r->timed_out || ((++r->rhs_calls % CLOCK_EVERY) == 0 && check_clock(r))) return -1;
    if (!r->n_states) {
        dx[0] = 0.0;
        return 0;
    }
    if (r->fmi.set_time(r->c, t) >= fmi2Error || set_inputs(r, t)
        || r->fmi.set_states(r->c, r->sun.N_VGetArrayPointer(y), (size_t)r->n_states) >= fmi2Error
        || r->fmi.get_derivatives(r->c, dx, (size_t)r->n_states) >= fmi2Error)
        return 1; /* recoverable: CVODE retries with a smaller step */
    return 0;
}

static int roots(double t, N_Vector y, double *g, void *user_data) {
    Runner *r = (Runner *)user_data;
    if (r->fmi.set_time(r->c, t) >= fmi2Error || set_inputs(r, t)
        || (r->n_states && r->fmi.set_states(r->c, r->sun.N_VGetArrayPointer(y), (size_t)r->n_states) >= fmi2Error)
        || r->fmi.get_event_indicators(r->c, g, (size_t)r->n_indicators) >= fmi2Error)
        return -1;
    return 0;
}

/* ---- opening ---- */

static void *sym(void *lib, const char *name, char *err, int err_len) {
    void *p = dlsym(lib, name);
    if (!p && err[0] == 0) snprintf(err, err_len, "symbol %s not found", name);
    return p;
}

static int load_sundials(Runner *r, const char *const paths[5], char *err, int err_len) {
    Sundials *s = &r->sun;
    int i, major = 0, minor = 0, patch = 0;
    char label[32] = "";
    for (i = 0; i < 5; i++) {
        r->sun_libs[i] = dlopen(paths[i], RTLD_NOW | RTLD_LOCAL);
        if (!r->sun_libs[i]) {
            snprintf(err, err_len, "cannot load SUNDIALS library %s: %s", paths[i], dlerror());
            return 1;
        }
    }
#define CORE(f) *(void **)(&s->f) = sym(r->sun_libs[0], #f, err, err_len)
#define NVEC(f) *(void **)(&s->f) = sym(r->sun_libs[1], #f, err, err_len)
#define MAT(f) *(void **)(&s->f) = sym(r->sun_libs[2], #f, err, err_len)
#define LS(f) *(void **)(&s->f) = sym(r->sun_libs[3], #f, err, err_len)
#define CV(f) *(void **)(&s->f) = sym(r->sun_libs[4], #f, err, err_len)
    CORE(SUNDIALSGetVersionNumber); CORE(SUNContext_Create); CORE(SUNContext_Free);
    CORE(SUNContext_ClearErrHandlers); CORE(SUNContext_PushErrHandler); CORE(N_VGetArrayPointer);
    CORE(N_VDestroy); CORE(SUNMatDestroy); CORE(SUNLinSolFree);
    NVEC(N_VNew_Serial); NVEC(N_VEnableFusedOps_Serial);
    MAT(SUNDenseMatrix);
    LS(SUNLinSol_Dense);
    CV(CVodeCreate); CV(CVodeInit); CV(CVodeReInit); CV(CVodeSVtolerances); CV(CVodeSetLinearSolver);
    CV(CVodeSetMaxStep); CV(CVodeSetMaxNumSteps); CV(CVodeSetUserData); CV(CVodeRootInit);
    CV(CVodeGetRootInfo); CV(CVodeSetNoInactiveRootWarn); CV(CVode); CV(CVodeFree);
    CV(CVodeGetDky); CV(CVodeGetLastOrder); CV(CVodeGetLastStep);
#undef CORE
#undef NVEC
#undef MAT
#undef LS
#undef CV
    if (err[0]) return 1;
    s->SUNDIALSGetVersionNumber(&major, &minor, &patch, label, (int)sizeof(label));
    if (major != 7) {
        snprintf(err, err_len, "SUNDIALS %d.%d.%d found; the runner is written for SUNDIALS 7", major, minor, patch);
        return 1;
    }
    return 0;
}

/* ---- FMI 3.0 Model Exchange through FMI 2.0's shape ---- */

typedef struct {
    fmi3Instance inst;
    const Fmi3 *f;
    double start;
} Fmi3Adapter;

#define A3(c) ((Fmi3Adapter *)(c))
#define I3(c) (A3(c)->inst)
#define F3(c) (A3(c)->f)

static void fmi3_logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    Runner *r = (Runner *)env;
    (void)category;
    if (r && status >= fmi3Warning) snprintf(r->fmu_log, MSG_LEN, "%s", message ? message : "");
}
static fmi2Component fmi3_instantiate(fmi2String name, fmi2Type type, fmi2String token, fmi2String resources,
                                      const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    Runner *r = (Runner *)cb->componentEnvironment;
    Fmi3Adapter *a = calloc(1, sizeof(Fmi3Adapter));
    (void)type;
    if (!a) return NULL;
    a->f = &r->fmi3;
    a->inst = r->fmi3.instantiate_me(name, token, resources, visible != 0, logging != 0, r, fmi3_logger);
    if (!a->inst) {
        free(a);
        return NULL;
    }
    return a;
}
static void fmi3_free_instance(fmi2Component c) {
    F3(c)->free_instance(I3(c));
    free(c);
}
static fmi2Status fmi3_setup_experiment(fmi2Component c, fmi2Boolean tol_defined, fmi2Real tol, fmi2Real start,
                                        fmi2Boolean stop_defined, fmi2Real stop) {
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    A3(c)->start = start;
    return fmi2OK;
}
static fmi2Status fmi3_enter_init(fmi2Component c) {
    return (fmi2Status)F3(c)->enter_init(I3(c), false, 0.0, A3(c)->start, false, 0.0);
}
static fmi2Status fmi3_exit_init(fmi2Component c) { return (fmi2Status)F3(c)->exit_init(I3(c)); }
static fmi2Status fmi3_reset(fmi2Component c) { return (fmi2Status)F3(c)->reset(I3(c)); }
static fmi2Status fmi3_terminate(fmi2Component c) { return (fmi2Status)F3(c)->terminate(I3(c)); }
static fmi2Status fmi3_set_real(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    return (fmi2Status)F3(c)->set_float64(I3(c), vr, n, v, n);
}
static fmi2Status fmi3_get_real(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    return (fmi2Status)F3(c)->get_float64(I3(c), vr, n, v, n);
}
static fmi2Status fmi3_get_integer(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) {
    size_t k;
    for (k = 0; k < n; k++) {
        fmi3Int32 x = 0;
        fmi3Status s = F3(c)->get_int32(I3(c), &vr[k], 1, &x, 1);
        if (s >= fmi3Error) return (fmi2Status)s;
        v[k] = x;
    }
    return fmi2OK;
}
static fmi2Status fmi3_get_boolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) {
    size_t k;
    for (k = 0; k < n; k++) {
        fmi3Boolean x = 0;
        fmi3Status s = F3(c)->get_boolean(I3(c), &vr[k], 1, &x, 1);
        if (s >= fmi3Error) return (fmi2Status)s;
        v[k] = x ? fmi2True : fmi2False;
    }
    return fmi2OK;
}
static fmi2Status fmi3_get_typed(fmi2Component c, int code, fmi2ValueReference vr, const int *elem,
                                 double *value) {
    return (fmi2Status)fmi3_read_output(F3(c), I3(c), code, vr, elem, value);
}
static fmi2Status fmi3_set_time(fmi2Component c, fmi2Real t) { return (fmi2Status)F3(c)->set_time(I3(c), t); }
static fmi2Status fmi3_set_states(fmi2Component c, const fmi2Real x[], size_t n) {
    return (fmi2Status)F3(c)->set_states(I3(c), x, n);
}
static fmi2Status fmi3_get_states(fmi2Component c, fmi2Real x[], size_t n) {
    return (fmi2Status)F3(c)->get_states(I3(c), x, n);
}
static fmi2Status fmi3_get_derivatives(fmi2Component c, fmi2Real dx[], size_t n) {
    return (fmi2Status)F3(c)->get_derivatives(I3(c), dx, n);
}
static fmi2Status fmi3_get_event_indicators(fmi2Component c, fmi2Real z[], size_t n) {
    return (fmi2Status)F3(c)->get_event_indicators(I3(c), z, n);
}
static fmi2Status fmi3_get_nominals(fmi2Component c, fmi2Real x[], size_t n) {
    return (fmi2Status)F3(c)->get_nominals(I3(c), x, n);
}
static fmi2Status fmi3_enter_event_mode(fmi2Component c) { return (fmi2Status)F3(c)->enter_event_mode(I3(c)); }
static fmi2Status fmi3_new_discrete_states(fmi2Component c, fmi2EventInfo *info) {
    fmi3Boolean need = false, terminate = false, nominals = false, values = false, defined = false;
    fmi3Float64 next = 0.0;
    fmi3Status s = F3(c)->update_discrete(I3(c), &need, &terminate, &nominals, &values, &defined, &next);
    info->newDiscreteStatesNeeded = need ? fmi2True : fmi2False;
    info->terminateSimulation = terminate ? fmi2True : fmi2False;
    info->nominalsOfContinuousStatesChanged = nominals ? fmi2True : fmi2False;
    info->valuesOfContinuousStatesChanged = values ? fmi2True : fmi2False;
    info->nextEventTimeDefined = defined ? fmi2True : fmi2False;
    info->nextEventTime = next;
    return (fmi2Status)s;
}
static fmi2Status fmi3_enter_continuous(fmi2Component c) { return (fmi2Status)F3(c)->enter_continuous(I3(c)); }
static fmi2Status fmi3_completed_step(fmi2Component c, fmi2Boolean nosp, fmi2Boolean *enter, fmi2Boolean *term) {
    fmi3Boolean e = false, t = false;
    fmi3Status s = F3(c)->completed_step(I3(c), nosp != 0, &e, &t);
    *enter = e ? fmi2True : fmi2False;
    *term = t ? fmi2True : fmi2False;
    return (fmi2Status)s;
}

static int load_fmu3(Runner *r, char *err, int err_len) {
    Fmi2 *f = &r->fmi;
    if (fmi3_load(r->fmu_lib, &r->fmi3, 1, err, err_len)) return 1;
    f->instantiate = fmi3_instantiate; f->free_instance = fmi3_free_instance;
    f->setup_experiment = fmi3_setup_experiment; f->enter_init = fmi3_enter_init; f->exit_init = fmi3_exit_init;
    f->reset = fmi3_reset; f->terminate = fmi3_terminate; f->set_real = fmi3_set_real; f->get_real = fmi3_get_real;
    f->get_integer = fmi3_get_integer; f->get_boolean = fmi3_get_boolean; f->set_time = fmi3_set_time;
    f->set_integer = NULL; f->set_boolean = NULL; /* refused before a run (fmu.py): FMI 3.0 sets Float64 only */
    f->set_states = fmi3_set_states; f->get_states = fmi3_get_states; f->get_derivatives = fmi3_get_derivatives;
    f->get_event_indicators = fmi3_get_event_indicators; f->get_nominals = fmi3_get_nominals;
    f->enter_event_mode = fmi3_enter_event_mode; f->new_discrete_states = fmi3_new_discrete_states;
    f->enter_continuous = fmi3_enter_continuous; f->completed_step = fmi3_completed_step;
    f->get_typed = fmi3_get_typed;
    return 0;
}

static int load_fmu(Runner *r, const char *path, char *err, int err_len) {
    Fmi2 *f = &r->fmi;
    r->fmu_lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!r->fmu_lib) {
        snprintf(err, err_len, "cannot load the FMU binary %s: %s", path, dlerror());
        return 1;
    }
    if (r->version == 3) return load_fmu3(r, err, err_len);
#define F(field, name) *(void **)(&f->field) = sym(r->fmu_lib, name, err, err_len)
    F(instantiate, "fmi2Instantiate"); F(free_instance, "fmi2FreeInstance");
    F(setup_experiment, "fmi2SetupExperiment"); F(enter_init, "fmi2EnterInitializationMode");
    F(exit_init, "fmi2ExitInitializationMode"); F(reset, "fmi2Reset"); F(terminate, "fmi2Terminate");
    F(set_real, "fmi2SetReal"); F(get_real, "fmi2GetReal"); F(get_integer, "fmi2GetInteger");
    F(get_boolean, "fmi2GetBoolean"); F(set_integer, "fmi2SetInteger"); F(set_boolean, "fmi2SetBoolean");
    F(set_time, "fmi2SetTime"); F(set_states, "fmi2SetContinuousStates");
    F(get_states, "fmi2GetContinuousStates"); F(get_derivatives, "fmi2GetDerivatives");
    F(get_event_indicators, "fmi2GetEventIndicators"); F(get_nominals, "fmi2GetNominalsOfContinuousStates");
    F(enter_event_mode, "fmi2EnterEventMode"); F(new_discrete_states, "fmi2NewDiscreteStates");
    F(enter_continuous, "fmi2EnterContinuousTimeMode"); F(completed_step, "fmi2CompletedIntegratorStep");
#undef F
    return err[0] != 0;
}

static int instantiate(Runner *r) {
    r->c = r->fmi.instantiate(r->instance_name, fmi2ModelExchange, r->guid, r->resource_uri, &r->callbacks,
                              fmi2False, fmi2False);
    r->fresh = 1;
    return r->c == NULL;
}

static char *copy(const char *s) {
    size_t n = strlen(s ? s : "") + 1;
    char *out = malloc(n);
    if (out) memcpy(out, s ? s : "", n);
    return out;
}

RC_EXPORT void rc_close(Runner *r);

/* The FMU instantiated once and CVODE set up once; rc_run re-initialises both per set. */
RC_EXPORT Runner *rc_open(const char *fmu_binary, const char *instance_name, const char *guid,
                          const char *resource_uri, int n_states, int n_indicators, double rtol,
                          const char *const sundials_paths[5], char *err, int err_len, int fmi_version) {
    Runner *r = calloc(1, sizeof(Runner));
    int i;
    double *tol;
    double nominals[1024];
    err[0] = 0;
    if (!r) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    if (n_states > 1024) {
        snprintf(err, err_len, "%d states; the runner handles up to 1024", n_states);
        free(r);
        return NULL;
    }
    r->n_states = n_states;
    r->version = fmi_version == 3 ? 3 : 2;
    r->n_dim = n_states > 0 ? n_states : 1; /* CVODE needs one state; a stateless model gets a dummy */
    r->n_indicators = n_indicators;
    r->rtol = rtol;
    r->instance_name = copy(instance_name);
    r->guid = copy(guid);
    r->resource_uri = copy(resource_uri);
    r->callbacks.logger = fmu_logger;
    r->callbacks.allocateMemory = calloc;
    r->callbacks.freeMemory = free;
    r->callbacks.componentEnvironment = r;
    r->limit_row = -1;
    if (load_sundials(r, sundials_paths, err, err_len) || load_fmu(r, fmu_binary, err, err_len)) goto fail;
    if (instantiate(r)) {
        snprintf(err, err_len, "%s failed%s%s", r->version == 3 ? "fmi3InstantiateModelExchange" : "fmi2Instantiate",
                 r->fmu_log[0] ? ": " : "", r->fmu_log);
        goto fail;
    }
    if (r->sun.SUNContext_Create(0, &r->ctx)) { snprintf(err, err_len, "SUNContext_Create failed"); goto fail; }
    r->sun.SUNContext_ClearErrHandlers(r->ctx);
    r->sun.SUNContext_PushErrHandler(r->ctx, sundials_error, r);
    r->x = r->sun.N_VNew_Serial(r->n_dim, r->ctx);
    r->abstol = r->sun.N_VNew_Serial(r->n_dim, r->ctx);
    /* Fused vector operations: CVODE's vectors are cloned from x, so its interpolation at
     * each output time is one loop instead of a chain of generic vector calls. */
    r->sun.N_VEnableFusedOps_Serial(r->x, 1);
    r->dky = r->sun.N_VNew_Serial(r->n_dim, r->ctx);
    r->zn = calloc((size_t)(MAX_ORDER + 2) * r->n_dim, sizeof(double)); /* + one row: the value at t */
    if (!r->x || !r->abstol || !r->dky || !r->zn) {
        snprintf(err, err_len, "out of memory");
        goto fail;
    }
    r->px = r->sun.N_VGetArrayPointer(r->x);
    tol = r->sun.N_VGetArrayPointer(r->abstol);
    for (i = 0; i < r->n_dim; i++) nominals[i] = 1.0;
    if (n_states && r->version == 2) r->fmi.get_nominals(r->c, nominals, (size_t)n_states); /* FMI 3.0: per set */
    for (i = 0; i < r->n_dim; i++) tol[i] = rtol * fabs(nominals[i]);
    for (i = 0; i < r->n_dim; i++) r->px[i] = 0.0;
    r->mem = r->sun.CVodeCreate(CV_BDF, r->ctx);
    if (!r->mem || r->sun.CVodeInit(r->mem, rhs, 0.0, r->x) || r->sun.CVodeSVtolerances(r->mem, rtol, r->abstol)) {
        snprintf(err, err_len, "setting up CVODE failed");
        goto fail;
    }
    r->matrix = r->sun.SUNDenseMatrix(r->n_dim, r->n_dim, r->ctx);
    r->solver = r->sun.SUNLinSol_Dense(r->x, r->matrix, r->ctx);
    if (r->sun.CVodeSetLinearSolver(r->mem, r->solver, r->matrix) || r->sun.CVodeSetMaxNumSteps(r->mem, 5000)
        || r->sun.CVodeSetUserData(r->mem, r)) {
        snprintf(err, err_len, "setting up CVODE's linear solver failed");
        goto fail;
    }
    if (n_indicators > 0) {
        r->root_info = calloc((size_t)n_indicators, sizeof(int));
        r->indicators = calloc((size_t)n_indicators, sizeof(double));
        if (r->sun.CVodeRootInit(r->mem, n_indicators, roots)) {
            snprintf(err, err_len, "CVodeRootInit failed");
            goto fail;
        }
        r->sun.CVodeSetNoInactiveRootWarn(r->mem);
    }
    r->span[0] = r->span[1] = NAN;
    return r;
fail:
    rc_close(r);
    return NULL;
}

RC_EXPORT void rc_close(Runner *r) {
    int i;
    if (!r) return;
    if (r->mem) r->sun.CVodeFree(&r->mem);
    if (r->solver) r->sun.SUNLinSolFree(r->solver);
    if (r->matrix) r->sun.SUNMatDestroy(r->matrix);
    if (r->x) r->sun.N_VDestroy(r->x);
    if (r->abstol) r->sun.N_VDestroy(r->abstol);
    if (r->dky) r->sun.N_VDestroy(r->dky);
    free(r->zn);
    if (r->ctx) r->sun.SUNContext_Free(&r->ctx);
    if (r->c) r->fmi.free_instance(r->c);
    if (r->fmu_lib) dlclose(r->fmu_lib);
    for (i = 0; i < 5; i++)
        if (r->sun_libs[i]) dlclose(r->sun_libs[i]);
    free(r->root_info);
    free(r->indicators);
    free(r->instance_name);
    free(r->guid);
    free(r->resource_uri);
    free(r);
}

/* ---- one set ---- */

/* One set's parameters, each by its type (Batch.param_types): an FMU's Integer or Boolean
 * flag (GGOV1's Rselect) set through fmi2SetReal would be refused, or, by an FMU that
 * indexes its Reals by value reference, silently set another variable. */
static fmi2Status set_parameters(Runner *r, const Batch *b, const double *params) {
    fmi2Status s, worst = fmi2OK;
    int k;
    if (!b->n_params) return fmi2OK;
    if (!b->param_types) return r->fmi.set_real(r->c, b->param_vrs, (size_t)b->n_params, params);
    for (k = 0; k < b->n_params; k++) {
        if (b->param_types[k] == 1 && r->fmi.set_integer) {
            fmi2Integer v = (fmi2Integer)lround(params[k]); /* as the Python loops round it */
            s = r->fmi.set_integer(r->c, &b->param_vrs[k], 1, &v);
        } else if (b->param_types[k] == 2 && r->fmi.set_boolean) {
            fmi2Boolean v = params[k] != 0.0 ? fmi2True : fmi2False;
            s = r->fmi.set_boolean(r->c, &b->param_vrs[k], 1, &v);
        } else if (b->param_types[k] == 0) {
            s = r->fmi.set_real(r->c, &b->param_vrs[k], 1, &params[k]);
        } else {
            s = fmi2Error;
        }
        if (s > worst) worst = s;
    }
    return worst;
}

#define FMI(call, what)                                                                  \
    do {                                                                                 \
        if ((call) >= fmi2Error) {                                                       \
            set_message(r, "%s failed%s%s", what, r->fmu_log[0] ? ": " : "", r->fmu_log); \
            return RC_FMI;                                                               \
        }                                                                                \
    } while (0)

/* An FMI 3.0 FMU's absolute tolerances (rtol times its states' nominals), taken per set
 * once initialised, as fmpy takes them: FMI 3.0 allows fmi3GetNominalsOfContinuousStates
 * only from Initialization Mode on, and a strict FMU (the standard's Reference FMUs) logs
 * an illegal call sequence before it and refuses every call after. FMI 2.0 allows it once
 * instantiated: rc_open takes them there. */
static int fmi3_tolerances(Runner *r) {
    double nominals[1024], *tol;
    int i, changed = 0;
    if (r->version != 3 || !r->n_states) return RC_OK;
    FMI(r->fmi.get_nominals(r->c, nominals, (size_t)r->n_states), "fmi3GetNominalsOfContinuousStates");
    tol = r->sun.N_VGetArrayPointer(r->abstol);
    for (i = 0; i < r->n_states; i++) {
        double a = r->rtol * fabs(nominals[i]);
        if (a != tol[i]) {
            tol[i] = a;
            changed = 1;
        }
    }
    if (changed && r->sun.CVodeSVtolerances(r->mem, r->rtol, r->abstol)) {
        set_message(r, "CVodeSVtolerances failed");
        return RC_SOLVER;
    }
    return RC_OK;
}

/* Event iteration (FMI 2.0, section 3.2.2): until no new discrete states are needed. */
static int update_discrete(Runner *r, int *has_event, double *t_event) {
    fmi2EventInfo info;
    info.newDiscreteStatesNeeded = fmi2True;
    info.terminateSimulation = fmi2False;
    while (info.newDiscreteStatesNeeded) {
        FMI(r->fmi.new_discrete_states(r->c, &info), "fmi2NewDiscreteStates");
        if (info.terminateSimulation) return RC_TERMINATED; /* the caller says where (terminated) */
    }
    *has_event = info.nextEventTimeDefined != fmi2False;
    *t_event = info.nextEventTime;
    return RC_OK;
}

static int reinit(Runner *r, double t) {
    if (r->n_states) FMI(r->fmi.get_states(r->c, r->px, (size_t)r->n_states), "fmi2GetContinuousStates");
    else r->px[0] = 0.0;
    if (r->sun.CVodeReInit(r->mem, t, r->x)) {
        set_message(r, "CVodeReInit failed at t=%g", t);
        return RC_SOLVER;
    }
    r->tn = t;
    r->has_step = 0;
    return RC_OK;
}

/* An event at the current time: event mode, iteration, back to continuous time. */
static int handle_event(Runner *r, double t, int *has_event, double *t_event) {
    int s;
    FMI(r->fmi.enter_event_mode(r->c), "fmi2EnterEventMode");
    if (set_inputs(r, t)) { set_message(r, "setting inputs failed at t=%g", t); return RC_FMI; }
    if ((s = update_discrete(r, has_event, t_event))) return s;
    FMI(r->fmi.enter_continuous(r->c), "fmi2EnterContinuousTimeMode");
    return reinit(r, t);
}

/* The first row of the next input step strictly after t, or -1. */
static int next_input_step(const Runner *r, double t) {
    const Batch *b = r->b;
    int i;
    for (i = 0; i + 1 < b->n_rows; i++)
        if (b->input_time[i] == b->input_time[i + 1] && b->input_time[i] > t) return i;
    return -1;
}

static int solver_failure(Runner *r, int flag, double t_ret) {
    if (r->timed_out) {
        set_message(r, "over its %g s wall-clock budget at t=%g", r->b->timeout, t_ret);
        return RC_TIMEOUT;
    }
    if (!r->message[0]) {
        set_message(r, "CVODE failed (flag %d) near t=%g", flag, t_ret);
    } else {
        char detail[MSG_LEN];
        memcpy(detail, r->message, MSG_LEN);
        set_message(r, "CVODE failed near t=%g: %s", t_ret, detail);
    }
    return RC_SOLVER;
}

/* Without event indicators: CVODE steps (CV_ONE_STEP) until it passes t_out, and the
 * interpolating polynomial of its last step, taken once per step, gives the states at
 * t_out. It is the polynomial CVODE's own dense output (CV_NORMAL) evaluates, so the
 * steps and the values are those of the reference loop up to rounding; the cost per
 * output time is a few multiplications instead of a solver call. */
#define CLOSE (64.0 * 2.220446049250313e-16) /* relative: an output time within rounding of the last reinit */
static int too_close(double t, double t_out) { return t_out - t <= CLOSE * fmax(fabs(t), fabs(t_out)); }

static int advance_smooth(Runner *r, double t_out, double *t) {
    int n = r->n_dim, steps = 0, j, i, flag;
    double *y = r->zn + (size_t)(MAX_ORDER + 1) * n, t_ret, scale, s;
    while (r->tn < t_out && (r->has_step || !too_close(r->tn, t_out))) { /* a first step that short: refused (advance) */
        flag = r->sun.CVode(r->mem, t_out, r->x, &t_ret, CV_ONE_STEP);
        if (flag < 0) return solver_failure(r, flag, t_ret);
        if (++steps > MAX_STEPS) {
            set_message(r, "more than %d solver steps between output times near t=%g", MAX_STEPS, t_ret);
            return RC_SOLVER;
        }
        r->tn = t_ret;
        r->sun.CVodeGetLastOrder(r->mem, &r->q);
        r->sun.CVodeGetLastStep(r->mem, &r->hu);
        memcpy(r->zn, r->px, n * sizeof(double));
        scale = 1.0;
        for (j = 1; j <= r->q; j++) { /* the j-th derivative at tn times hu^j / j! */
            const double *d;
            r->sun.CVodeGetDky(r->mem, t_ret, j, r->dky);
            d = r->sun.N_VGetArrayPointer(r->dky);
            scale *= r->hu / j;
            for (i = 0; i < n; i++) r->zn[(size_t)j * n + i] = d[i] * scale;
        }
        r->has_step = 1;
    }
    if (r->has_step && t_out != r->tn) {
        s = (t_out - r->tn) / r->hu;
        for (i = 0; i < n; i++) {
            double v = r->zn[(size_t)r->q * n + i];
            for (j = r->q - 1; j >= 0; j--) v = v * s + r->zn[(size_t)j * n + i];
            y[i] = v;
        }
    } else {
        memcpy(y, r->has_step ? r->zn : r->px, n * sizeof(double));
    }
    if (r->n_states) FMI(r->fmi.set_states(r->c, y, (size_t)r->n_states), "fmi2SetContinuousStates");
    FMI(r->fmi.set_time(r->c, t_out), "fmi2SetTime");
    *t = t_out;
    return RC_OK;
}

/* With event indicators: CV_NORMAL to t_out, so that CVODE looks for roots only up to
 * t_out; state events and step events met on the way are handled. An event within
 * rounding of t_out (CLOSE) ends the step there: CVODE, reinitialised at the event, refuses
 * a first step that short ("tout too close to t0", which failed a fleet unit's plot on its
 * fine grid), and the states move by nothing in it. */
static int advance(Runner *r, double t_out, double *t, int *has_event, double *t_event) {
    if (!r->n_indicators) return advance_smooth(r, t_out, t);
    while (*t < t_out) {
        double t_ret = *t;
        if (too_close(*t, t_out)) {
            FMI(r->fmi.set_time(r->c, t_out), "fmi2SetTime");
            *t = t_out;
            break;
        }
        int flag = r->sun.CVode(r->mem, t_out, r->x, &t_ret, CV_NORMAL), s;
        fmi2Boolean enter = fmi2False, terminate = fmi2False;
        if (flag < 0) return solver_failure(r, flag, t_ret);
        if (r->n_states) FMI(r->fmi.set_states(r->c, r->px, (size_t)r->n_states), "fmi2SetContinuousStates");
        FMI(r->fmi.set_time(r->c, t_ret), "fmi2SetTime");
        *t = t_ret;
        if (flag == CV_ROOT_RETURN) {
            if (set_inputs(r, t_ret)) { set_message(r, "setting inputs failed at t=%g", t_ret); return RC_FMI; }
            if ((s = handle_event(r, t_ret, has_event, t_event))) return s;
            continue;
        }
        FMI(r->fmi.completed_step(r->c, fmi2True, &enter, &terminate), "fmi2CompletedIntegratorStep");
        if (terminate) return RC_TERMINATED;
        if (enter && (s = handle_event(r, t_ret, has_event, t_event))) return s;
        break;
    }
    return RC_OK;
}

static int read_outputs(Runner *r, double *row) {
    const Batch *b = r->b;
    int j;
    for (j = 0; j < b->n_out; j++) {
        fmi2ValueReference vr = b->out_vrs[j];
        if (b->out_types[j] == 0) {
            FMI(r->fmi.get_real(r->c, &vr, 1, &row[j]), "fmi2GetReal");
        } else if (b->out_types[j] == 1) {
            fmi2Integer v;
            FMI(r->fmi.get_integer(r->c, &vr, 1, &v), "fmi2GetInteger");
            row[j] = (double)v;
        } else if (b->out_types[j] == 2) {
            fmi2Boolean v;
            FMI(r->fmi.get_boolean(r->c, &vr, 1, &v), "fmi2GetBoolean");
            row[j] = v ? 1.0 : 0.0;
        } else {
            if (!r->fmi.get_typed) { set_message(r, "output %d has an FMI 3.0 type", j); return RC_FMI; }
            FMI(r->fmi.get_typed(r->c, b->out_types[j], vr, b->out_elem ? b->out_elem + 2 * j : NULL, &row[j]),
                "fmi3Get (typed output)");
        }
        if (!isfinite(row[j])) {
            set_message(r, "output %d is %g", j, row[j]);
            return RC_NONFINITE;
        }
    }
    return RC_OK;
}

/* The model asked to terminate at t while the runner worked towards output row k: the rows
 * before k stand, and row k too if t is its time (the values as the model holds them). */
static int terminated(Runner *r, int k, double t, double *out) {
    const Batch *b = r->b;
    char log[MSG_LEN];
    memcpy(log, r->fmu_log, MSG_LEN);
    r->rows_done = k;
    if (k < b->n_times && t >= b->times[k] - 1e-12 * fmax(1.0, fabs(b->times[k]))) {
        if (!(b->n_inputs && set_inputs(r, t)) && read_outputs(r, out + (size_t)k * b->n_out) == RC_OK)
            r->rows_done = k + 1;
    }
    set_message(r, "the model asked to terminate at t=%g%s%s", t, log[0] ? ": " : "", log);
    return RC_TERMINATED;
}

/* A status from a step of run_set while working towards row k at time t. */
#define STOPPED(s, k, t) ((s) == RC_TERMINATED ? terminated(r, (k), (t), out) : (s))

static int run_set(Runner *r, const double *params, double *out, double *t_reached) {
    const Batch *b = r->b;
    int has_event = 0, k, s, all_real = 1, step_row;
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
    FMI(r->fmi.enter_init(r->c), "fmi2EnterInitializationMode");
    FMI(r->fmi.exit_init(r->c), "fmi2ExitInitializationMode");
    if ((s = update_discrete(r, &has_event, &t_event))) return STOPPED(s, 0, t);
    FMI(r->fmi.enter_continuous(r->c), "fmi2EnterContinuousTimeMode");
    if ((s = fmi3_tolerances(r))) return s;
    max_step = (b->times[b->n_times - 1] - b->start_time) / 50.0;
    if (r->span[0] != b->start_time || r->span[1] != b->times[b->n_times - 1]) {
        r->sun.CVodeSetMaxStep(r->mem, max_step);
        r->span[0] = b->start_time;
        r->span[1] = b->times[b->n_times - 1];
    }
    if ((s = reinit(r, t))) return s;
    step_row = b->n_inputs ? next_input_step(r, t) : -1;
    r->limit_row = step_row;
    for (k = 0; k < b->n_times; k++) {
        double tk = b->times[k], reach = tk + 1e-12 * fmax(1.0, fabs(tk));
        for (;;) { /* time events up to tk: the FMU's and the input's steps, earliest first */
            double ts = step_row >= 0 ? b->input_time[step_row] : INFINITY;
            double te = has_event ? t_event : INFINITY;
            double next = te < ts ? te : ts;
            if (!(next <= reach)) break;
            if (next > t && (s = advance(r, next, &t, &has_event, &t_event))) return STOPPED(s, k, t);
            if (ts <= next) r->limit_row = step_row = next_input_step(r, ts); /* the step is taken now */
            if ((s = handle_event(r, t, &has_event, &t_event))) return STOPPED(s, k, t);
        }
        if (tk > t && (s = advance(r, tk, &t, &has_event, &t_event))) return STOPPED(s, k, t);
        *t_reached = t;
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
        if (check_clock(r)) {
            set_message(r, "over its %g s wall-clock budget at t=%g", b->timeout, t);
            return RC_TIMEOUT;
        }
    }
    r->fmi.terminate(r->c);
    return RC_OK;
}

/* A new instance in place of the current one. */
static void renew(Runner *r) {
    r->fmi.free_instance(r->c);
    r->c = NULL;
    instantiate(r);
}

/* After a failure the instance may be in any state: reset it, or make a new one. */
static void recover(Runner *r) {
    if (r->fmi.reset(r->c) < fmi2Error) {
        r->fresh = 1;
        return;
    }
    renew(r);
}

/* After a set: a failure's outputs are NaN and the instance recovers; a terminated set keeps
 * the rows it gave (NaN after them), and is ok if it gave them all. */
static int finish_set(Runner *r, int status, double *o) {
    const Batch *b = r->b;
    size_t per_row = (size_t)b->n_out, j;
    if (status == RC_OK) return RC_OK;
    if (status == RC_TERMINATED) {
        for (j = (size_t)r->rows_done * per_row; j < (size_t)b->n_times * per_row; j++) o[j] = NAN;
        r->fmi.terminate(r->c);
        /* the next set on a new instance: the standard's Reference FMUs keep their
         * terminateSimulation through fmi2Reset / fmi3Reset */
        renew(r);
        if (r->rows_done >= b->n_times) {
            r->message[0] = 0;
            return RC_OK;
        }
        return RC_TERMINATED;
    }
    for (j = 0; j < (size_t)b->n_times * per_row; j++) o[j] = NAN;
    recover(r);
    return status;
}

/* One set's integration: run_set below, or the exponential runner's (expint.c). */
typedef int (*SetRun)(Runner *r, void *ctx, const double *params, double *out, double *t_reached);

/* Every set of the batch through `one`, each with its own deadline, status and message.
 * out: n_sets x n_times x n_out (NaN after a failure, or after the rows a terminated set
 * gave); status and t_reached: one per set; messages: n_sets x MSG_LEN. Returns the number
 * of failed sets, or -1 if the instance could not be re-created (the rest then fail). */
static int run_batch(Runner *r, const Batch *b, SetRun one, void *ctx, double *out, int *status,
                     double *t_reached, char *messages) {
    int i, failed = 0;
    size_t per_set = (size_t)b->n_times * b->n_out, j;
    r->b = b;
    for (i = 0; i < b->n_sets; i++) {
        double *o = out + per_set * i;
        r->message[0] = 0;
        r->fmu_log[0] = 0;
        r->timed_out = 0;
        if (!r->c) {
            status[i] = RC_FMI;
            snprintf(messages + (size_t)MSG_LEN * i, MSG_LEN, "the FMU could not be instantiated again");
            for (j = 0; j < per_set; j++) o[j] = NAN;
            failed++;
            continue;
        }
        r->deadline = b->timeout > 0 ? now() + b->timeout : 0.0;
        status[i] = finish_set(r, one(r, ctx, b->param_values + (size_t)b->n_params * i, o, &t_reached[i]), o);
        memcpy(messages + (size_t)MSG_LEN * i, r->message, MSG_LEN);
        if (status[i] != RC_OK) failed++;
    }
    r->b = NULL;
    return r->c ? failed : -1;
}

static int cvode_set(Runner *r, void *ctx, const double *params, double *out, double *t_reached) {
    (void)ctx;
    return run_set(r, params, out, t_reached);
}

/* Run every set of the batch with CVODE (see run_batch). */
RC_EXPORT int rc_run(Runner *r, const Batch *b, double *out, int *status, double *t_reached, char *messages) {
    if (b->n_inputs > 64) return -2;
    return run_batch(r, b, cvode_set, NULL, out, status, t_reached, messages);
}

RC_EXPORT int rc_msg_len(void) { return MSG_LEN; }
