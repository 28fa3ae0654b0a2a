"""CVode on a model-exchange FMU, with as little Python per step as possible.

Calibration spends nearly all its time here, in two kinds of calls: the integrator's
right-hand side (set time, set states, get derivatives) and the step to each output
time. fmpy's ``CVodeSolver`` goes through its generic FMI wrappers (argument logging,
status checks in Python) and copies states both ways on every step; measured on the
staged-test benches that is ~25 us per call. This integrator uses the same SUNDIALS 7
binding that fmpy ships and the same FMU instance, but calls the FMU's FMI functions
directly (``fmu.dll``, whose ctypes signatures fmpy declared) and only what each call
needs. fmpy 0.3.32 is pinned for this.
"""

from __future__ import annotations

from ctypes import byref, c_double, c_int, c_void_p, cast

import numpy as np
from fmpy.sundials import (CV_BDF, CV_NORMAL, CVode, CVodeCreate, CVodeFree, CVodeInit, CVodeReInit,
                           CVodeSetLinearSolver, CVodeSetMaxNumSteps, CVodeSetMaxStep, CVodeSVtolerances,
                           CVRhsFn, N_VDestroy_Serial, N_VNew_Serial, NV_DATA_S, SUNContext,
                           SUNContext_Create, SUNContext_PushErrHandler, SUNDenseMatrix, SUNErrHandlerFn,
                           SUNLinSol_Dense, realtype)
from fmpy.sundials.libraries import sundials_core

# Destructors fmpy's binding does not declare (its own solver leaves them to the OS).
SUNContext_Free = sundials_core.SUNContext_Free
SUNContext_Free.argtypes, SUNContext_Free.restype = [c_void_p], c_int
SUNLinSolFree = sundials_core.SUNLinSolFree
SUNLinSolFree.argtypes, SUNLinSolFree.restype = [c_void_p], c_int
SUNMatDestroy = sundials_core.SUNMatDestroy
SUNMatDestroy.argtypes, SUNMatDestroy.restype = [c_void_p], None

_FMI_ERROR = 2  # fmi2Discard or worse: the model could not evaluate


class IntegrationError(RuntimeError):
    """CVode gave up; the message is SUNDIALS' own."""


class Integrator:
    """BDF integration of one FMU instance's continuous states."""

    def __init__(self, fmu, n_states: int, *, start_time: float, max_step: float, relative_tolerance: float,
                 max_num_steps: int = 5000):
        self._component = fmu.component
        dll = fmu.dll
        self._set_time = dll.fmi2SetTime
        self._set_states = dll.fmi2SetContinuousStates
        self._get_states = dll.fmi2GetContinuousStates
        self._get_derivatives = dll.fmi2GetDerivatives
        self._real_n = n_states
        self._n = max(n_states, 1)  # CVode needs one state; a stateless model gets a dummy
        self._error = "no details"
        self._ctx = SUNContext()
        _check(SUNContext_Create(0, byref(self._ctx)), "SUNContext_Create")
        self._x = N_VNew_Serial(self._n, self._ctx)
        self._abstol = N_VNew_Serial(self._n, self._ctx)
        self._px = NV_DATA_S(self._x)
        self._x_array = np.ctypeslib.as_array(self._px, (self._n,))
        tolerance = np.ctypeslib.as_array(NV_DATA_S(self._abstol), (self._n,))
        nominals = (c_double * self._n)(*([1.0] * self._n))
        if n_states:
            dll.fmi2GetNominalsOfContinuousStates(self._component, nominals, n_states)
        tolerance[:] = relative_tolerance * np.abs(np.frombuffer(nominals, dtype=float))
        self._data_of: dict[int, object] = {}
        self._mem = CVodeCreate(CV_BDF, self._ctx)
        self._rhs = CVRhsFn(self._f)  # kept referenced: CVode calls it from C
        self._on_error = SUNErrHandlerFn(self._record_error)
        self.reset(start_time)
        _check(CVodeInit(self._mem, self._rhs, start_time, self._x), "CVodeInit")
        _check(CVodeSVtolerances(self._mem, relative_tolerance, self._abstol), "CVodeSVtolerances")
        self._matrix = SUNDenseMatrix(self._n, self._n, self._ctx)
        self._solver = SUNLinSol_Dense(self._x, self._matrix, self._ctx)
        _check(CVodeSetLinearSolver(self._mem, self._solver, self._matrix), "CVodeSetLinearSolver")
        _check(CVodeSetMaxStep(self._mem, max_step), "CVodeSetMaxStep")
        _check(CVodeSetMaxNumSteps(self._mem, max_num_steps), "CVodeSetMaxNumSteps")
        _check(SUNContext_PushErrHandler(self._ctx, self._on_error, None), "SUNContext_PushErrHandler")
        self._t = realtype(start_time)

    def _data(self, vector) -> object:
        """The double* of an N_Vector, cached per vector (CVode reuses a handful)."""
        key = cast(vector, c_void_p).value
        data = self._data_of.get(key)
        if data is None:
            data = self._data_of[key] = NV_DATA_S(vector)
        return data

    def _f(self, t, y, ydot, user_data) -> int:
        if not self._real_n:
            self._data(ydot)[0] = 0.0
            return 0
        c = self._component
        if (self._set_time(c, t) >= _FMI_ERROR
                or self._set_states(c, self._data(y), self._real_n) >= _FMI_ERROR
                or self._get_derivatives(c, self._data(ydot), self._real_n) >= _FMI_ERROR):
            return 1  # recoverable: CVode retries with a smaller step
        return 0

    def _record_error(self, line, func, file, msg, err_code, err_user_data, ctx) -> None:
        self._error = f"{func.decode()}: {msg.decode()}" if func and msg else str(err_code)

    def reset(self, time: float) -> None:
        """Take the FMU's current states as the new initial value (after an event)."""
        if self._real_n:
            self._get_states(self._component, self._px, self._real_n)
        else:
            self._x_array[:] = 0.0
        if hasattr(self, "_matrix"):
            _check(CVodeReInit(self._mem, time, self._x), "CVodeReInit")

    def set_max_step(self, max_step: float) -> None:
        _check(CVodeSetMaxStep(self._mem, max_step), "CVodeSetMaxStep")

    def advance(self, t_out: float) -> float:
        """Integrate to ``t_out`` and leave the FMU at that time and state."""
        flag = CVode(self._mem, t_out, self._x, byref(self._t), CV_NORMAL)
        if flag < 0:
            raise IntegrationError(f"CVode failed (flag {flag}) near t={self._t.value:g}: {self._error}")
        c = self._component
        if self._real_n:
            self._set_states(c, self._px, self._real_n)
        self._set_time(c, self._t.value)
        return self._t.value

    def close(self) -> None:
        if getattr(self, "_mem", None) is not None:
            CVodeFree(byref(c_void_p(self._mem)))
            self._mem = None
            SUNLinSolFree(self._solver)
            SUNMatDestroy(self._matrix)
            N_VDestroy_Serial(self._x)
            N_VDestroy_Serial(self._abstol)
            SUNContext_Free(byref(self._ctx))  # takes the address of the context handle

    def __del__(self):
        try:
            self.close()
        except Exception:  # interpreter shutdown: the libraries may be gone already
            pass


def _check(flag: int, what: str) -> None:
    if flag != 0:
        raise IntegrationError(f"{what} failed with flag {flag}")


__all__ = ["Integrator", "IntegrationError"]
