/* A unit with droop R and one lag T, driven by a measured frequency deviation:
 *   p' = (p_ref - dw / R - p) / T,   p(0) = p_ref - dw(0) / R  (steady start)
 * dw is an input in pu (positive: frequency above nominal). Output p in pu.
 * Real vrs: 0 p, 1 der(p), 2 R, 3 T, 4 p_ref, 5 dw (input). */
#define MODEL_GUID "{6f0d1e2a-0b3c-4d5e-8f70-9a1b2c3d4e5f}"
#define N_REAL 6
#define N_INT 0
#define N_BOOL 0
#define N_STATES 1
#define N_INDICATORS 0
#define STATE_VRS {0}
#define DER_VRS {1}
#define N_INPUTS 1
#define INPUT_VRS {5}
#include "fmu_template.h"

static void model_start(Model *m) {
    m->r[2] = 0.05;
    m->r[3] = 2.0;
    m->r[4] = 0.6;
}
static void model_initialize(Model *m) { m->r[0] = m->r[4] - m->r[5] / m->r[2]; }
static void model_derivatives(Model *m) { m->r[1] = (m->r[4] - m->r[5] / m->r[2] - m->r[0]) / m->r[3]; }
static void model_indicators(Model *m, double *z) { (void)m; (void)z; }
static void model_event(Model *m, EventInfo *info) { (void)m; (void)info; }
