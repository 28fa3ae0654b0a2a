/* A counter that steps up every `period` seconds (time events), with Integer and Boolean
 * outputs and one continuous state x' = count (so x is piecewise linear).
 * Real vrs: 0 x, 1 der(x), 2 period. Integer vr 0: count. Boolean vr 0: odd. */
#define MODEL_GUID "{2a1b0c7e-4f55-4e1c-9d0a-5a1f00c0a001}"
#define N_REAL 3
#define N_INT 1
#define N_BOOL 1
#define N_STATES 1
#define N_INDICATORS 0
#define STATE_VRS {0}
#define DER_VRS {1}
#include "fmu_template.h"

static void model_start(Model *m) { m->r[2] = 1.0; }
static void model_initialize(Model *m) {
    m->r[0] = 0.0;
    m->i[0] = 0;
}
static void model_derivatives(Model *m) {
    m->r[1] = (double)m->i[0];
    m->b[0] = m->i[0] % 2 == 1;
}
static void model_indicators(Model *m, double *z) { (void)m; (void)z; }
static void model_event(Model *m, fmi2EventInfo *info) {
    /* the count is the number of whole periods elapsed; the next event is the next one */
    double tol = 1e-9 * (1.0 + m->time);
    int k = (int)((m->time + tol) / m->r[2]);
    m->i[0] = k;
    info->nextEventTimeDefined = fmi2True;
    info->nextEventTime = (k + 1) * m->r[2];
}
