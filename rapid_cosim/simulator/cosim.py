"""Co-Simulation FMUs (FMI 2.0 and 3.0): the FMU's own solver, driven from communication
point to communication point.

Many plant models come from their tools as Co-Simulation FMUs, the tool's solver inside.
They run here with the same results as Model Exchange FMUs (:class:`~.simulation.BatchResult`,
statuses, messages, time-outs, failures per set) through one of two drivers:

- :class:`CosimDriver`, the C driver ``cosim.c`` in the runners' library (the default, for
  runners "compiled" and "exponential"): one call per batch, no Python per step;
- :class:`CosimLoop`, the same sequence through fmpy's ``FMU2Slave`` / ``FMU3Slave`` (runner
  "python"): the readable statement of what the driver does, which it is checked against
  bit for bit.

Chosen by measurement (``benchmarks/run.py fmi``, 2 shared cores): on the droop plant twin,
60 s at 601 output samples with a recorded input (some 600 communication steps), the fmpy
loop took 6.2 ms per simulation for the FMI 2.0 Co-Simulation FMU, about 10 microseconds of
Python per step (inputs, ``doStep``, outputs, fmpy's status checks), and 110 ms for the FMI
3.0 one, whose intermediate-update callback runs in Python at every internal step; the C
driver took 0.29 and 0.30 ms per set in batches (0.54 ms one call at a time), nearly all of
it the FMU's own solver.

What is decided before a batch runs (communication points, inputs, the grid's weights) is
:mod:`.communication`'s.

A terminate request ends a set where it happened: the outputs at the points reached stand
(those after are NaN) with status "terminated", unless every output was given.
"""

from __future__ import annotations

import ctypes
import math
import time as time_module
from ctypes import POINTER, c_double, c_int, c_uint, c_void_p

import numpy as np

from ..errors import SimulationError
from . import compiled
from .compiled import FMI, NONFINITE, OK, TERMINATED, TIMEOUT, _address, _ptr
from .communication import left_values, plan_communication
from .fmu import ELEMENT, LoadedFmu, set_parameters
from .inputs import InputTable

INTERPOLATION = {"hold": 0, "derivatives": 1, "intermediate": 2}


# --------------------------------------------------------------------------- the C driver


class _CsBatch(ctypes.Structure):
    _fields_ = [
        ("n_sets", c_int), ("n_params", c_int), ("param_vrs", POINTER(c_uint)), ("param_values", c_void_p),
        ("n_times", c_int), ("times", POINTER(c_double)),
        ("n_out", c_int), ("out_vrs", POINTER(c_uint)), ("out_types", POINTER(c_int)),
        ("n_inputs", c_int), ("input_vrs", POINTER(c_uint)), ("n_rows", c_int),
        ("input_time", POINTER(c_double)), ("input_values", POINTER(c_double)),
        ("n_comm", c_int), ("comm", POINTER(c_double)), ("steps", POINTER(c_double)),
        ("u", POINTER(c_double)), ("du", POINTER(c_double)), ("read", POINTER(c_int)),
        ("out_comm", POINTER(c_int)), ("out_w", POINTER(c_double)),
        ("start_time", c_double), ("stop_time", c_double), ("timeout", c_double), ("tolerance", c_double),
        ("interpolation", c_int), ("out_elem", POINTER(c_int)), ("param_types", POINTER(c_int)),
    ]


class CosimDriver:
    """One instance of a Co-Simulation FMU in ``cosim.c``, for any number of batches."""

    def __init__(self, fmu: LoadedFmu, relative_tolerance: float):
        lib = compiled._library()
        self.fmu, self._lib, self.relative_tolerance = fmu, lib, relative_tolerance
        vr = fmu.value_references
        self._input_vrs = np.array([vr[n] for n in fmu.inputs], dtype=np.uint32)
        err = ctypes.create_string_buffer(1024)
        md = fmu.model_description
        intermediate = fmu.input_interpolation == "intermediate"
        self._handle = lib.cs_open(str(fmu.binary).encode(), md.modelName.encode(), md.guid.encode(),
                                   fmu.resource_location.encode(), 3 if fmu.fmi3 else 2, int(intermediate),
                                   _ptr(self._input_vrs, c_uint), len(self._input_vrs), err, len(err))
        if not self._handle:
            raise SimulationError(f"{fmu.name}: the Co-Simulation driver could not open the FMU: {err.value.decode()}")
        self._msg_len = lib.cs_msg_len()

    def prepare(self, param_names, names, types, start_time, times, inputs, timeout,
                communication_step=None) -> "PreparedCosim":
        return PreparedCosim(self, param_names, names, types, start_time, times, inputs, timeout, communication_step)

    def close(self) -> None:
        if getattr(self, "_handle", None):
            self._lib.cs_close(self._handle)
            self._handle = None

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


