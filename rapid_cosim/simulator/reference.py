"""The Python model-exchange loop: the reference the compiled runner is checked against.

It drives fmpy's ``FMU2Model`` (``FMU3Model`` for FMI 3.0, whose calls differ only in
name and in FMI 3.0's initialisation) with the SUNDIALS 7 build that fmpy ships, calling
the FMU's FMI functions directly (``fmu.dll``, whose ctypes signatures fmpy declared) and
only what each call needs: fmpy's own ``CVodeSolver`` goes through its generic wrappers
(argument logging, status checks in Python) and copies states both ways on every step.
Each right-hand side is still a Python callback and each output sample a Python call,
which is why :mod:`.compiled` exists; this loop stays as the readable statement of what
the runner must do, and runs archives made before the runner existed. fmpy 0.3.32 is
pinned for the binding.

Time events (``nextEventTime``) and input tables (:mod:`.inputs`) are handled; an FMU
with event indicators (state events) is refused, as this loop does no root-finding. A
terminate request ends the run as in the compiled runner: the rows up to it stand
(:class:`Terminated` carries them), unless it came at or after the last output time.
"""

from __future__ import annotations

import contextlib
import ctypes
import signal
import time as time_module
from ctypes import byref, c_double, c_void_p, cast

import numpy as np
from fmpy import instantiate_fmu
from fmpy.fmi2 import fmi2Real, fmi2ValueReference
from fmpy.sundials import (CV_BDF, CV_NORMAL, CVode, CVodeCreate, CVodeFree, CVodeInit, CVodeReInit,
                           CVodeSetLinearSolver, CVodeSetMaxNumSteps, CVodeSetMaxStep, CVodeSVtolerances,
                           CVRhsFn, N_VDestroy_Serial, N_VNew_Serial, NV_DATA_S, SUNContext,
                           SUNContext_Create, SUNContext_PushErrHandler, SUNDenseMatrix, SUNErrHandlerFn,
                           SUNLinSol_Dense, realtype)
from fmpy.sundials.libraries import sundials_core

from ..errors import FmuError, SimulationError, SimulationTimeout
from .fmu import ELEMENT, LoadedFmu, set_parameters
from .inputs import InputTable

# Destructors fmpy's binding does not declare (its own solver leaves them to the OS).
SUNContext_Free = sundials_core.SUNContext_Free
SUNContext_Free.argtypes, SUNContext_Free.restype = [c_void_p], ctypes.c_int
SUNLinSolFree = sundials_core.SUNLinSolFree
SUNLinSolFree.argtypes, SUNLinSolFree.restype = [c_void_p], ctypes.c_int
SUNMatDestroy = sundials_core.SUNMatDestroy
SUNMatDestroy.argtypes, SUNMatDestroy.restype = [c_void_p], None

_FMI_ERROR = 2  # fmi2Error or worse: the model could not evaluate
_GET_REAL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(fmi2ValueReference), ctypes.c_size_t,
                             ctypes.c_void_p)
_GET_FLOAT64 = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(fmi2ValueReference), ctypes.c_size_t,
                                ctypes.c_void_p, ctypes.c_size_t)
# The continuous-state functions, same shape in both versions: (instance, array, size).
_ME_FUNCTIONS = {False: ("fmi2SetTime", "fmi2SetContinuousStates", "fmi2GetContinuousStates", "fmi2GetDerivatives",
                         "fmi2GetNominalsOfContinuousStates"),
                 True: ("fmi3SetTime", "fmi3SetContinuousStates", "fmi3GetContinuousStates",
                        "fmi3GetContinuousStateDerivatives", "fmi3GetNominalsOfContinuousStates")}


class Integrator:
    """BDF integration of one FMU instance's continuous states."""

    def __init__(self, fmu, n_states: int, *, start_time: float, max_step: float, relative_tolerance: float,
                 max_num_steps: int = 5000, fmi3: bool = False):
        self._component = fmu.component
        dll = fmu.dll
        self._set_time, self._set_states, self._get_states, self._get_derivatives, get_nominals = (
            getattr(dll, name) for name in _ME_FUNCTIONS[fmi3])
        self.before_rhs = None  # called with t before each right-hand side (inputs)
        self._raised: BaseException | None = None  # what a right-hand side raised
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
        if n_states:  # once initialised: FMI 3.0 allows it no earlier
            get_nominals(self._component, nominals, n_states)
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
        # ctypes prints and drops an exception raised in a callback (Ctrl-C included): it
        # is kept instead, CVode is stopped (-1: unrecoverable), and advance() raises it.
        try:
            if not self._real_n:
                self._data(ydot)[0] = 0.0
                return 0
            c = self._component
            if self.before_rhs is not None and self.before_rhs(t):
                return 1
            if (self._set_time(c, t) >= _FMI_ERROR
                    or self._set_states(c, self._data(y), self._real_n) >= _FMI_ERROR
                    or self._get_derivatives(c, self._data(ydot), self._real_n) >= _FMI_ERROR):
                return 1  # recoverable: CVode retries with a smaller step
            return 0
        except BaseException as e:
            self._raised = e
            return -1

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
        if self._raised is not None:
            raised, self._raised = self._raised, None
            raise raised
        if flag < 0:
            raise SimulationError(f"CVode failed (flag {flag}) near t={self._t.value:g}: {self._error}")
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


