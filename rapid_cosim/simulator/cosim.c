/* rapid-cosim Co-Simulation driver: many parameter sets through one FMI 2.0 or 3.0
 * Co-Simulation FMU (the exporting tool's solver inside), without returning to Python
 * between sets or communication steps. It sits beside the Model Exchange runner
 * (runner.c, expint.c) in the same library and keeps its conventions: one instance made
 * once and reset per set, a status and a message per set, NaN outputs after a failure,
 * a wall-clock budget per set.
 *
 * Why C (measured, see rapid_cosim/simulator/cosim.py): driven through fmpy's FMU2Slave /
 * FMU3Slave, every communication step costs some 10 to 20 microseconds of Python (the
 * inputs set, fmi2DoStep, the outputs read, fmpy's status checks); a calibration makes
 * hundreds of steps per simulation and thousands of simulations.
 *
 * Everything about time is decided in Python (cosim.py) and arrives in the batch: the
 * communication points c[0] = start < c[1] < ... (the output times and the input table's
 * rows for an FMU that can handle a variable communication step size, a fixed step
 * otherwise), the input values set at each point (after a step of the table written
 * twice) and their derivatives over the step (FMI 2.0 canInterpolateInputs), which points'
 * outputs are read, and for each output time the point at or after it with a weight
 * (1 on the grid; else linear between the point before and it, for a fixed step off the
 * output times). FMI 3.0 FMUs that provide intermediate update get the table itself: the
 * FMU asks for its inputs at its own intermediate times (intermediateUpdate callback,
 * intermediateVariableSetRequested) and is given the table's value just before that time.
 *
 * Per set (FMI 2.0): reset, fmi2SetupExperiment (tolerance, start, stop), parameters,
 * initialisation mode, inputs at the start, exit; then per step the inputs (and their
 * derivatives), fmi2DoStep(c[j], c[j+1] - c[j]) and the outputs at c[j+1] when needed.
 * FMI 3.0: reset, parameters, fmi3EnterInitializationMode (tolerance, start, stop), inputs,
 * exit (Step Mode: no event mode, no early return), fmi3DoStep per step.
 *
 * A terminate request (FMI 2.0: fmi2DoStep returns fmi2Discard and fmi2GetBooleanStatus
 * (fmi2Terminated) says so, with fmi2LastSuccessfulTime; FMI 3.0: fmi3DoStep's
 * terminateSimulation and lastSuccessfulTime) ends the set there: outputs at the points
 * reached stand, the rest are NaN; status "terminated" unless every output was given.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2FunctionTypes.h"
#include "fmi3_table.h"

#define RC_EXPORT __attribute__((visibility("default")))

/* Set status codes, as runner.c's (mirrored in rapid_cosim/simulator/compiled.py). */
enum { CS_OK = 0, CS_SOLVER = 1, CS_FMI = 2, CS_NONFINITE = 3, CS_TIMEOUT = 4, CS_TERMINATED = 5 };

#define MSG_LEN 256
#define MAX_INPUTS 64

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
    fmi2SetIntegerTYPE *set_integer; /* flag parameters */
    fmi2SetBooleanTYPE *set_boolean;
    fmi2DoStepTYPE *do_step;
    fmi2SetRealInputDerivativesTYPE *set_input_derivatives;
    fmi2GetBooleanStatusTYPE *get_boolean_status;
    fmi2GetRealStatusTYPE *get_real_status;
} Cs2;

/* One batch: what cs_run reads (see the file comment). Arrays are row-major. */
typedef struct {
    int n_sets;
    int n_params;
    const unsigned *param_vrs;
    const double *param_values; /* n_sets x n_params */
    int n_times;
    const double *times;
    int n_out;
    const unsigned *out_vrs;
    const int *out_types; /* fmi3_table.h's codes (FMI 2.0: 0 Real, 1 Integer, 2 Boolean) */
    int n_inputs;
    const unsigned *input_vrs;
    int n_rows;
    const double *input_time;   /* the table: n_rows */
    const double *input_values; /* n_rows x n_inputs */
    int n_comm;
    const double *comm;  /* communication points, n_comm */
    const double *steps; /* c[j + 1] - c[j] as given to doStep, n_comm - 1 */
    const double *u;     /* inputs set at c[j], (n_comm - 1) x n_inputs */
    const double *du;    /* their derivatives over the step (interpolation 1), or NULL */
    const int *read;     /* n_comm: read the outputs at c[j] */
    const int *out_comm; /* n_times: the point at or after each output time */
    const double *out_w; /* n_times: its weight (1: the point's values) */
    double start_time, stop_time, timeout, tolerance;
    int interpolation; /* 0 held, 1 FMI 2.0 input derivatives, 2 FMI 3.0 intermediate update */
    const int *out_elem; /* n_out x 2: an array element's offset and array size (NULL: none) */
    const int *param_types; /* n_params: 0 Real, 1 Integer, 2 Boolean (FMI 2.0 flags); NULL: all Real */
} CsBatch;