class PreparedCosim:
    """A batch whose shape is fixed: the plan made and the C structure filled once."""

    def __init__(self, driver: CosimDriver, param_names, names, types, start_time, times, inputs, timeout,
                 communication_step):
        fmu = driver.fmu
        vr = fmu.value_references
        self.driver = driver
        self.plan = plan = plan_communication(fmu, times, start_time, inputs, communication_step)
        self.n_params, self.n_times, self.n_out = len(param_names), len(times), len(names)
        keep = self._keep = {
            "param_vrs": np.array([vr[p] for p in param_names], dtype=np.uint32),
            "times": np.ascontiguousarray(times, dtype=float),
            "out_vrs": np.array([vr[o] for o in names], dtype=np.uint32),
            "out_types": np.array(types, dtype=np.int32), "plan": plan, "out_elem": fmu.output_elements(names),
        }
        b = self._batch = _CsBatch(
            n_params=self.n_params, param_vrs=_ptr(keep["param_vrs"], c_uint), n_times=self.n_times,
            times=_ptr(keep["times"], c_double), n_out=self.n_out, out_vrs=_ptr(keep["out_vrs"], c_uint),
            out_types=_ptr(keep["out_types"], c_int), n_comm=plan.comm.size, comm=_ptr(plan.comm, c_double),
            steps=_ptr(plan.steps, c_double), u=_ptr(plan.u, c_double), du=_ptr(plan.du, c_double),
            read=_ptr(plan.read, c_int), out_comm=_ptr(plan.out_comm, c_int), out_w=_ptr(plan.out_w, c_double),
            start_time=start_time, stop_time=float(plan.comm[-1]), timeout=timeout or 0.0,
            tolerance=driver.relative_tolerance, interpolation=INTERPOLATION[plan.interpolation])
        if keep["out_elem"] is not None:
            b.out_elem = _ptr(keep["out_elem"], c_int)
        keep["param_types"] = fmu.parameter_types(param_names)
        if keep["param_types"] is not None:
            b.param_types = _ptr(keep["param_types"], c_int)
        if inputs is not None:
            if len(inputs.names) > 64:
                raise SimulationError(f"{fmu.name}: the Co-Simulation driver drives at most 64 inputs")
            input_vrs = np.array([vr[i] for i in inputs.names], dtype=np.uint32)
            keep["input_vrs"], keep["inputs"] = input_vrs, inputs
            b.n_inputs, b.input_vrs, b.n_rows = len(inputs.names), _ptr(input_vrs, c_uint), inputs.time.size
            b.input_time, b.input_values = _ptr(inputs.time, c_double), _ptr(inputs.values, c_double)
        self._messages = None

    def __call__(self, values: np.ndarray):
        driver = self.driver
        if not driver._handle:
            raise SimulationError(f"{driver.fmu.name}: the driver was closed (the FMU was reloaded)")
        values = np.ascontiguousarray(values, dtype=float)
        n = values.shape[0]
        b = self._batch
        b.n_sets, b.param_values = n, _address(values) if values.size else None
        out = np.empty((n, self.n_times, self.n_out))
        status = np.zeros(n, dtype=np.int32)
        reached = np.empty(n)
        size = driver._msg_len
        if self._messages is None or len(self._messages) < size * max(n, 1):
            self._messages = ctypes.create_string_buffer(size * max(n, 1))
        failed = driver._lib.cs_run(driver._handle, ctypes.addressof(b), _address(out) if out.size else None,
                                    _address(status), _address(reached), ctypes.addressof(self._messages))
        if failed == -2:
            raise SimulationError(f"{driver.fmu.name}: the Co-Simulation driver cannot take this batch")
        texts = [""] * n
        if failed:
            raw = self._messages.raw
            texts = [raw[i * size:(i + 1) * size].split(b"\0", 1)[0].decode(errors="replace") for i in range(n)]
        return out, status, texts


