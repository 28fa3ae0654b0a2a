/* A minimal FMI implementation for the test FMUs of this folder: FMI 2.0 (the default) or
 * FMI 3.0 (compiled with -DFMI3), each with Model Exchange and Co-Simulation in one binary;
 * the model description says which interfaces an FMU offers. This file holds what the
 * versions share; their functions are in fmu_fmi2.h and fmu_fmi3.h.
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
    int mode;               /* the FMI 3.0 state machine's state (fmu_fmi3.h) */
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
    model_start(m); /* FMI 3.0: back in Instantiated (mode 0) */
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

/* The FMI functions, one version per build: fmu_fmi2.h, or fmu_fmi3.h with -DFMI3. */
#ifndef FMI3
#include "fmu_fmi2.h"
#else
#include "fmu_fmi3.h"
#endif