typedef struct {
    int version;
    void *lib;
    Cs2 f2;
    Fmi3 f3;
    fmi2CallbackFunctions callbacks;
    char *instance_name, *token, *resources;
    void *c;
    int fresh;
    int intermediate; /* FMI 3.0: instantiated with the intermediate-update callback */
    unsigned required[MAX_INPUTS];
    int n_required;
    const CsBatch *b;
    int cursor;
    double deadline;
    int rows_done;
    char message[MSG_LEN];
    char fmu_log[MSG_LEN];
    double *cur, *prev; /* outputs at the latest point read and the one before */
    int cap;
} CsRunner;

static void set_message(CsRunner *r, const char *fmt, ...) {
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

static char *copy(const char *s) {
    size_t n = strlen(s ? s : "") + 1;
    char *out = malloc(n);
    if (out) memcpy(out, s ? s : "", n);
    return out;
}

/* ---- callbacks ---- */

static void logger2(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                    fmi2String message, ...) {
    CsRunner *r = (CsRunner *)env;
    va_list ap;
    (void)name; (void)category;
    if (!r || status < fmi2Warning) return;
    va_start(ap, message);
    vsnprintf(r->fmu_log, MSG_LEN, message, ap);
    va_end(ap);
}

static void logger3(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    CsRunner *r = (CsRunner *)env;
    (void)category;
    if (r && status >= fmi3Warning) snprintf(r->fmu_log, MSG_LEN, "%s", message ? message : "");
}

/* The table's values just before t (a step written at t keeps its value before it);
 * held before the first row and after the last. Walks from the last row looked up. */
/* The table's value just before t, linear between rows (cosim.py's left_values, with its
 * arithmetic): a step written at t, or within TIME_TOL of it, keeps its value before. */
#define TIME_TOL(t) (1e-9 * (fabs(t) > 1.0 ? fabs(t) : 1.0))
static void input_before(CsRunner *r, double t, double *u) {
    const CsBatch *b = r->b;
    const double *tt = b->input_time;
    double s = t - TIME_TOL(t);
    int n = b->n_rows, k = b->n_inputs, i = r->cursor, j;
    if (n == 1 || s <= tt[0]) {
        memcpy(u, b->input_values, k * sizeof(double));
        return;
    }
    if (s > tt[n - 1]) {
        memcpy(u, b->input_values + (size_t)(n - 1) * k, k * sizeof(double));
        return;
    }
    if (i > n - 2) i = n - 2;
    if (i < 0) i = 0;
    while (i > 0 && tt[i] >= s) i--;
    while (i + 1 < n - 1 && tt[i + 1] < s) i++;
    r->cursor = i; /* tt[i] < s <= tt[i + 1] */
    {
        double w = (t - tt[i]) / (tt[i + 1] - tt[i]);
        const double *a = b->input_values + (size_t)i * k, *c = b->input_values + (size_t)(i + 1) * k;
        if (w < 0.0) w = 0.0;
        if (w > 1.0) w = 1.0;
        for (j = 0; j < k; j++) u[j] = a[j] + w * (c[j] - a[j]);
    }
}

static void intermediate_update(fmi3InstanceEnvironment env, fmi3Float64 t, fmi3Boolean set_requested,
                                fmi3Boolean get_allowed, fmi3Boolean step_finished, fmi3Boolean can_return_early,
                                fmi3Boolean *early_requested, fmi3Float64 *early_time) {
    CsRunner *r = (CsRunner *)env;
    double u[MAX_INPUTS];
    (void)get_allowed; (void)step_finished; (void)can_return_early; (void)early_time;
    if (early_requested) *early_requested = false;
    if (!r || !set_requested || !r->b || r->b->interpolation != 2 || !r->b->n_inputs || !r->c) return;
    input_before(r, t, u);
    r->f3.set_float64(r->c, r->b->input_vrs, (size_t)r->b->n_inputs, u, (size_t)r->b->n_inputs);
}

/* ---- opening ---- */

static void *sym(void *lib, const char *name, char *err, int err_len) {
    void *p = dlsym(lib, name);
    if (!p && err[0] == 0) snprintf(err, err_len, "symbol %s not found", name);
    return p;
}

static int load2(CsRunner *r, char *err, int err_len) {
    Cs2 *f = &r->f2;
#define F(field, name) *(void **)(&f->field) = sym(r->lib, name, err, err_len)
    F(instantiate, "fmi2Instantiate"); F(free_instance, "fmi2FreeInstance");
    F(setup_experiment, "fmi2SetupExperiment"); F(enter_init, "fmi2EnterInitializationMode");
    F(exit_init, "fmi2ExitInitializationMode"); F(reset, "fmi2Reset"); F(terminate, "fmi2Terminate");
    F(set_real, "fmi2SetReal"); F(get_real, "fmi2GetReal"); F(get_integer, "fmi2GetInteger");
    F(get_boolean, "fmi2GetBoolean"); F(set_integer, "fmi2SetInteger"); F(set_boolean, "fmi2SetBoolean");
    F(do_step, "fmi2DoStep");
    F(set_input_derivatives, "fmi2SetRealInputDerivatives"); F(get_boolean_status, "fmi2GetBooleanStatus");
    F(get_real_status, "fmi2GetRealStatus");
#undef F
    return err[0] != 0;
}

static int instantiate(CsRunner *r) {
    if (r->version == 3)
        r->c = r->f3.instantiate_cs(r->instance_name, r->token, r->resources, false, false, false, false,
                                    r->intermediate ? r->required : NULL, r->intermediate ? (size_t)r->n_required : 0,
                                    r, logger3, r->intermediate ? intermediate_update : NULL);
    else
        r->c = r->f2.instantiate(r->instance_name, fmi2CoSimulation, r->token, r->resources, &r->callbacks, fmi2False,
                                 fmi2False);
    r->fresh = 1;
    return r->c == NULL;
}

RC_EXPORT void cs_close(CsRunner *r);

/* The FMU's binary opened and one instance made. resources: the resource URI (FMI 2.0)
 * or path (FMI 3.0). intermediate (FMI 3.0): instantiate with the intermediate-update
 * callback, the inputs input_vrs being the variables set through it. */
RC_EXPORT CsRunner *cs_open(const char *binary, const char *instance_name, const char *token, const char *resources,
                            int fmi_version, int intermediate, const unsigned *input_vrs, int n_inputs, char *err,
                            int err_len) {
    CsRunner *r = calloc(1, sizeof(CsRunner));
    int i;
    err[0] = 0;
    if (!r) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    if (n_inputs > MAX_INPUTS) {
        snprintf(err, err_len, "%d inputs; the driver handles up to %d", n_inputs, MAX_INPUTS);
        free(r);
        return NULL;
    }
    r->version = fmi_version == 3 ? 3 : 2;
    r->intermediate = r->version == 3 && intermediate && n_inputs > 0;
    r->n_required = n_inputs;
    for (i = 0; i < n_inputs; i++) r->required[i] = input_vrs[i];
    r->instance_name = copy(instance_name);
    r->token = copy(token);
    r->resources = copy(resources);
    r->callbacks.logger = logger2;
    r->callbacks.allocateMemory = calloc;
    r->callbacks.freeMemory = free;
    r->callbacks.componentEnvironment = r;
    r->lib = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (!r->lib) {
        snprintf(err, err_len, "cannot load the FMU binary %s: %s", binary, dlerror());
        goto fail;
    }
    if (r->version == 3 ? fmi3_load(r->lib, &r->f3, 0, err, err_len) : load2(r, err, err_len)) goto fail;
    if (instantiate(r)) {
        snprintf(err, err_len, "%s failed%s%s", r->version == 3 ? "fmi3InstantiateCoSimulation" : "fmi2Instantiate",
                 r->fmu_log[0] ? ": " : "", r->fmu_log);
        goto fail;
    }
    return r;
fail:
    cs_close(r);
    return NULL;
}

static void free_instance(CsRunner *r) {
    if (!r->c) return;
    if (r->version == 3) r->f3.free_instance(r->c);
    else r->f2.free_instance(r->c);
    r->c = NULL;
}

RC_EXPORT void cs_close(CsRunner *r) {
    if (!r) return;
    free_instance(r);
    if (r->lib) dlclose(r->lib);
    free(r->instance_name);
    free(r->token);
    free(r->resources);
    free(r->cur);
    free(r->prev);
    free(r);
}

/* ---- one set ---- */

/* One set's parameters on an FMI 2.0 FMU, each by its type (CsBatch.param_types): a flag
 * is set as the Integer or Boolean it is declared. */
static fmi2Status set_parameters2(CsRunner *r, const CsBatch *b, const double *params) {
    fmi2Status s, worst = fmi2OK;
    int k;
    if (!b->n_params) return fmi2OK;
    if (!b->param_types) return r->f2.set_real(r->c, b->param_vrs, (size_t)b->n_params, params);
    for (k = 0; k < b->n_params; k++) {
        if (b->param_types[k] == 1) {
            fmi2Integer v = (fmi2Integer)lround(params[k]); /* as the Python loops round it */
            s = r->f2.set_integer(r->c, &b->param_vrs[k], 1, &v);
        } else if (b->param_types[k] == 2) {
            fmi2Boolean v = params[k] != 0.0 ? fmi2True : fmi2False;
            s = r->f2.set_boolean(r->c, &b->param_vrs[k], 1, &v);
        } else {
            s = r->f2.set_real(r->c, &b->param_vrs[k], 1, &params[k]);
        }
        if (s > worst) worst = s;
    }
    return worst;
}

#define FMI(call, what)                                                                  \
    do {                                                                                 \
        if ((int)(call) >= 3) { /* fmi2Error / fmi3Error or worse */                     \
            set_message(r, "%s failed%s%s", what, r->fmu_log[0] ? ": " : "", r->fmu_log); \
            return CS_FMI;                                                               \
        }                                                                                \
    } while (0)

static int set_inputs(CsRunner *r, const double *u) {
    const CsBatch *b = r->b;
    if (!b->n_inputs) return 0;
    if (r->version == 3) return r->f3.set_float64(r->c, b->input_vrs, (size_t)b->n_inputs, u, (size_t)b->n_inputs) >= fmi3Error;
    return r->f2.set_real(r->c, b->input_vrs, (size_t)b->n_inputs, u) >= fmi2Error;
}

/* The outputs now into r->cur. */
static int read_outputs(CsRunner *r, int all_real, double t) {
    const CsBatch *b = r->b;
    int j;
    if (all_real) {
        if (r->version == 3) FMI(r->f3.get_float64(r->c, b->out_vrs, (size_t)b->n_out, r->cur, (size_t)b->n_out), "fmi3GetFloat64");
        else FMI(r->f2.get_real(r->c, b->out_vrs, (size_t)b->n_out, r->cur), "fmi2GetReal");
    } else {
        for (j = 0; j < b->n_out; j++) {
            unsigned vr = b->out_vrs[j];
            int code = b->out_types[j];
            if (r->version == 3) {
                FMI(fmi3_read_output(&r->f3, r->c, code, vr, b->out_elem ? b->out_elem + 2 * j : NULL, &r->cur[j]),
                    "fmi3Get (output)");
            } else if (code == 0) {
                FMI(r->f2.get_real(r->c, &vr, 1, &r->cur[j]), "fmi2GetReal");
            } else if (code == 1) {
                fmi2Integer v = 0;
                FMI(r->f2.get_integer(r->c, &vr, 1, &v), "fmi2GetInteger");
                r->cur[j] = (double)v;
            } else if (code == 2) {
                fmi2Boolean v = 0;
                FMI(r->f2.get_boolean(r->c, &vr, 1, &v), "fmi2GetBoolean");
                r->cur[j] = v ? 1.0 : 0.0;
            } else {
                set_message(r, "output %d has a type FMI 2.0 has not", j);
                return CS_FMI;
            }
        }
    }
    for (j = 0; j < b->n_out; j++)
        if (!isfinite(r->cur[j])) {
            set_message(r, "output %d is %g at t=%g", j, r->cur[j], t);
            return CS_NONFINITE;
        }
    return CS_OK;
}

/* The output rows whose point is j, from r->cur (and r->prev, the point before). */
static void fill_rows(CsRunner *r, int j, double *out) {
    const CsBatch *b = r->b;
    int k = r->rows_done, m;
    while (k < b->n_times && b->out_comm[k] == j) {
        double w = b->out_w[k], *row = out + (size_t)k * b->n_out;
        if (w == 1.0) {
            memcpy(row, r->cur, b->n_out * sizeof(double));
        } else {
            for (m = 0; m < b->n_out; m++) {
                int code = b->out_types[m] & ~RC_ELEMENT, real = code == 0 || code == 3;
                row[m] = real ? r->prev[m] + w * (r->cur[m] - r->prev[m]) : r->prev[m];
            }
        }
        k++;
    }
    r->rows_done = k;
}

static int take_point(CsRunner *r, int j, int all_real, double *out) {
    int s;
    double *swap = r->prev;
    r->prev = r->cur;
    r->cur = swap;
    if ((s = read_outputs(r, all_real, r->b->comm[j]))) return s;
    fill_rows(r, j, out);
    return CS_OK;
}

static int run_set(CsRunner *r, const double *params, double *out, double *t_reached) {
    const CsBatch *b = r->b;
    int j, s, all_real = 1, k = b->n_inputs;
    static const fmi2Integer orders[MAX_INPUTS] = {
        1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1,
        1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
    for (j = 0; j < b->n_out; j++) all_real &= b->out_types[j] == 0;
    *t_reached = b->start_time;
    r->rows_done = 0;
    r->cursor = 0;
    if (r->version == 3) {
        if (!r->fresh) FMI(r->f3.reset(r->c), "fmi3Reset");
        r->fresh = 0;
        if (b->n_params)
            FMI(r->f3.set_float64(r->c, b->param_vrs, (size_t)b->n_params, params, (size_t)b->n_params),
                "fmi3SetFloat64 (parameters)");
        FMI(r->f3.enter_init(r->c, true, b->tolerance, b->start_time, true, b->stop_time), "fmi3EnterInitializationMode");
        if (set_inputs(r, b->u)) { set_message(r, "setting inputs failed at the start"); return CS_FMI; }
        FMI(r->f3.exit_init(r->c), "fmi3ExitInitializationMode");
    } else {
        if (!r->fresh) FMI(r->f2.reset(r->c), "fmi2Reset");
        r->fresh = 0;
        FMI(r->f2.setup_experiment(r->c, fmi2True, b->tolerance, b->start_time, fmi2True, b->stop_time),
            "fmi2SetupExperiment");
        FMI(set_parameters2(r, b, params), "setting the parameters");
        FMI(r->f2.enter_init(r->c), "fmi2EnterInitializationMode");
        if (set_inputs(r, b->u)) { set_message(r, "setting inputs failed at the start"); return CS_FMI; }
        FMI(r->f2.exit_init(r->c), "fmi2ExitInitializationMode");
    }
    if (b->read[0] && (s = take_point(r, 0, all_real, out))) return s;
    for (j = 0; j + 1 < b->n_comm; j++) {
        double t = b->comm[j], h = b->steps[j], t_last = t + h;
        int stop = 0, st;
        const double *u = b->u + (size_t)j * k;
        if (k && set_inputs(r, u)) { set_message(r, "setting inputs failed at t=%g", t); return CS_FMI; }
        if (k && b->interpolation == 1)
            FMI(r->f2.set_input_derivatives(r->c, b->input_vrs, (size_t)k, orders, b->du + (size_t)j * k),
                "fmi2SetRealInputDerivatives");
        if (r->version == 3) {
            fmi3Boolean event = false, terminate = false, early = false;
            fmi3Float64 last = t_last;
            st = r->f3.do_step(r->c, t, h, true, &event, &terminate, &early, &last);
            if (st >= fmi3Error) {
                set_message(r, "fmi3DoStep failed at t=%g%s%s", t, r->fmu_log[0] ? ": " : "", r->fmu_log);
                return CS_FMI;
            }
            if (terminate) {
                stop = 1;
                t_last = last;
            } else if (early || st == fmi3Discard) {
                set_message(r, "fmi3DoStep did not complete the step from t=%g%s%s", t, r->fmu_log[0] ? ": " : "",
                            r->fmu_log);
                return CS_FMI;
            }
        } else {
            st = r->f2.do_step(r->c, t, h, fmi2True);
            if (st == fmi2Discard) {
                fmi2Boolean terminated = fmi2False;
                fmi2Real last = t;
                if (r->f2.get_boolean_status(r->c, fmi2Terminated, &terminated) < fmi2Error && terminated) {
                    stop = 1;
                    if (r->f2.get_real_status(r->c, fmi2LastSuccessfulTime, &last) < fmi2Error) t_last = last;
                    else t_last = t;
                } else {
                    set_message(r, "fmi2DoStep discarded the step from t=%g%s%s", t, r->fmu_log[0] ? ": " : "",
                                r->fmu_log);
                    return CS_FMI;
                }
            } else if (st != fmi2OK && st != fmi2Warning) {
                set_message(r, "fmi2DoStep %s at t=%g%s%s", st == fmi2Pending ? "went asynchronous (pending)" : "failed",
                            t, r->fmu_log[0] ? ": " : "", r->fmu_log);
                return CS_FMI;
            }
        }
        if (stop) {
            char log[MSG_LEN];
            memcpy(log, r->fmu_log, MSG_LEN);
            /* the step was completed: its end point's outputs stand */
            if (t_last >= b->comm[j + 1] - 1e-12 * fmax(1.0, fabs(b->comm[j + 1])) && b->read[j + 1]
                && take_point(r, j + 1, all_real, out) == CS_OK)
                *t_reached = b->comm[j + 1];
            set_message(r, "the model asked to terminate at t=%g%s%s", t_last, log[0] ? ": " : "", log);
            return CS_TERMINATED;
        }
        *t_reached = b->comm[j + 1];
        if (b->read[j + 1] && (s = take_point(r, j + 1, all_real, out))) return s;
        if (r->deadline > 0 && now() > r->deadline) {
            set_message(r, "over its %g s wall-clock budget at t=%g", b->timeout, b->comm[j + 1]);
            return CS_TIMEOUT;
        }
    }
    if (r->version == 3) r->f3.terminate(r->c);
    else r->f2.terminate(r->c);
    return CS_OK;
}

/* A new instance in place of the current one. */
static void renew(CsRunner *r) {
    free_instance(r);
    instantiate(r);
}

/* After a failure the instance may be in any state: reset it, or make a new one. */
static void recover(CsRunner *r) {
    int s = r->version == 3 ? (int)r->f3.reset(r->c) : (int)r->f2.reset(r->c);
    if (s < 3) {
        r->fresh = 1;
        return;
    }
    renew(r);
}

/* Run every set of the batch. out: n_sets x n_times x n_out (NaN after a failure, or after
 * the rows a terminated set gave); status and t_reached: one per set; messages: n_sets x
 * MSG_LEN. Returns the number of failed sets, -1 if the instance could not be re-created,
 * -2 for a batch the driver cannot take. */
RC_EXPORT int cs_run(CsRunner *r, const CsBatch *b, double *out, int *status, double *t_reached, char *messages) {
    int i, failed = 0;
    size_t per_set = (size_t)b->n_times * b->n_out, j;
    if (b->n_inputs > MAX_INPUTS || (b->interpolation == 2 && !r->intermediate) || (b->interpolation == 1 && r->version == 3))
        return -2;
    if (b->n_out > r->cap) {
        free(r->cur);
        free(r->prev);
        r->cur = calloc((size_t)b->n_out, sizeof(double));
        r->prev = calloc((size_t)b->n_out, sizeof(double));
        if (!r->cur || !r->prev) {
            r->cap = 0;
            return -2;
        }
        r->cap = b->n_out;
    }
    r->b = b;
    for (i = 0; i < b->n_sets; i++) {
        double *o = out + per_set * i;
        r->message[0] = 0;
        r->fmu_log[0] = 0;
        if (!r->c) {
            status[i] = CS_FMI;
            snprintf(messages + (size_t)MSG_LEN * i, MSG_LEN, "the FMU could not be instantiated again");
            for (j = 0; j < per_set; j++) o[j] = NAN;
            failed++;
            continue;
        }
        r->deadline = b->timeout > 0 ? now() + b->timeout : 0.0;
        status[i] = run_set(r, b->param_values + (size_t)b->n_params * i, o, &t_reached[i]);
        if (status[i] == CS_TERMINATED) {
            for (j = (size_t)r->rows_done * b->n_out; j < per_set; j++) o[j] = NAN;
            if (r->version == 3) r->f3.terminate(r->c);
            else r->f2.terminate(r->c);
            /* the next set on a new instance: the standard's Reference FMUs keep their
             * terminateSimulation through fmi2Reset / fmi3Reset (Stair would stop at once) */
            renew(r);
            if (r->rows_done >= b->n_times) {
                status[i] = CS_OK;
                r->message[0] = 0;
            }
        } else if (status[i] != CS_OK) {
            for (j = 0; j < per_set; j++) o[j] = NAN;
            recover(r);
        }
        memcpy(messages + (size_t)MSG_LEN * i, r->message, MSG_LEN);
        if (status[i] != CS_OK) failed++;
    }
    r->b = NULL;
    return r->c ? failed : -1;
}

RC_EXPORT int cs_msg_len(void) { return MSG_LEN; }