# --------------------------------------------------------------------------- the fmpy loop


class _Stop(Exception):
    """A set ends here with a status (not an FMI exception: those are failures)."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


class CosimLoop:
    """The C driver's sequence through fmpy's ``FMU2Slave`` / ``FMU3Slave``: one instance,
    reset per set. Runs archives made with ``runner="python"`` and checks the driver."""

    def __init__(self, fmu: LoadedFmu, relative_tolerance: float):
        self.fmu, self.relative_tolerance = fmu, relative_tolerance
        self._table: InputTable | None = None
        self._elements: np.ndarray | None = None  # the outputs' (offset, size) where one is an array element
        self._input_vrs: list[int] = []
        self._instance = self._instantiate()
        self._fresh = True

    def _instantiate(self):
        from fmpy import instantiate_fmu

        fmu = self.fmu
        kw = {}
        self._callback = None
        if fmu.fmi3 and fmu.input_interpolation == "intermediate":
            self._callback = self._intermediate_update
            kw = dict(intermediate_update=self._callback,
                      required_intermediate_variables=[fmu.value_references[n] for n in fmu.inputs])
        return instantiate_fmu(str(fmu.dir), fmu.model_description, fmi_type="CoSimulation", **kw)

    def _intermediate_update(self, env, t, set_requested, get_allowed, step_finished, can_return_early,
                             early_requested, early_time):
        if early_requested:
            early_requested[0] = False
        if set_requested and self._table is not None and self._interpolation == "intermediate":
            self._instance.setFloat64(self._input_vrs, left_values(self._table, t)[0].tolist())

    def prepare(self, param_names, names, types, start_time, times, inputs, timeout, communication_step=None):
        plan = plan_communication(self.fmu, times, start_time, inputs, communication_step)
        vr = self.fmu.value_references
        params = [vr[p] for p in param_names]
        outs = [vr[o] for o in names]
        elements = self.fmu.output_elements(names)
        input_vrs = [vr[i] for i in inputs.names] if inputs is not None else []

        def call(values):
            values = np.asarray(values, dtype=float)
            n = values.shape[0]
            out = np.full((n, len(times), len(names)), np.nan)
            status = np.zeros(n, dtype=np.int32)
            messages = []
            self._table, self._input_vrs, self._interpolation = inputs, input_vrs, plan.interpolation
            self._elements = elements
            self._param_kinds = self.fmu.parameter_types(param_names)
            try:
                for i, row in enumerate(values):
                    rows = [0]
                    try:
                        self._run(row.tolist(), params, outs, types, input_vrs, plan, start_time, timeout, out[i],
                                  rows)
                        messages.append("")
                    except _Stop as e:
                        status[i] = e.status
                        if e.status == TERMINATED:
                            out[i, rows[0]:] = np.nan
                            self._terminate()
                            if rows[0] >= len(times):
                                status[i] = OK
                                messages.append("")
                                continue
                        else:
                            out[i] = np.nan
                            self._recover()
                        messages.append(str(e))
                    except Exception as e:  # fmpy raises FMICallException or bare Exceptions
                        status[i] = FMI
                        out[i] = np.nan
                        messages.append(str(e))
                        self._recover()
            finally:
                self._table = None
            return out, status, messages

        return call

    def _read(self, outs, types):
        f = self._instance
        if self.fmu.fmi3:
            getters = {0: f.getFloat64, 1: f.getInt32, 2: f.getBoolean, 3: f.getFloat32, 4: f.getInt8, 5: f.getUInt8,
                       6: f.getInt16, 7: f.getUInt16, 8: f.getUInt32, 9: f.getInt64, 10: f.getUInt64}
        else:
            getters = {0: f.getReal, 1: f.getInteger, 2: f.getBoolean}
        if self._elements is None:
            return [float(getters[kind]([vr])[0]) for vr, kind in zip(outs, types)]
        values = []  # an array element (ELEMENT): the whole array read, its element taken
        for (offset, size), vr, kind in zip(self._elements.tolist(), outs, types):
            values.append(float(getters[kind & ~ELEMENT]([vr], size)[offset] if kind & ELEMENT else
                                getters[kind]([vr])[0]))
        return values

    def _run(self, params, param_vrs, outs, types, input_vrs, plan, start_time, timeout, out, rows):
        f, fmu = self._instance, self.fmu
        deadline = None if not timeout else time_module.perf_counter() + timeout
        if not self._fresh:
            f.reset()
        self._fresh = False
        stop_time = float(plan.comm[-1])
        set_inputs = f.setFloat64 if fmu.fmi3 else f.setReal
        if fmu.fmi3:
            set_parameters(f, True, param_vrs, params, None)
            f.enterInitializationMode(tolerance=self.relative_tolerance, startTime=start_time, stopTime=stop_time)
        else:
            f.setupExperiment(tolerance=self.relative_tolerance, startTime=start_time, stopTime=stop_time)
            set_parameters(f, False, param_vrs, params, self._param_kinds)
            f.enterInitializationMode()
        if input_vrs:
            set_inputs(input_vrs, plan.u[0].tolist())
        f.exitInitializationMode()
        cur = prev = None

        def take(j):
            nonlocal cur, prev
            prev, cur = cur, self._read(outs, types)
            for m, v in enumerate(cur):
                if not math.isfinite(v):
                    raise _Stop(NONFINITE, f"output {m} is {v:g} at t={plan.comm[j]:g}")
            k = rows[0]
            while k < plan.out_comm.size and plan.out_comm[k] == j:
                w = plan.out_w[k]
                if w == 1.0:
                    out[k] = cur
                else:
                    out[k] = [p + w * (c - p) if kind & ~ELEMENT in (0, 3) else p
                              for p, c, kind in zip(prev, cur, types)]
                k += 1
            rows[0] = k

        if plan.read[0]:
            take(0)
        derivatives = plan.interpolation == "derivatives" and input_vrs
        for j in range(plan.comm.size - 1):
            t, h = float(plan.comm[j]), float(plan.steps[j])
            if input_vrs:
                set_inputs(input_vrs, plan.u[j].tolist())
            if derivatives:
                f.setRealInputDerivatives(input_vrs, [1] * len(input_vrs), plan.du[j].tolist())
            stopped, last = False, t + h
            if fmu.fmi3:
                _, terminate, early, last_time = f.doStep(t, h)
                if terminate:
                    stopped, last = True, last_time
                elif early:
                    raise _Stop(FMI, f"fmi3DoStep did not complete the step from t={t:g}")
            else:
                from fmpy.fmi2 import fmi2Discard, fmi2LastSuccessfulTime, fmi2Terminated
                from fmpy.fmi1 import FMICallException

                try:
                    f.doStep(t, h)
                except FMICallException as e:
                    if e.status != fmi2Discard or not f.getBooleanStatus(fmi2Terminated):
                        raise
                    stopped, last = True, f.getRealStatus(fmi2LastSuccessfulTime)
            end = float(plan.comm[j + 1])
            if stopped:
                if last >= end - 1e-12 * max(1.0, abs(end)) and plan.read[j + 1]:
                    take(j + 1)
                raise _Stop(TERMINATED, f"the model asked to terminate at t={last:g}")
            if plan.read[j + 1]:
                take(j + 1)
            if deadline is not None and time_module.perf_counter() > deadline:
                raise _Stop(TIMEOUT, f"over its {timeout:g} s wall-clock budget at t={end:g}")
        f.terminate()

    def _terminate(self) -> None:
        """After a terminate request: the next set on a new instance (the standard's
        Reference FMUs keep terminateSimulation through a reset), as the C driver does."""
        try:
            self._instance.terminate()
            self._instance.freeInstance()
        except Exception:
            pass
        self._instance = self._instantiate()
        self._fresh = True

    def _recover(self) -> None:
        try:
            self._instance.reset()
        except Exception:
            try:
                self._instance.freeInstance()
            except Exception:
                pass
            self._instance = self._instantiate()
        self._fresh = True

    def close(self) -> None:
        self._instance.freeInstance()
