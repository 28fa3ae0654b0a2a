/* A minimal FMI implementation for the test FMUs of this folder: FMI 2.0 (the default) or
 * FMI 3.0 (compiled with -DFMI3), each with Model Exchange and Co-Simulation in one binary;
 * the model description says which interfaces an FMU offers.
 *
 * Written against the FMI standards' headers (the copies fmpy ships), independently of
 * rapid-cosim's embedded compiler and runners, so that the simulator is tested on FMUs it
 * did not make. A model defines, before including this file:
 *   N_REAL, N_INT, N_BOOL         variables per type (value references 0..N-1 per type in
 *                                 FMI 2.0; in FMI 3.0, where value references are unique,
 *                                 Int32 ones start at 100, Boolean 200, String 300, Binary 400)
 *   N_STRING (optional)           String variables, computed by the model (const char *)
 *   N_STATES, N_INDICATORS        continuous states and event indicators
 *   STATE_VRS, DER_VRS            Real value references of the states and derivatives
 *   N_INPUTS, INPUT_VRS (optional) Real inputs (the Co-Simulation solver interpolates them)
 *   CS_STEP (optional)            the Co-Simulation solver's largest internal step (0.01 s)
 *   void model_start(Model *)     start values
 *   void model_initialize(Model *) states from parameters, at the end of initialisation
 *   void model_derivatives(Model *) derivatives (and outputs) from states, time, inputs
 *   void model_indicators(Model *, double *z)
 *   void model_event(Model *, EventInfo *) discrete update at an event (time events: the
 *                                 next one in info->next_event; info->terminate stops)
 *
 * Co-Simulation: the model is integrated inside fmi2DoStep / fmi3DoStep with the classic
 * Runge-Kutta method at steps of at most CS_STEP, stopping at the model's time events and
 * locating state events by bisection on the step length. Real inputs are held over a
 * communication step unless the importer interpolates them: FMI 2.0 input derivatives
 * (fmi2SetRealInputDerivatives, order 1: u(t) = u(t_c) + du (t - t_c)), FMI 3.0 intermediate
 * update (the importer's callback asked for the inputs at the end of every internal step,
 * linear within it). A terminate request ends the step where it happened: fmi2Discard
 * with fmi2Terminated / fmi2LastSuccessfulTime, or fmi3DoStep's terminateSimulation and
 * lastSuccessfulTime. Compiled with -DFIXED_STEP, a Co-Simulation instance refuses a
 * communication step other than its first (what an FMU that cannot handle a variable
 * communication step size may do).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifdef FMI3
#include "fmi3Functions.h"
#else
#include "fmi2Functions.h"
#endif

#ifndef N_STRING
#define N_STRING 0
#endif
#ifndef N_INPUTS
#define N_INPUTS 0
#define INPUT_VRS {0}
#endif
#ifndef CS_STEP
#define CS_STEP 0.01
#endif
#define NZ (N_INDICATORS > 0 ? N_INDICATORS : 1)
#define NX (N_STATES > 0 ? N_STATES : 1)
#define NU (N_INPUTS > 0 ? N_INPUTS : 1)

typedef struct {
    int values_changed;     /* the continuous states were re-initialised */
    int next_event_defined; /* a time event is due at next_event */
    double next_event;
    int terminate;          /* the model asks to stop the simulation */
} EventInfo;

typedef struct {
    double r[N_REAL > 0 ? N_REAL : 1];
    int i[N_INT > 0 ? N_INT : 1];
    int b[N_BOOL > 0 ? N_BOOL : 1];
    const char *s[N_STRING > 0 ? N_STRING : 1];
    double time;
    int initialized;
    int cs;                 /* a Co-Simulation instance */
    int next_event_defined;
    double next_event;
    int terminated;
    /* Co-Simulation inputs: values at the communication point, FMI 2.0 derivatives */
    double t_comm, u0[NU], du[NU];
    double first_step;      /* -DFIXED_STEP: the communication step all must have */
#ifdef FMI3
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    fmi3IntermediateUpdateCallback update;
#else
    fmi2CallbackFunctions cb;
#endif
} Model;

static const int state_vrs[NX] = STATE_VRS;
static const int der_vrs[NX] = DER_VRS;
static const int input_vrs[NU] = INPUT_VRS;

