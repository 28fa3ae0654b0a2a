/* The FMI 3.0 functions of the test FMUs (see fmu_template.h, which includes this file
 * at its end when FMI3 is defined). */

#define VR_INT 100
#define VR_BOOL 200
#define VR_STRING 300
#define VR_BINARY 400
#define VR_TIME 999

/* The FMI 3.0 state machine, checked as strictly as the standard's Reference FMUs check
 * it: a call in a state that does not allow it logs "Illegal call sequence", fails, and
 * leaves the instance Terminated (only fmi3Reset and fmi3FreeInstance then work). */
#define INSTANTIATED 1
#define INITIALIZATION 2
#define EVENT 4
#define CONTINUOUS 8
#define STEP 16
#define TERMINATED 32
#define ALLOWED(c, states, name)                                                                  \
    do {                                                                                          \
        Model *m_ = (Model *)(c);                                                                 \
        if (!((m_->mode ? m_->mode : INSTANTIATED) & (states))) {                                 \
            if (m_->log) m_->log(m_->env, fmi3Error, "logStatusError", name ": Illegal call sequence."); \
            m_->mode = TERMINATED;                                                                \
            return fmi3Error;                                                                     \
        }                                                                                         \
    } while (0)
#define EVALUATED (INITIALIZATION | EVENT | CONTINUOUS | TERMINATED) /* states, derivatives, nominals */

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
    ALLOWED(c, INSTANTIATED, "fmi3EnterInitializationMode");
    ((Model *)c)->time = start;
    ((Model *)c)->mode = INITIALIZATION;
    return fmi3OK;
}
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) {
    Model *m = (Model *)c;
    ALLOWED(c, INITIALIZATION, "fmi3ExitInitializationMode");
    m->mode = m->cs ? STEP : EVENT;
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
fmi3Status fmi3EnterEventMode(fmi3Instance c) {
    ALLOWED(c, CONTINUOUS, "fmi3EnterEventMode");
    ((Model *)c)->mode = EVENT;
    return fmi3OK;
}
fmi3Status fmi3Terminate(fmi3Instance c) {
    ALLOWED(c, EVENT | CONTINUOUS | STEP, "fmi3Terminate");
    ((Model *)c)->mode = TERMINATED;
    return fmi3OK;
}
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
    ALLOWED(c, EVENT, "fmi3UpdateDiscreteStates");
    take_event(m, &e);
    *need_update = 0;
    *terminate = e.terminate != 0;
    *nominals_changed = 0;
    *values_changed = e.values_changed != 0;
    *next_defined = e.next_event_defined != 0;
    *next_time = e.next_event;
    return fmi3OK;
}
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance c) {
    ALLOWED(c, EVENT, "fmi3EnterContinuousTimeMode");
    ((Model *)c)->mode = CONTINUOUS;
    return fmi3OK;
}
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance c, fmi3Boolean nosp, fmi3Boolean *enter, fmi3Boolean *term) {
    (void)nosp;
    ALLOWED(c, CONTINUOUS, "fmi3CompletedIntegratorStep");
    *enter = 0;
    *term = 0;
    return fmi3OK;
}
fmi3Status fmi3SetTime(fmi3Instance c, fmi3Float64 t) {
    ALLOWED(c, EVENT | CONTINUOUS, "fmi3SetTime");
    ((Model *)c)->time = t;
    return fmi3OK;
}
fmi3Status fmi3SetContinuousStates(fmi3Instance c, const fmi3Float64 x[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    ALLOWED(c, CONTINUOUS, "fmi3SetContinuousStates");
    if (nx != N_STATES) return fmi3Error;
    for (k = 0; k < nx; k++) m->r[state_vrs[k]] = x[k];
    return fmi3OK;
}
fmi3Status fmi3GetContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    ALLOWED(c, EVALUATED, "fmi3GetContinuousStates");
    if (nx != N_STATES) return fmi3Error;
    for (k = 0; k < nx; k++) x[k] = m->r[state_vrs[k]];
    return fmi3OK;
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance c, fmi3Float64 dx[], size_t nx) {
    Model *m = (Model *)c;
    size_t k;
    ALLOWED(c, EVALUATED, "fmi3GetContinuousStateDerivatives");
    if (nx != N_STATES) return fmi3Error;
    model_derivatives(m);
    for (k = 0; k < nx; k++) dx[k] = m->r[der_vrs[k]];
    return fmi3OK;
}
fmi3Status fmi3GetEventIndicators(fmi3Instance c, fmi3Float64 z[], size_t nz) {
    ALLOWED(c, EVALUATED, "fmi3GetEventIndicators");
    if (nz != N_INDICATORS) return fmi3Error;
    if (nz) model_indicators((Model *)c, z);
    return fmi3OK;
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance c, fmi3Float64 x[], size_t nx) {
    size_t k;
    ALLOWED(c, EVALUATED, "fmi3GetNominalsOfContinuousStates");
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
    ALLOWED(c, STEP, "fmi3DoStep");
    if (!check_step(m, h)) return fmi3Error;
    *terminate = cs_step(m, t, h) != 0;
    *event = 0;
    *early = 0;
    *last = m->time;
    return fmi3OK;
}
