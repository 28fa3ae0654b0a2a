/* The FMI 3.0 functions rapid-cosim's runners call, looked up in an FMU's binary, and the
 * typed reads of outputs. Shared by runner.c (FMI 3.0 Model Exchange, through an adapter
 * with FMI 2.0's shape) and cosim.c (Co-Simulation), each of which includes it once.
 *
 * Output type codes (mirrored in rapid_cosim/simulator/fmu.py): 0 Float64 (FMI 2.0 Real),
 * 1 Int32 (FMI 2.0 Integer and Enumeration), 2 Boolean, 3 Float32, 4 Int8, 5 UInt8,
 * 6 Int16, 7 UInt16, 8 UInt32, 9 Int64 (FMI 3.0 Enumeration), 10 UInt64; plus RC_ELEMENT
 * for one element of an FMI 3.0 array (its offset and the array's size given beside), so
 * that every path reading Float64 scalars in one call leaves arrays to the typed reads.
 */
#ifndef RC_FMI3_TABLE_H
#define RC_FMI3_TABLE_H

#include <dlfcn.h>
#include <stdio.h>

#include "fmi3FunctionTypes.h"

typedef struct {
    fmi3InstantiateModelExchangeTYPE *instantiate_me;
    fmi3InstantiateCoSimulationTYPE *instantiate_cs;
    fmi3FreeInstanceTYPE *free_instance;
    fmi3EnterInitializationModeTYPE *enter_init;
    fmi3ExitInitializationModeTYPE *exit_init;
    fmi3ResetTYPE *reset;
    fmi3TerminateTYPE *terminate;
    fmi3SetFloat64TYPE *set_float64;
    fmi3GetFloat64TYPE *get_float64;
    fmi3GetFloat32TYPE *get_float32;
    fmi3GetInt8TYPE *get_int8;
    fmi3GetUInt8TYPE *get_uint8;
    fmi3GetInt16TYPE *get_int16;
    fmi3GetUInt16TYPE *get_uint16;
    fmi3GetInt32TYPE *get_int32;
    fmi3GetUInt32TYPE *get_uint32;
    fmi3GetInt64TYPE *get_int64;
    fmi3GetUInt64TYPE *get_uint64;
    fmi3GetBooleanTYPE *get_boolean;
    /* Model Exchange */
    fmi3SetTimeTYPE *set_time;
    fmi3SetContinuousStatesTYPE *set_states;
    fmi3GetContinuousStatesTYPE *get_states;
    fmi3GetContinuousStateDerivativesTYPE *get_derivatives;
    fmi3GetEventIndicatorsTYPE *get_event_indicators;
    fmi3GetNominalsOfContinuousStatesTYPE *get_nominals;
    fmi3EnterEventModeTYPE *enter_event_mode;
    fmi3UpdateDiscreteStatesTYPE *update_discrete;
    fmi3EnterContinuousTimeModeTYPE *enter_continuous;
    fmi3CompletedIntegratorStepTYPE *completed_step;
    /* Co-Simulation */
    fmi3DoStepTYPE *do_step;
} Fmi3;

static void *fmi3_sym(void *lib, const char *name, int required, char *err, int err_len) {
    void *p = dlsym(lib, name);
    if (!p && required && err[0] == 0) snprintf(err, err_len, "symbol %s not found", name);
    return p;
}

/* Fill f from lib: the common functions and those of the interface (me: Model Exchange,
 * else Co-Simulation). Returns 1 with err set if one is missing. */
static int fmi3_load(void *lib, Fmi3 *f, int me, char *err, int err_len) {
#define G(field, name) *(void **)(&f->field) = fmi3_sym(lib, name, 1, err, err_len)
#define I(field, name, required) *(void **)(&f->field) = fmi3_sym(lib, name, required, err, err_len)
    G(free_instance, "fmi3FreeInstance"); G(enter_init, "fmi3EnterInitializationMode");
    G(exit_init, "fmi3ExitInitializationMode"); G(reset, "fmi3Reset"); G(terminate, "fmi3Terminate");
    G(set_float64, "fmi3SetFloat64"); G(get_float64, "fmi3GetFloat64"); G(get_float32, "fmi3GetFloat32");
    G(get_int8, "fmi3GetInt8"); G(get_uint8, "fmi3GetUInt8"); G(get_int16, "fmi3GetInt16");
    G(get_uint16, "fmi3GetUInt16"); G(get_int32, "fmi3GetInt32"); G(get_uint32, "fmi3GetUInt32");
    G(get_int64, "fmi3GetInt64"); G(get_uint64, "fmi3GetUInt64"); G(get_boolean, "fmi3GetBoolean");
    I(instantiate_me, "fmi3InstantiateModelExchange", me);
    I(set_time, "fmi3SetTime", me); I(set_states, "fmi3SetContinuousStates", me);
    I(get_states, "fmi3GetContinuousStates", me); I(get_derivatives, "fmi3GetContinuousStateDerivatives", me);
    I(get_event_indicators, "fmi3GetEventIndicators", me);
    I(get_nominals, "fmi3GetNominalsOfContinuousStates", me); I(enter_event_mode, "fmi3EnterEventMode", me);
    I(update_discrete, "fmi3UpdateDiscreteStates", me); I(enter_continuous, "fmi3EnterContinuousTimeMode", me);
    I(completed_step, "fmi3CompletedIntegratorStep", me);
    I(instantiate_cs, "fmi3InstantiateCoSimulation", !me); I(do_step, "fmi3DoStep", !me);
#undef G
#undef I
    return err[0] != 0;
}