static void model_start(Model *m);
static void model_initialize(Model *m);
static void model_derivatives(Model *m);
static void model_indicators(Model *m, double *z);
static void model_event(Model *m, EventInfo *info);

static void reset_model(Model *m) {
    /* everything but the importer's callbacks and the interface */
    Model keep = *m;
    memset(m, 0, sizeof(Model));
#ifdef FMI3
    m->env = keep.env;
    m->log = keep.log;
    m->update = keep.update;
#else
    m->cb = keep.cb;
#endif
    m->cs = keep.cs;
    model_start(m);
}

/* ---- the Co-Simulation solver ---- */

static void take_event(Model *m, EventInfo *info) {
    memset(info, 0, sizeof(*info));
    model_event(m, info);
    m->next_event_defined = info->next_event_defined;
    m->next_event = info->next_event;
    if (info->terminate) m->terminated = 1;
}

/* Inputs at t inside the internal step [ta, tb] whose end values are ub (intermediate
 * update) or from the communication point's values and derivatives. */
static void inputs_at(Model *m, double t, double ta, const double *ua, double tb, const double *ub) {
    int j;
    for (j = 0; j < N_INPUTS; j++) {
        double u;
        if (ub) u = tb > ta ? ua[j] + (ub[j] - ua[j]) * (t - ta) / (tb - ta) : ub[j];
        else u = m->u0[j] + m->du[j] * (t - m->t_comm);
        m->r[input_vrs[j]] = u;
    }
}

static void eval(Model *m, double t, const double *x, double *dx, double ta, const double *ua, double tb,
                 const double *ub) {
    int k;
    m->time = t;
    inputs_at(m, t, ta, ua, tb, ub);
    for (k = 0; k < N_STATES; k++) m->r[state_vrs[k]] = x[k];
    model_derivatives(m);
    for (k = 0; k < N_STATES; k++) dx[k] = m->r[der_vrs[k]];
}

/* One classic Runge-Kutta step of length h from (t0, x0) into x1. */
static void rk4(Model *m, double t0, const double *x0, double h, double *x1, double ta, const double *ua, double tb,
                const double *ub) {
    double k1[NX], k2[NX], k3[NX], k4[NX], y[NX];
    int k;
    eval(m, t0, x0, k1, ta, ua, tb, ub);
    for (k = 0; k < N_STATES; k++) y[k] = x0[k] + 0.5 * h * k1[k];
    eval(m, t0 + 0.5 * h, y, k2, ta, ua, tb, ub);
    for (k = 0; k < N_STATES; k++) y[k] = x0[k] + 0.5 * h * k2[k];
    eval(m, t0 + 0.5 * h, y, k3, ta, ua, tb, ub);
    for (k = 0; k < N_STATES; k++) y[k] = x0[k] + h * k3[k];
    eval(m, t0 + h, y, k4, ta, ua, tb, ub);
    for (k = 0; k < N_STATES; k++) x1[k] = x0[k] + h / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
}

static void set_state(Model *m, double t, const double *x, double ta, const double *ua, double tb,
                      const double *ub) {
    double dx[NX];
    eval(m, t, x, dx, ta, ua, tb, ub); /* leaves states, time, inputs and outputs at t */
}

static int crossed(const double *z0, const double *z1) {
    int k;
    for (k = 0; k < N_INDICATORS; k++)
        if ((z0[k] > 0 && z1[k] <= 0) || (z0[k] < 0 && z1[k] >= 0)) return 1;
    return 0;
}

#ifdef FMI3
static int request_inputs(Model *m, double t) {
    fmi3Boolean early = 0;
    fmi3Float64 early_time = 0.0;
    if (!m->update || !N_INPUTS) return 0;
    m->update(m->env, t, 1, 0, 0, 0, &early, &early_time);
    return 1;
}
#endif

/* Integrate from the current time over [t_comm, t_comm + h]: 0 when done, 1 when the model
 * asked to terminate (m->time is where it stopped). */
