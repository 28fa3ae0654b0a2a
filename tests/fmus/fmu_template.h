/* A minimal FMI 2.0 Model Exchange implementation for the test FMUs of this folder.
 *
 * Written against the FMI 2.0 standard's headers (the copy fmpy ships), independently of
 * rapid-cosim's embedded compiler, so that the simulator is tested on FMUs it did not
 * make. A model defines, before including this file:
 *   N_REAL, N_INT, N_BOOL         variables per type (value references 0..N-1 per type)
 *   N_STATES, N_INDICATORS        continuous states and event indicators
 *   STATE_VRS, DER_VRS            Real value references of the states and derivatives
 *   void model_start(Model *)     start values
 *   void model_initialize(Model *) states from parameters, at the end of initialisation
 *   void model_derivatives(Model *) derivatives (and outputs) from states, time, inputs
 *   void model_indicators(Model *, double *z)
 *   void model_event(Model *, fmi2EventInfo *) discrete update at an event
 */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

typedef struct {
    double r[N_REAL > 0 ? N_REAL : 1];
    int i[N_INT > 0 ? N_INT : 1];
    int b[N_BOOL > 0 ? N_BOOL : 1];
    double time;
    int initialized;
    fmi2CallbackFunctions cb;
    int next_event_defined;
    double next_event;
} Model;

static const int state_vrs[N_STATES > 0 ? N_STATES : 1] = STATE_VRS;
static const int der_vrs[N_STATES > 0 ? N_STATES : 1] = DER_VRS;

static void model_start(Model *m);
static void model_initialize(Model *m);
static void model_derivatives(Model *m);
static void model_indicators(Model *m, double *z);
static void model_event(Model *m, fmi2EventInfo *info);

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    Model *m;
    (void)name; (void)resources; (void)visible; (void)logging;
    if (type != fmi2ModelExchange || strcmp(guid, MODEL_GUID) != 0) return NULL;
    m = calloc(1, sizeof(Model));
    if (!m) return NULL;
    m->cb = *cb;
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
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) {
    Model *m = (Model *)c;
    fmi2CallbackFunctions cb = m->cb;
    memset(m, 0, sizeof(Model));
    m->cb = cb;
    model_start(m);
    return fmi2OK;
}

#define GETSET(Type, T, field, n)                                                                          \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, T value[]) {      \
        Model *m = (Model *)c;                                                                             \
        size_t k;                                                                                          \
        if (m->initialized) model_derivatives(m);                                                          \
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
    (void)c; (void)vr; (void)n; (void)v;
    return fmi2Error;
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

fmi2Status fmi2EnterEventMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info) {
    Model *m = (Model *)c;
    memset(info, 0, sizeof(*info));
    model_event(m, info);
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
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)c; (void)vr; (void)nvr; (void)order; (void)value;
    return fmi2Error;
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)c; (void)vr; (void)nvr; (void)order; (void)value;
    return fmi2Error;
}
