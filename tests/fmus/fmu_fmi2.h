/* The FMI 2.0 functions of the test FMUs (see fmu_template.h, which includes this file
 * at its end unless FMI3 is defined). */
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
