/* FMI 2.0 Model Exchange wrapper around CasADi-generated model functions.
 *
 * One generic file for every model: the generated model_config.h gives the sizes and
 * start values, rc_model.c (CasADi's code generator) the four functions
 *   rc_ode(x, u, p, c, t)  -> der(x)
 *   rc_vars(x, u, p, c, t) -> [calculated parameters; der(x); algebraic variables]
 *   rc_init(u, p, c, t)    -> x at the start (the model's initial equations solved)
 *   rc_events(p)           -> times at which the conditions c switch
 * Value references: parameters, calculated parameters, inputs, states, derivatives,
 * algebraic variables, in that order.
 *
 * Conditions c_i = (time >= te_i) are discrete: they change only in event mode, at the
 * time events announced through nextEventTime, so the integrator never sees a step early.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model_config.h"
#include "rc_model.h"

#define VR_CALC (N_PARAMS)
#define VR_INPUTS (VR_CALC + N_CALC)
#define VR_STATES (VR_INPUTS + N_INPUTS)
#define VR_DERIVS (VR_STATES + N_STATES)
#define VR_ALGS (VR_DERIVS + N_STATES)
#define N_VARS (VR_ALGS + N_ALGS)
#define N_COMPUTED (N_CALC + N_STATES + N_ALGS)
#define DIM(n) ((n) > 0 ? (n) : 1)

typedef enum { MODE_INSTANTIATED, MODE_INIT, MODE_EVENT, MODE_CONTINUOUS, MODE_TERMINATED, MODE_ERROR } Mode;

typedef struct {
    fmi2CallbackFunctions cb;
    fmi2String name;
    fmi2Boolean logging;
    Mode mode;
    double time;
    double p[DIM(N_PARAMS)];
    double u[DIM(N_INPUTS)];
    double x[DIM(N_STATES)];
    double c[DIM(N_EVENTS)];
    double computed[DIM(N_COMPUTED)];
    int computed_valid;
    /* CasADi work space, sized for the largest of the four functions */
    const double **arg;
    double **res;
    casadi_int *iw;
    double *w;
} Instance;

static void logf_(Instance *m, fmi2Status status, const char *category, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    if (!m->cb.logger || (status == fmi2OK && !m->logging)) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    m->cb.logger(m->cb.componentEnvironment, m->name, status, category, "%s", buf);
}

static void *alloc_(Instance *m, size_t n, size_t size) {
    if (m && m->cb.allocateMemory) return m->cb.allocateMemory(n, size);
    return calloc(n, size);
}

static void free_(Instance *m, void *ptr) {
    if (!ptr) return;
    if (m && m->cb.freeMemory) m->cb.freeMemory(ptr);
    else free(ptr);
}

static void reset_values(Instance *m) {
    int i;
    for (i = 0; i < N_PARAMS; i++) m->p[i] = PARAM_START[i];
    for (i = 0; i < N_INPUTS; i++) m->u[i] = INPUT_START[i];
    for (i = 0; i < N_STATES; i++) m->x[i] = 0.0;
    for (i = 0; i < N_EVENTS; i++) m->c[i] = 0.0;
    m->time = 0.0;
    m->computed_valid = 0;
    m->mode = MODE_INSTANTIATED;
}

static int eval_events(Instance *m, double *te) {
    m->arg[0] = m->p;
    m->res[0] = te;
    return rc_events(m->arg, m->res, m->iw, m->w, 0);
}

/* Conditions at the current time; a relative tolerance absorbs the rounding of the
 * integrator's stop at an event time. */
static int update_conditions(Instance *m) {
#if N_EVENTS > 0
    double te[N_EVENTS];
    int i;
    if (eval_events(m, te)) return 1;
    for (i = 0; i < N_EVENTS; i++)
        m->c[i] = (m->time >= te[i] - 1e-10 * (1.0 + fabs(te[i]))) ? 1.0 : 0.0;
#endif
    m->computed_valid = 0;
    return 0;
}