static int cs_step(Model *m, double t_comm, double h) {
    double t_end = t_comm + h, eps = 1e-12 * (1.0 + fabs(t_end)), x0[NX], x1[NX], z0[NZ], z1[NZ];
    double ua[NU], ub[NU];
    int k, interpolated = 0;
    (void)ub;
    m->t_comm = t_comm;
    for (k = 0; k < N_INPUTS; k++) m->u0[k] = m->r[input_vrs[k]];
    if (m->terminated) return 1;
    while (m->time < t_end - eps) {
        double t0 = m->time, t1 = t0 + CS_STEP;
        int time_event = 0, state_event = 0;
        const double *pb = NULL;
        EventInfo info;
        if (t1 > t_end - eps) t1 = t_end;
        if (m->next_event_defined && m->next_event <= t1 + eps) {
            t1 = m->next_event > t0 ? m->next_event : t0;
            time_event = 1;
        }
        for (k = 0; k < N_STATES; k++) x0[k] = m->r[state_vrs[k]];
        for (k = 0; k < N_INPUTS; k++) ua[k] = m->r[input_vrs[k]];
#ifdef FMI3
        if (t1 > t0 && request_inputs(m, t1)) { /* the importer set the inputs at t1 */
            for (k = 0; k < N_INPUTS; k++) ub[k] = m->r[input_vrs[k]];
            pb = ub;
            interpolated = 1;
        }
#endif
        if (N_INDICATORS) {
            set_state(m, t0, x0, t0, ua, t1, pb);
            model_indicators(m, z0);
        }
        if (t1 > t0) rk4(m, t0, x0, t1 - t0, x1, t0, ua, t1, pb);
        else memcpy(x1, x0, sizeof(x0));
        set_state(m, t1, x1, t0, ua, t1, pb);
        if (N_INDICATORS) {
            model_indicators(m, z1);
            if (crossed(z0, z1)) { /* bisect on the step length for the first crossing */
                double lo = 0.0, hi = t1 - t0, tb = t1;
                int it;
                for (it = 0; it < 200 && hi - lo > 1e-15 * (1.0 + fabs(t0)); it++) {
                    double mid = 0.5 * (lo + hi);
                    rk4(m, t0, x0, mid, x1, t0, ua, tb, pb);
                    set_state(m, t0 + mid, x1, t0, ua, tb, pb);
                    model_indicators(m, z1);
                    if (crossed(z0, z1)) hi = mid;
                    else lo = mid;
                }
                rk4(m, t0, x0, hi, x1, t0, ua, tb, pb);
                t1 = t0 + hi;
                set_state(m, t1, x1, t0, ua, tb, pb);
                state_event = 1;
                time_event = time_event && m->next_event <= t1 + eps;
            }
        }
        m->time = t1;
        if (time_event || state_event) {
            take_event(m, &info);
            model_derivatives(m);
            if (m->terminated) return 1;
        }
    }
    m->time = t_end;
    if (!interpolated) inputs_at(m, t_end, 0.0, NULL, 0.0, NULL);
    model_derivatives(m);
    for (k = 0; k < N_INPUTS; k++) m->du[k] = 0.0; /* derivatives hold for one step */
    return 0;
}

static int check_step(Model *m, double h) {
#ifdef FIXED_STEP
    if (m->first_step == 0.0) m->first_step = h;
    return fabs(h - m->first_step) <= 1e-12 * m->first_step;
#else
    (void)m; (void)h;
    return 1;
#endif
}

static const char *string_at(Model *m, unsigned k) {
    return N_STRING > 0 && m->s[k] ? m->s[k] : "";
}

#ifndef FMI3
/* ================================================================ FMI 2.0 */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    Model *m;
    (void)name; (void)resources; (void)visible; (void)logging;
    if (strcmp(guid, MODEL_GUID) != 0) return NULL;
    m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->cb = *cb;
    m->cs = type == fmi2CoSimulation;
    model_start(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean l, size_t n, const fmi2String cat[]) {
    (void)c; (void)l; (void)n; (void)cat;
    return fmi2OK;
}
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop) {
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    ((Model *)c)->time = start;
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Model *m = (Model *)c;
    model_initialize(m);
    m->initialized = 1;
    model_derivatives(m);
    if (m->cs) { /* the initial event iteration, done by the Co-Simulation solver itself */
        EventInfo info;
        take_event(m, &info);
        model_derivatives(m);
    }
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    reset_model((Model *)c);
    return fmi2OK;
}

