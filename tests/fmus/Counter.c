/* A counter that steps up every `period` seconds (time events), with Integer and Boolean
 * outputs, a String output (and, in FMI 3.0, a Binary one) and one continuous state
 * x' = count (so x is piecewise linear). At `stop_at` the model asks to terminate the
 * simulation (terminateSimulation), whatever the importer's stop time.
 * Real vrs: 0 x, 1 der(x), 2 period, 3 stop_at. Integer vr 0: count. Boolean vr 0: odd.
 * String vr 0 (and Binary, FMI 3.0): label, "even" or "odd". */
#define MODEL_GUID "{2a1b0c7e-4f55-4e1c-9d0a-5a1f00c0a001}"
#define N_REAL 4
#define N_INT 1
#define N_BOOL 1
#define N_STRING 1
#define N_STATES 1
#define N_INDICATORS 0
#define STATE_VRS {0}
#define DER_VRS {1}
#include "fmu_template.h"

static void model_start(Model *m) {
    m->r[2] = 1.0;
    m->r[3] = 1e9;
}
static void model_initialize(Model *m) {
    m->r[0] = 0.0;
    m->i[0] = 0;
}
static void model_derivatives(Model *m) {
    m->r[1] = (double)m->i[0];
    m->b[0] = m->i[0] % 2 == 1;
    m->s[0] = m->b[0] ? "odd" : "even";
}
static void model_indicators(Model *m, double *z) { (void)m; (void)z; }
static void model_event(Model *m, EventInfo *info) {
    /* the count is the number of whole periods elapsed; the next event is the next one */
    double tol = 1e-9 * (1.0 + m->time);
    int k = (int)((m->time + tol) / m->r[2]);
    m->i[0] = k;
    model_derivatives(m);
    if (m->time + tol >= m->r[3]) {
        info->terminate = 1;
        return;
    }
    info->next_event_defined = 1;
    info->next_event = (k + 1) * m->r[2];
    if (info->next_event > m->r[3]) info->next_event = m->r[3];
}