static int next_event(Instance *m, double *t_next) {
    int found = 0;
#if N_EVENTS > 0
    double te[N_EVENTS];
    int i;
    if (eval_events(m, te)) return -1;
    for (i = 0; i < N_EVENTS; i++) {
        if (te[i] > m->time + 1e-10 * (1.0 + fabs(te[i])) && (!found || te[i] < *t_next)) {
            *t_next = te[i];
            found = 1;
        }
    }
#endif
    return found;
}

static int compute_initial_states(Instance *m) {
#if N_STATES > 0
    m->arg[0] = m->u;
    m->arg[1] = m->p;
    m->arg[2] = m->c;
    m->arg[3] = &m->time;
    m->res[0] = m->x;
    if (rc_init(m->arg, m->res, m->iw, m->w, 0)) return 1;
#endif
    m->computed_valid = 0;
    return 0;
}

static int compute_all(Instance *m) {
    if (m->computed_valid) return 0;
    if (m->mode == MODE_INSTANTIATED || m->mode == MODE_INIT) {
        if (update_conditions(m) || compute_initial_states(m)) return 1;
    }
#if N_COMPUTED > 0
    m->arg[0] = m->x;
    m->arg[1] = m->u;
    m->arg[2] = m->p;
    m->arg[3] = m->c;
    m->arg[4] = &m->time;
    m->res[0] = m->computed;
    if (rc_vars(m->arg, m->res, m->iw, m->w, 0)) return 1;
#endif
    m->computed_valid = 1;
    return 0;
}

/* ---- common functions ------------------------------------------------------------ */

FMI2_Export const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char *fmi2GetVersion(void) { return fmi2Version; }

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t n, const fmi2String cats[]) {
    (void)n; (void)cats;
    ((Instance *)c)->logging = loggingOn;
    return fmi2OK;
}

static void grow(casadi_int *a, casadi_int *r, casadi_int *i, casadi_int *w,
                 int (*work)(casadi_int *, casadi_int *, casadi_int *, casadi_int *)) {
    casadi_int sa, sr, si, sw;
    work(&sa, &sr, &si, &sw);
    if (sa > *a) *a = sa;
    if (sr > *r) *r = sr;
    if (si > *i) *i = si;
    if (sw > *w) *w = sw;
}

FMI2_Export fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                                          const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                                          fmi2Boolean loggingOn) {
    Instance *m;
    casadi_int sa = 5, sr = 1, si = 1, sw = 1;
    (void)location; (void)visible;
    if (type != fmi2ModelExchange) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "error",
                              "this FMU supports Model Exchange only");
        return NULL;
    }
    if (!guid || strcmp(guid, MODEL_GUID) != 0) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "error",
                              "GUID %s does not match the model's %s", guid ? guid : "(null)", MODEL_GUID);
        return NULL;
    }
    m = (Instance *)(functions && functions->allocateMemory ? functions->allocateMemory(1, sizeof(Instance))
                                                             : calloc(1, sizeof(Instance)));
    if (!m) return NULL;
    if (functions) m->cb = *functions;
    m->name = name;
    m->logging = loggingOn;
    grow(&sa, &sr, &si, &sw, rc_ode_work);
    grow(&sa, &sr, &si, &sw, rc_vars_work);
    grow(&sa, &sr, &si, &sw, rc_init_work);
    grow(&sa, &sr, &si, &sw, rc_events_work);
    m->arg = (const double **)alloc_(m, (size_t)sa, sizeof(double *));
    m->res = (double **)alloc_(m, (size_t)sr, sizeof(double *));
    m->iw = (casadi_int *)alloc_(m, (size_t)(si > 0 ? si : 1), sizeof(casadi_int));
    m->w = (double *)alloc_(m, (size_t)(sw > 0 ? sw : 1), sizeof(double));
    if (!m->arg || !m->res || !m->iw || !m->w) return NULL;
    reset_values(m);
    return m;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) {
    Instance *m = (Instance *)c;
    if (!m) return;
    free_(m, m->arg);
    free_(m, m->res);
    free_(m, m->iw);
    free_(m, m->w);
    if (m->cb.freeMemory) m->cb.freeMemory(m);
    else free(m);
}

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol,
                                           fmi2Real startTime, fmi2Boolean stopDefined, fmi2Real stopTime) {
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stopTime;
    ((Instance *)c)->time = startTime;
    ((Instance *)c)->computed_valid = 0;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ((Instance *)c)->mode = MODE_INIT;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *m = (Instance *)c;
    if (update_conditions(m) || compute_initial_states(m)) {
        logf_(m, fmi2Error, "error", "initialisation failed at t=%g", m->time);
        m->mode = MODE_ERROR;
        return fmi2Error;
    }
    m->mode = MODE_EVENT;
    return compute_all(m) ? fmi2Error : fmi2OK;
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) {
    ((Instance *)c)->mode = MODE_TERMINATED;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
    reset_values((Instance *)c);
    return fmi2OK;
}