#define GETSET(Type, T, field, n)                                                                          \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, T value[]) {      \
        Model *m = (Model *)c;                                                                             \
        size_t k;                                                                                          \
        if (m->initialized && !m->cs) model_derivatives(m);                                                \
        for (k = 0; k < nvr; k++) {                                                                        \
            if (vr[k] >= (n)) return fmi2Error;                                                            \
            value[k] = (T)m->field[vr[k]];                                                                 \
        }                                                                                                  \
        return fmi2OK;                                                                                     \
    }                                                                                                      \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const T value[]) { \
        Model *m = (Model *)c;                                                                             \
        size_t k;                                                                                          \
        for (k = 0; k < nvr; k++) {                                                                        \
            if (vr[k] >= (n)) return fmi2Error;                                                            \
            m->field[vr[k]] = value[k];                                                                    \
        }                                                                                                  \
        return fmi2OK;                                                                                     \
    }
GETSET(Real, fmi2Real, r, N_REAL)
GETSET(Integer, fmi2Integer, i, N_INT)
GETSET(Boolean, fmi2Boolean, b, N_BOOL)

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) {
    Model *m = (Model *)c;
    size_t k;
    if (m->initialized && !m->cs) model_derivatives(m);
    for (k = 0; k < n; k++) {
        if (vr[k] >= N_STRING) return fmi2Error;
        v[k] = string_at(m, vr[k]);
    }
    return fmi2OK;
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) {
    (void)c; (void)vr; (void)n; (void)v;
    return fmi2Error;
}
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) {
    (void)c; (void)s; (void)n;
    return fmi2Error;
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) {
    (void)c; (void)s; (void)b; (void)n;
    return fmi2Error;
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) {
    (void)c; (void)b; (void)n; (void)s;
    return fmi2Error;
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[],
                                        fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz;
    return fmi2Error;
}

/* ---- Model Exchange ---- */

fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Model *m = (Model *)c;
    EventInfo e;
    take_event(m, &e);
    memset(info, 0, sizeof(*info));
    info->terminateSimulation = e.terminate ? fmi2True : fmi2False;
    info->valuesOfContinuousStatesChanged = e.values_changed ? fmi2True : fmi2False;
    info->nextEventTimeDefined = e.next_event_defined ? fmi2True : fmi2False;
    info->nextEventTime = e.next_event;
    return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean nosp, fmi2Boolean *enter, fmi2Boolean *term) {
    (void)c; (void)nosp;
    *enter = fmi2False;
    *term = fmi2False;
    return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) {
    ((Model *)c)->time = t;
    return fmi2OK;
}
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    for (k = 0; k < nx; k++) m->r[state_vrs[k]] = x[k];
    return fmi2OK;
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    for (k = 0; k < nx; k++) x[k] = m->r[state_vrs[k]];
    return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    model_derivatives(m);
    for (k = 0; k < nx; k++) dx[k] = m->r[der_vrs[k]];
    return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) {
    if (nz != N_INDICATORS) return fmi2Error;
    if (nz) model_indicators((Model *)c, z);
    return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    size_t k;
    (void)c;
    for (k = 0; k < nx; k++) x[k] = 1.0;
    return fmi2OK;
}

/* ---- Co-Simulation ---- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Model *m = (Model *)c;
    size_t k;
    int j;
    for (k = 0; k < nvr; k++) {
        int found = 0;
        if (order[k] != 1) return fmi2Error;
        for (j = 0; j < N_INPUTS; j++)
            if ((int)vr[k] == input_vrs[j]) {
                m->du[j] = value[k];
                found = 1;
            }
        if (!found) return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)c; (void)vr; (void)nvr; (void)order; (void)value;
    return fmi2Error;
}
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean nosp) {
    Model *m = (Model *)c;
    (void)nosp;
    if (!check_step(m, h)) return fmi2Error;
    return cs_step(m, t, h) ? fmi2Discard : fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) {
    if (s != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = ((Model *)c)->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) {
    if (s != fmi2Terminated) return fmi2Discard;
    *v = ((Model *)c)->terminated ? fmi2True : fmi2False;
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) {
    (void)c; (void)s; (void)v;
    return fmi2Discard;
}

#else
/* ================================================================ FMI 3.0 */

#define VR_INT 100
#define VR_BOOL 200
#define VR_STRING 300
#define VR_BINARY 400
#define VR_TIME 999

const char *fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance c, fmi3Boolean on, size_t n, const fmi3String cat[]) {
    (void)c; (void)on; (void)n; (void)cat;
    return fmi3OK;
}