#define RC_ELEMENT 16          /* flag of a type code: one element of an array */
#define RC_MAX_ELEMENTS 1024   /* elements of an array output (fmu.py: MAX_ELEMENTS) */

/* One output of type code `code` (see above) as a double. */
static fmi3Status fmi3_read(const Fmi3 *f, fmi3Instance c, int code, fmi3ValueReference vr, double *out) {
    fmi3Status s;
    switch (code) {
    case 0: return f->get_float64(c, &vr, 1, out, 1);
    case 1: { fmi3Int32 v = 0; s = f->get_int32(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 2: { fmi3Boolean v = 0; s = f->get_boolean(c, &vr, 1, &v, 1); *out = v ? 1.0 : 0.0; return s; }
    case 3: { fmi3Float32 v = 0; s = f->get_float32(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 4: { fmi3Int8 v = 0; s = f->get_int8(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 5: { fmi3UInt8 v = 0; s = f->get_uint8(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 6: { fmi3Int16 v = 0; s = f->get_int16(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 7: { fmi3UInt16 v = 0; s = f->get_uint16(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 8: { fmi3UInt32 v = 0; s = f->get_uint32(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 9: { fmi3Int64 v = 0; s = f->get_int64(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    case 10: { fmi3UInt64 v = 0; s = f->get_uint64(c, &vr, 1, &v, 1); *out = (double)v; return s; }
    default: return fmi3Error;
    }
}

/* Element `offset` of the array output vr of `size` elements (code without RC_ELEMENT). */
static fmi3Status fmi3_read_element(const Fmi3 *f, fmi3Instance c, int code, fmi3ValueReference vr, int offset,
                                    int size, double *out) {
    fmi3UInt64 buf[RC_MAX_ELEMENTS]; /* 8 bytes per element: room for any numeric type */
    fmi3Status s;
    size_t n = (size_t)size;
    if (size < 1 || size > RC_MAX_ELEMENTS || offset < 0 || offset >= size) return fmi3Error;
#define EL(k, T, get) \
    case k: { T *v = (T *)(void *)buf; s = f->get(c, &vr, 1, v, n); *out = (double)v[offset]; return s; }
    switch (code) {
    EL(0, fmi3Float64, get_float64) EL(1, fmi3Int32, get_int32) EL(3, fmi3Float32, get_float32)
    EL(4, fmi3Int8, get_int8) EL(5, fmi3UInt8, get_uint8) EL(6, fmi3Int16, get_int16)
    EL(7, fmi3UInt16, get_uint16) EL(8, fmi3UInt32, get_uint32) EL(9, fmi3Int64, get_int64)
    EL(10, fmi3UInt64, get_uint64)
    case 2: {
        fmi3Boolean *v = (fmi3Boolean *)(void *)buf;
        s = f->get_boolean(c, &vr, 1, v, n);
        *out = v[offset] ? 1.0 : 0.0;
        return s;
    }
    default: return fmi3Error;
    }
#undef EL
}

/* An output of type code `code`: a scalar, or (RC_ELEMENT) the element elem[0] of an array
 * of elem[1] elements. */
static fmi3Status fmi3_read_output(const Fmi3 *f, fmi3Instance c, int code, fmi3ValueReference vr, const int *elem,
                                   double *out) {
    if (code & RC_ELEMENT) {
        if (!elem) return fmi3Error;
        return fmi3_read_element(f, c, code & ~RC_ELEMENT, vr, elem[0], elem[1], out);
    }
    return fmi3_read(f, c, code, vr, out);
}

#endif