static fmi2Status check_vr(Instance *m, const fmi2ValueReference vr[], size_t nvr, unsigned limit, const char *what) {
    size_t i;
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= limit) {
            logf_(m, fmi2Error, "error", "value reference %u is not a %s", vr[i], what);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

/* A flag parameter (PARAM_TYPE 1 Integer, 2 Boolean) is set and got by its own type's
 * functions only, every other variable by the Real ones: a caller that sets GGOV1's Rselect
 * through fmi2SetReal is told, not obeyed. */
static fmi2Status check_type(Instance *m, const fmi2ValueReference vr[], size_t nvr, int type, const char *fn) {
    size_t i;
    for (i = 0; i < nvr; i++) {
        int actual = vr[i] < N_PARAMS ? PARAM_TYPE[vr[i]] : 0;
        if (vr[i] < N_VARS && actual != type) {
            logf_(m, fmi2Error, "error", "%s: value reference %u is %s", fn, vr[i],
                  actual == 1 ? "an Integer parameter" : actual == 2 ? "a Boolean parameter" : "a Real variable");
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *m = (Instance *)c;
    size_t i;
    if (check_vr(m, vr, nvr, N_VARS, "variable") != fmi2OK) return fmi2Error;
    if (compute_all(m)) {
        logf_(m, fmi2Error, "error", "evaluating the model failed at t=%g", m->time);
        return fmi2Error;
    }
    if (check_type(m, vr, nvr, 0, "fmi2GetReal") != fmi2OK) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        unsigned r = vr[i];
        if (r < VR_CALC) value[i] = m->p[r];
        else if (r < VR_INPUTS) value[i] = m->computed[r - VR_CALC];
        else if (r < VR_STATES) value[i] = m->u[r - VR_INPUTS];
        else if (r < VR_DERIVS) value[i] = m->x[r - VR_STATES];
        else value[i] = m->computed[N_CALC + (r - VR_DERIVS)];
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *m = (Instance *)c;
    size_t i;
    if (check_type(m, vr, nvr, 0, "fmi2SetReal") != fmi2OK) return fmi2Error;
    for (i = 0; i < nvr; i++) {
        unsigned r = vr[i];
        if (r < VR_CALC) m->p[r] = value[i];
        else if (r >= VR_INPUTS && r < VR_STATES) m->u[r - VR_INPUTS] = value[i];
        else {
            logf_(m, fmi2Error, "error", "value reference %u cannot be set (only parameters and inputs can)", r);
            return fmi2Error;
        }
    }
    m->computed_valid = 0;
    return fmi2OK;
}

#define NOT_SUPPORTED(n) if ((n) > 0) return fmi2Error; return fmi2OK
/* Integer and Boolean parameters (flags), held as doubles beside the Real ones. */
static fmi2Status get_flags(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, int type, double out[]) {
    Instance *m = (Instance *)c;
    size_t i;
    if (check_vr(m, vr, nvr, N_PARAMS, "parameter") != fmi2OK || check_type(m, vr, nvr, type, "get") != fmi2OK)
        return fmi2Error;
    for (i = 0; i < nvr; i++) out[i] = m->p[vr[i]];
    return fmi2OK;
}

static fmi2Status set_flags(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, int type, const double in[]) {
    Instance *m = (Instance *)c;
    size_t i;
    if (check_vr(m, vr, nvr, N_PARAMS, "parameter") != fmi2OK || check_type(m, vr, nvr, type, "set") != fmi2OK)
        return fmi2Error;
    for (i = 0; i < nvr; i++) m->p[vr[i]] = in[i];
    m->computed_valid = 0;
    return fmi2OK;
}

#define MAX_FLAGS 64
FMI2_Export fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer v[]) {
    double d[MAX_FLAGS];
    size_t i;
    if (nvr > MAX_FLAGS || get_flags(c, vr, nvr, 1, d) != fmi2OK) return fmi2Error;
    for (i = 0; i < nvr; i++) v[i] = (fmi2Integer)d[i];
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean v[]) {
    double d[MAX_FLAGS];
    size_t i;
    if (nvr > MAX_FLAGS || get_flags(c, vr, nvr, 2, d) != fmi2OK) return fmi2Error;
    for (i = 0; i < nvr; i++) v[i] = d[i] != 0.0 ? fmi2True : fmi2False;
    return fmi2OK;
}
FMI2_Export fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer v[]) {
    double d[MAX_FLAGS];
    size_t i;
    if (nvr > MAX_FLAGS) return fmi2Error;
    for (i = 0; i < nvr; i++) d[i] = (double)v[i];
    return set_flags(c, vr, nvr, 1, d);
}
FMI2_Export fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean v[]) {
    double d[MAX_FLAGS];
    size_t i;
    if (nvr > MAX_FLAGS) return fmi2Error;
    for (i = 0; i < nvr; i++) d[i] = v[i] ? 1.0 : 0.0;
    return set_flags(c, vr, nvr, 2, d);
}
FMI2_Export fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String v[]) {
    (void)c; (void)vr; (void)v; NOT_SUPPORTED(nvr);
}
FMI2_Export fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String v[]) {
    (void)c; (void)vr; (void)v; NOT_SUPPORTED(nvr);
}