static Model *new_model(fmi3String token, int cs, fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    Model *m;
    if (!token || strcmp(token, MODEL_GUID) != 0) return NULL;
    m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->cs = cs;
    m->env = env;
    m->log = log;
    model_start(m);
    return m;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                          fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback log) {
    (void)name; (void)resources; (void)visible; (void)logging;
    return new_model(token, 0, env, log);
}
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
                                         fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean event_mode,
                                         fmi3Boolean early_return, const fmi3ValueReference required[],
                                         size_t n_required, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback update) {
    Model *m;
    (void)name; (void)resources; (void)visible; (void)logging; (void)early_return; (void)required;
    (void)n_required;
    if (event_mode) return NULL; /* this FMU has no event mode */
    m = new_model(token, 1, env, log);
    if (m) m->update = update;
    return m;
}
fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resources,
                                               fmi3Boolean visible, fmi3Boolean logging,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback log,
                                               fmi3ClockUpdateCallback clock, fmi3LockPreemptionCallback lock,
                                               fmi3UnlockPreemptionCallback unlock) {
    (void)name; (void)token; (void)resources; (void)visible; (void)logging; (void)env; (void)log; (void)clock;
    (void)lock; (void)unlock;
    return NULL;
}
void fmi3FreeInstance(fmi3Instance c) { free(c); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean tol_defined, fmi3Float64 tol, fmi3Float64 start,
                                       fmi3Boolean stop_defined, fmi3Float64 stop) {
    (void)tol_defined; (void)tol; (void)stop_defined; (void)stop;
    ((Model *)c)->time = start;
    return fmi3OK;
}
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Model *m = (Model *)c;
    model_initialize(m);
    m->initialized = 1;
    model_derivatives(m);
    if (m->cs) {
        EventInfo info;
        take_event(m, &info);
        model_derivatives(m);
    }
    return fmi3OK;
}
fmi3Status fmi3EnterEventMode(fmi3Instance c) { (void)c; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance c) { (void)c; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance c) {
    reset_model((Model *)c);
    return fmi3OK;
}

/* Getters and setters: Float64 (reals), Int32 (integers), Boolean; the other numeric
 * types have no variables here. */
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 v[], size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    if (m->initialized && !m->cs) model_derivatives(m);
    for (k = 0; k < nvr; k++) {
        if (vr[k] == VR_TIME) v[k] = m->time;
        else if (vr[k] < N_REAL) v[k] = m->r[vr[k]];
        else return fmi3Error;
    }
    return fmi3OK;
}
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 v[],
                          size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] >= N_REAL) return fmi3Error;
        m->r[vr[k]] = v[k];
    }
    return fmi3OK;
}
fmi3Status fmi3GetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 v[], size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    if (m->initialized && !m->cs) model_derivatives(m);
    for (k = 0; k < nvr; k++) {
        if (vr[k] < VR_INT || vr[k] >= VR_INT + N_INT) return fmi3Error;
        v[k] = m->i[vr[k] - VR_INT];
    }
    return fmi3OK;
}
fmi3Status fmi3SetInt32(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 v[], size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] < VR_INT || vr[k] >= VR_INT + N_INT) return fmi3Error;
        m->i[vr[k] - VR_INT] = v[k];
    }
    return fmi3OK;
}
fmi3Status fmi3GetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean v[], size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    if (m->initialized && !m->cs) model_derivatives(m);
    for (k = 0; k < nvr; k++) {
        if (vr[k] < VR_BOOL || vr[k] >= VR_BOOL + N_BOOL) return fmi3Error;
        v[k] = m->b[vr[k] - VR_BOOL] != 0;
    }
    return fmi3OK;
}
fmi3Status fmi3SetBoolean(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean v[],
                          size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        if (vr[k] < VR_BOOL || vr[k] >= VR_BOOL + N_BOOL) return fmi3Error;
        m->b[vr[k] - VR_BOOL] = v[k];
    }
    return fmi3OK;
}
fmi3Status fmi3GetString(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3String v[], size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    if (m->initialized && !m->cs) model_derivatives(m);
    for (k = 0; k < nvr; k++) {
        if (vr[k] < VR_STRING || vr[k] >= VR_STRING + N_STRING) return fmi3Error;
        v[k] = string_at(m, vr[k] - VR_STRING);
    }
    return fmi3OK;
}
fmi3Status fmi3SetString(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3String v[],
                         size_t nv) {
    (void)c; (void)vr; (void)nvr; (void)v; (void)nv;
    return fmi3Error;
}
/* Binary outputs (vr 400...): the String's bytes. */
fmi3Status fmi3GetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, size_t sizes[],
                         fmi3Binary v[], size_t nv) {
    Model *m = (Model *)c;
    size_t k;
    if (nv != nvr) return fmi3Error;
    for (k = 0; k < nvr; k++) {
        const char *s;
        if (vr[k] < VR_BINARY || vr[k] >= VR_BINARY + N_STRING) return fmi3Error;
        s = string_at(m, vr[k] - VR_BINARY);
        v[k] = (fmi3Binary)s;
        sizes[k] = strlen(s);
    }
    return fmi3OK;
}
fmi3Status fmi3SetBinary(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const size_t sizes[],
                         const fmi3Binary v[], size_t nv) {
    (void)c; (void)vr; (void)nvr; (void)sizes; (void)v; (void)nv;
    return fmi3Error;
}