class Terminated(SimulationError):
    """The model asked to terminate before the last output time: ``out`` holds the rows
    up to that moment, NaN after."""

    def __init__(self, message: str, out: np.ndarray):
        super().__init__(message)
        self.out = out


class _TerminateRequest(Exception):
    pass


def _check(flag: int, what: str) -> None:
    if flag != 0:
        raise SimulationError(f"{what} failed with flag {flag}")


def _input_setter(set_real, input_vrs, inputs: InputTable, limit: dict):
    """Sets the inputs at t (returns 0, the right-hand side's "go on")."""
    def set_inputs(t: float) -> int:
        set_real(input_vrs, inputs.at(t, limit["row"]).tolist())
        return 0

    return set_inputs


@contextlib.contextmanager
def _signals_deferred():
    deferred = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, deferred)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)  # a pending signal is delivered here


class ReferenceLoop:
    """One fmpy instance of an FMU and its integrator, re-initialised for every run."""

    def __init__(self, fmu: LoadedFmu, relative_tolerance: float):
        if fmu.n_event_indicators:
            raise FmuError(f"{fmu.name} has {fmu.n_event_indicators} event indicator(s) (state events); the "
                           "Python reference loop handles time events only: use the compiled runner")
        self.fmu = fmu
        self.relative_tolerance = relative_tolerance
        self._instance = instantiate_fmu(str(fmu.dir), fmu.model_description, fmi_type="ModelExchange")
        self._fresh = True
        self._solver: Integrator | None = None
        self._solver_span: tuple[float, float] | None = None

    def run(self, params: dict[str, float], names: list[str], types: list[int], start_time: float,
            times: np.ndarray, inputs: InputTable | None, timeout: float | None) -> np.ndarray:
        """Outputs (times, names) of one run; a failure leaves the loop ready for the next.

        Ctrl-C and SIGTERM wait for the end of the run (milliseconds): raised inside one of
        CVode's Python callbacks, ctypes would print and drop them."""
        with _signals_deferred():
            try:
                return self._integrate(params, names, types, start_time, times, inputs, timeout)
            except BaseException:
                self._recover()
                raise

    def _integrate(self, params, names, types, start_time, times, inputs, timeout) -> np.ndarray:
        fmu, vr = self._instance, self.fmu.value_references
        if not self._fresh:
            fmu.reset()
        self._fresh = False
        v3 = self.fmu.fmi3
        set_real = fmu.setFloat64 if v3 else fmu.setReal
        if not v3:
            fmu.setupExperiment(startTime=start_time)
        set_parameters(fmu, v3, [vr[n] for n in params], list(params.values()), self.fmu.parameter_types(params))
        limit = {"row": -1}
        set_inputs = None if inputs is None else _input_setter(set_real, [vr[n] for n in inputs.names], inputs, limit)
        if set_inputs is not None:
            set_inputs(start_time)
        if v3:  # FMI 3.0 takes the start time here (no tolerance given, as runner.c's adapter)
            fmu.enterInitializationMode(startTime=start_time)
        else:
            fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        component, m = fmu.component, len(names)
        out = (fmi2Real * (times.size * m))()  # filled in place, row by row
        t, k = start_time, 0
        try:
            has_event, t_event = self._update_discrete(fmu)
        except _TerminateRequest:
            return self._stopped(names, types, out, 0, t, times, set_inputs)
        fmu.enterContinuousTimeMode()
        stop_time = float(times[-1])
        max_step = (stop_time - start_time) / 50.0
        if self._solver is None:
            self._solver = Integrator(fmu, self.fmu.n_states, start_time=start_time, max_step=max_step,
                                      relative_tolerance=self.relative_tolerance, fmi3=v3)
        else:  # a joint fit alternates spans: re-initialise the one solver rather than rebuild it
            if self._solver_span != (start_time, stop_time):
                self._solver.set_max_step(max_step)
            self._solver.reset(start_time)
        self._solver_span = (start_time, stop_time)
        solver = self._solver
        solver.before_rhs = set_inputs
        step_row = inputs.next_step(start_time) if inputs is not None else -1
        limit["row"] = step_row
        all_real = not any(types)
        vrs = (fmi2ValueReference * m)(*[vr[n] for n in names])
        row_bytes, base = m * ctypes.sizeof(fmi2Real), ctypes.addressof(out)
        # fmi2GetReal taking the destination as a plain address, to write into ``out`` rows
        if v3:
            get64 = _GET_FLOAT64(ctypes.cast(fmu.dll.fmi3GetFloat64, ctypes.c_void_p).value)
            get_real = lambda c, vrs, n, address: get64(c, vrs, n, address, n)  # noqa: E731
        else:
            get_real = _GET_REAL(ctypes.cast(fmu.dll.fmi2GetReal, ctypes.c_void_p).value)
        reach = (times + 1e-12 * np.maximum(1.0, np.abs(times))).tolist()  # an event this close is "at" t
        deadline = None if timeout is None else time_module.perf_counter() + timeout
        for k, tk in enumerate(times.tolist()):
            while True:  # time events up to tk: the FMU's and the input's steps, earliest first
                ts = float(inputs.time[step_row]) if step_row >= 0 else np.inf
                te = t_event if has_event else np.inf
                nxt = min(te, ts)
                if not nxt <= reach[k]:
                    break
                if nxt > t:
                    t = solver.advance(nxt)
                if ts <= nxt:
                    limit["row"] = step_row = inputs.next_step(ts)  # the step is taken now
                fmu.enterEventMode()
                if set_inputs is not None:
                    set_inputs(t)
                try:
                    has_event, t_event = self._update_discrete(fmu)
                except _TerminateRequest:
                    return self._stopped(names, types, out, k, t, times, set_inputs)
                fmu.enterContinuousTimeMode()
                solver.reset(t)
            if tk > t:
                t = solver.advance(tk)
            if set_inputs is not None:
                set_inputs(t)
            if all_real:
                if get_real(component, vrs, m, base + k * row_bytes) >= _FMI_ERROR:
                    raise SimulationError(f"{self.fmu.name}: evaluating the outputs failed at t={t:g}")
            else:
                out[k * m:(k + 1) * m] = self._read_typed(names, types)
            if deadline is not None and k % 32 == 0 and time_module.perf_counter() > deadline:
                raise SimulationTimeout(f"{self.fmu.name} stopped at t={t:g} of {times[-1]:g} s after the "
                                        f"{timeout} s time-out")
        fmu.terminate()
        return np.frombuffer(out, dtype=float).reshape(times.size, m).copy()

    def _stopped(self, names, types, out, k, t, times, set_inputs) -> np.ndarray:
        """The model asked to terminate at t while working towards row k (runner.c's
        ``terminated``): the rows before k stand, and row k if t is its time."""
        m = len(names)
        values = np.frombuffer(out, dtype=float).reshape(times.size, m).copy()
        rows = k
        if k < times.size and t >= times[k] - 1e-12 * max(1.0, abs(times[k])):
            if set_inputs is not None:
                set_inputs(t)
            values[k] = self._read_typed(names, types)
            rows = k + 1
        self._renew()
        values[rows:] = np.nan
        if rows >= times.size:
            return values
        raise Terminated(f"the model asked to terminate at t={t:g}", values)

    def _read_typed(self, names, types) -> list[float]:
        """Outputs of any type code (fmi3_table.h), an FMI 3.0 array's element included."""
        f, vr = self._instance, self.fmu.value_references
        if not self.fmu.fmi3:
            getters = (f.getReal, f.getInteger, f.getBoolean)
            return [float(getters[kind]([vr[n]])[0]) for n, kind in zip(names, types)]
        getters = (f.getFloat64, f.getInt32, f.getBoolean, f.getFloat32, f.getInt8, f.getUInt8, f.getInt16,
                   f.getUInt16, f.getUInt32, f.getInt64, f.getUInt64)
        offset_size = self.fmu.elements
        return [float(getters[kind & ~ELEMENT]([vr[n]], offset_size[n][1])[offset_size[n][0]]) if kind & ELEMENT
                else float(getters[kind]([vr[n]])[0]) for n, kind in zip(names, types)]

    def _update_discrete(self, fmu) -> tuple[bool, float]:
        update = fmu.updateDiscreteStates if self.fmu.fmi3 else fmu.newDiscreteStates  # same results, in order
        needed, defined, t_next = True, False, 0.0
        while needed:
            needed, terminate, _, _, defined, t_next = update()
            if terminate:
                raise _TerminateRequest()
        return bool(defined), float(t_next)

    def _renew(self) -> None:
        """After a terminate request: a new instance for the next run (the standard's
        Reference FMUs keep terminateSimulation through fmi2Reset), as runner.c does."""
        self._instance.terminate()
        if self._solver is not None:
            self._solver.close()
        self._solver = None  # its callbacks point at the instance freed here
        self._instance.freeInstance()
        self._instance = instantiate_fmu(str(self.fmu.dir), self.fmu.model_description, fmi_type="ModelExchange")
        self._fresh = True

    def _recover(self) -> None:
        """After a failure the instance may be in any state; a reset brings it back."""
        if self._solver is not None:
            self._solver.close()
        self._solver = None  # its callbacks may point at a replaced instance
        try:
            self._instance.reset()
        except Exception:
            self._instance.freeInstance()
            self._instance = instantiate_fmu(str(self.fmu.dir), self.fmu.model_description,
                                             fmi_type="ModelExchange")
        self._fresh = True

    def close(self) -> None:
        if self._solver is not None:
            self._solver.close()
        self._instance.freeInstance()