/* canGetAndSetFMUstate="false", providesDirectionalDerivative="false" */
FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)c; (void)s; (void)n; return fmi2Error;
}
FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)c; (void)s; (void)b; (void)n; return fmi2Error;
}
FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)c; (void)b; (void)n; (void)s; return fmi2Error;
}
FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                                    const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                                    fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return fmi2Error;
}

/* ---- Model Exchange -------------------------------------------------------------- */

FMI2_Export fmi2Status fmi2EnterEventMode(fmi2Component c) {
    ((Instance *)c)->mode = MODE_EVENT;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Instance *m = (Instance *)c;
    double t_next = 0.0;
    int found;
    if (update_conditions(m)) return fmi2Error;
    found = next_event(m, &t_next);
    if (found < 0) return fmi2Error;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = found ? fmi2True : fmi2False;
    info->nextEventTime = found ? t_next : 0.0;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    ((Instance *)c)->mode = MODE_CONTINUOUS;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)c; (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    Instance *m = (Instance *)c;
    m->time = time;
    m->computed_valid = 0;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *m = (Instance *)c;
    if (nx != N_STATES) return fmi2Error;
    if (nx) memcpy(m->x, x, nx * sizeof(double));
    m->computed_valid = 0;
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Instance *m = (Instance *)c;
    size_t i;
    if (nx != N_STATES) return fmi2Error;
    if (nx == 0) return fmi2OK;
    m->arg[0] = m->x;
    m->arg[1] = m->u;
    m->arg[2] = m->p;
    m->arg[3] = m->c;
    m->arg[4] = &m->time;
    m->res[0] = dx;
    if (rc_ode(m->arg, m->res, m->iw, m->w, 0)) return fmi2Error;
    for (i = 0; i < nx; i++) {
        if (!isfinite(dx[i])) {
            logf_(m, fmi2Error, "error", "der(%s) is not finite at t=%g", STATE_NAMES[i], m->time);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    (void)c; (void)z;
    return nz == 0 ? fmi2OK : fmi2Error;
}

FMI2_Export fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Instance *m = (Instance *)c;
    if (nx != N_STATES) return fmi2Error;
    if (nx) memcpy(x, m->x, nx * sizeof(double));
    return fmi2OK;
}

FMI2_Export fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    size_t i;
    (void)c;
    for (i = 0; i < nx; i++) x_nominal[i] = 1.0;
    return fmi2OK;
}