#define NO_VARIABLES(T)                                                                                      \
    fmi3Status fmi3Get##T(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3##T v[], size_t nv) { \
        (void)c; (void)vr; (void)v; (void)nv;                                                                \
        return nvr ? fmi3Error : fmi3OK;                                                                     \
    }                                                                                                        \
    fmi3Status fmi3Set##T(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3##T v[],      \
                          size_t nv) {                                                                       \
        (void)c; (void)vr; (void)v; (void)nv;                                                                \
        return nvr ? fmi3Error : fmi3OK;                                                                     \
    }
NO_VARIABLES(Float32)
NO_VARIABLES(Int8)
NO_VARIABLES(UInt8)
NO_VARIABLES(Int16)
NO_VARIABLES(UInt16)
NO_VARIABLES(UInt32)
NO_VARIABLES(Int64)
NO_VARIABLES(UInt64)

fmi3Status fmi3GetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, fmi3Clock v[]) {
    (void)c; (void)vr; (void)v;
    return nvr ? fmi3Error : fmi3OK;
}
fmi3Status fmi3SetClock(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock v[]) {
    (void)c; (void)vr; (void)v;
    return nvr ? fmi3Error : fmi3OK;
}

/* What this FMU does not provide. */
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance c, fmi3ValueReference vr, size_t *n) {
    (void)c; (void)vr; (void)n;
    return fmi3Error;
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance c, fmi3ValueReference dep, size_t ei[], fmi3ValueReference ind[],
                                       size_t ie[], fmi3DependencyKind kinds[], size_t n) {
    (void)c; (void)dep; (void)ei; (void)ind; (void)ie; (void)kinds; (void)n;
    return fmi3Error;
}
fmi3Status fmi3GetFMUState(fmi3Instance c, fmi3FMUState *s) { (void)c; (void)s; return fmi3Error; }
fmi3Status fmi3SetFMUState(fmi3Instance c, fmi3FMUState s) { (void)c; (void)s; return fmi3Error; }
fmi3Status fmi3FreeFMUState(fmi3Instance c, fmi3FMUState *s) { (void)c; (void)s; return fmi3Error; }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance c, fmi3FMUState s, size_t *n) {
    (void)c; (void)s; (void)n;
    return fmi3Error;
}
fmi3Status fmi3SerializeFMUState(fmi3Instance c, fmi3FMUState s, fmi3Byte b[], size_t n) {
    (void)c; (void)s; (void)b; (void)n;
    return fmi3Error;
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance c, const fmi3Byte b[], size_t n, fmi3FMUState *s) {
    (void)c; (void)b; (void)n; (void)s;
    return fmi3Error;
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                        const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
                                        size_t ns, fmi3Float64 sens[], size_t nsens) {
    (void)c; (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return fmi3Error;
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance c, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[], size_t ns,
                                    fmi3Float64 sens[], size_t nsens) {
    (void)c; (void)u; (void)nu; (void)k; (void)nk; (void)seed; (void)ns; (void)sens; (void)nsens;
    return fmi3Error;
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance c) { (void)c; return fmi3Error; }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance c) { (void)c; return fmi3Error; }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 iv[],
                                  fmi3IntervalQualifier q[]) {
    (void)c; (void)vr; (void)n; (void)iv; (void)q;
    return fmi3Error;
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 ic[],
                                   fmi3UInt64 res[], fmi3IntervalQualifier q[]) {
    (void)c; (void)vr; (void)n; (void)ic; (void)res; (void)q;
    return fmi3Error;
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 s[]) {
    (void)c; (void)vr; (void)n; (void)s;
    return fmi3Error;
}
fmi3Status fmi3GetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3UInt64 sc[],
                                fmi3UInt64 res[]) {
    (void)c; (void)vr; (void)n; (void)sc; (void)res;
    return fmi3Error;
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 iv[]) {
    (void)c; (void)vr; (void)n; (void)iv;
    return fmi3Error;
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 ic[],
                                   const fmi3UInt64 res[]) {
    (void)c; (void)vr; (void)n; (void)ic; (void)res;
    return fmi3Error;
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 s[]) {
    (void)c; (void)vr; (void)n; (void)s;
    return fmi3Error;
}
fmi3Status fmi3SetShiftFraction(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3UInt64 sc[],
                                const fmi3UInt64 res[]) {
    (void)c; (void)vr; (void)n; (void)sc; (void)res;
    return fmi3Error;
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance c) { (void)c; return fmi3OK; }
fmi3Status fmi3ActivateModelPartition(fmi3Instance c, fmi3ValueReference vr, fmi3Float64 t) {
    (void)c; (void)vr; (void)t;
    return fmi3Error;
}
fmi3Status fmi3GetOutputDerivatives(fmi3Instance c, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 o[],
                                    fmi3Float64 v[], size_t nv) {
    (void)c; (void)vr; (void)nvr; (void)o; (void)v; (void)nv;
    return fmi3Error;
}

