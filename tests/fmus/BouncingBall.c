/* A ball dropped from h0 onto a floor: h' = v, v' = -g; at h = 0 going down, v := -e v.
 * State event on the event indicator h. Once a bounce leaves less than V_MIN the ball
 * rests on the floor (the bounces would otherwise pile up towards a Zeno point). Real vrs: 0 h, 1 der(h), 2 v, 3 der(v), 4 g, 5 e,
 * 6 h0. Integer vr 0: bounces so far. Boolean vrs: 0 falling, 1 resting. */
#define MODEL_GUID "{8c4e810f-3df3-4a00-8276-176fa3c9f000}"
#define N_REAL 7
#define N_INT 1
#define N_BOOL 2
#define N_STATES 2
#define N_INDICATORS 1
#define STATE_VRS {0, 2}
#define DER_VRS {1, 3}
#define V_MIN 0.1
#include "fmu_template.h"

static void model_start(Model *m) {
    m->r[4] = 9.81;
    m->r[5] = 0.7;
    m->r[6] = 1.0;
}
static void model_initialize(Model *m) {
    m->r[0] = m->r[6];
    m->r[2] = 0.0;
}
static void model_derivatives(Model *m) {
    int resting = m->b[1];
    m->r[1] = resting ? 0.0 : m->r[2];
    m->r[3] = resting ? 0.0 : -m->r[4];
    m->b[0] = m->r[2] < 0;
}
static void model_indicators(Model *m, double *z) { z[0] = m->b[1] ? 1.0 : m->r[0]; }
static void model_event(Model *m, EventInfo *info) {
    if (!m->b[1] && m->r[0] <= 0.0 && m->r[2] < 0.0) {
        m->r[0] = 0.0;
        m->r[2] = -m->r[5] * m->r[2];
        m->i[0] += 1;
        if (m->r[2] < V_MIN) {
            m->r[2] = 0.0;
            m->b[1] = 1;
        }
        info->values_changed = 1;
    }
}