/* ---- Model Exchange ---- */

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance c, fmi3Boolean *need_update, fmi3Boolean *terminate,
                                    fmi3Boolean *nominals_changed, fmi3Boolean *values_changed,
                                    fmi3Boolean *next_defined, fmi3Float64 *next_time) {
    Model *m = (Model *)c;
    EventInfo e;
    take_event(m, &e);
    *need_update = 0;
    *terminate = e.terminate != 0;
    *nominals_changed = 0;
    *values_changed = e.values_changed != 0;
    *next_defined = e.next_event_defined != 0;
    *next_time = e.next_event;
    return fmi3OK;
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) { (void)c; return fmi3OK; }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean nosp, fmi3Boolean *enter, fmi3Boolean *term) {
    (void)c; (void)nosp;
    *enter = 0;
    *term = 0;
    return fmi3OK;
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) {
    ((Model *)c)->time = t;
    return fmi3OK;
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    if (nx != N_STATES) return fmi3Error;
    for (k = 0; k < nx; k++) m->r[state_vrs[k]] = x[k];
    return fmi3OK;
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    if (nx != N_STATES) return fmi3Error;
    for (k = 0; k < nx; k++) x[k] = m->r[state_vrs[k]];
    return fmi3OK;
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    if (nx != N_STATES) return fmi3Error;
    model_derivatives(m);
    for (k = 0; k < nx; k++) dx[k] = m->r[der_vrs[k]];
    return fmi3OK;
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t nz) {
    if (nz != N_INDICATORS) return fmi3Error;
    if (nz) model_indicators((Model *)c, z);
    return fmi3OK;
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    size_t k;
    (void)c;
    for (k = 0; k < nx; k++) x[k] = 1.0;
    return fmi3OK;
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance c, size_t *n) {
    (void)c;
    *n = N_INDICATORS;
    return fmi3OK;
}
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance c, size_t *n) {
    (void)c;
    *n = N_STATES;
    return fmi3OK;
}

/* ---- Co-Simulation ---- */

fmi3Status fmi3EnterStepMode(fmi3Instance c) { (void)c; return fmi3Error; } /* no event mode */
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean nosp, fmi3Boolean *event,
                      fmi3Boolean *terminate, fmi3Boolean *early, fmi3Float64 *last) {
    Model *m = (Model *)c;
    (void)nosp;
    if (!check_step(m, h)) return fmi3Error;
    *terminate = cs_step(m, t, h) != 0;
    *event = 0;
    *early = 0;
    *last = m->time;
    return fmi3OK;
}
#endif
