"""FMU -> trajectories, on fmpy, with one instance per FMU and process.

fmpy re-extracts an FMU given as a ``.fmu`` path on every call, even with
``fmu_instance``; instantiating costs a library load. A :class:`Simulator` extracts and
instantiates once and ``reset()``s between runs. Instances cannot be pickled, so each
process (each joblib worker) keeps its own, through :func:`get_simulator`: the one piece
of global state in the package.
"""

from __future__ import annotations

import ctypes
import difflib
import hashlib
import math
import os
import shutil
import tempfile
import time as time_module
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from fmpy import extract, instantiate_fmu, read_model_description, simulate_fmu
from fmpy.fmi2 import fmi2Real, fmi2ValueReference

from .errors import ParameterError, SimulationError, SimulationTimeout
from .integrator import Integrator


@dataclass(frozen=True)
class ParameterInfo:
    name: str
    start: float | None
    min: float | None
    max: float | None
    unit: str
    description: str
    settable: bool  # False for calculated parameters


@dataclass(frozen=True)
class Trajectory:
    time: np.ndarray
    outputs: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.outputs[name]


class Simulator:
    """A model exchange FMU ready to run many times with different parameters."""

    def __init__(self, fmu: str | Path, *, timeout: float | None = None, relative_tolerance: float = 1e-6):
        self.path = Path(fmu)
        self.timeout = timeout
        self.relative_tolerance = relative_tolerance
        self.model_description = read_model_description(str(self.path), validate=False)
        self._dir = extract(str(self.path), unzipdir=tempfile.mkdtemp(prefix="rapid_cosim_fmu_"))
        self._finalizer = weakref.finalize(self, shutil.rmtree, self._dir, True)
        self._instance = instantiate_fmu(self._dir, self.model_description, fmi_type="ModelExchange")
        self._fresh = True
        self._solver = None  # CVode memory, created on the first run and re-initialised after
        self._solver_span: tuple[float, float] | None = None
        variables = self.model_description.modelVariables
        self._vr = {v.name: v.valueReference for v in variables}
        self.parameters: dict[str, ParameterInfo] = {
            v.name: ParameterInfo(
                name=v.name,
                start=_float(v.start),
                min=_float(v.min),
                max=_float(v.max),
                unit=v.unit or "",
                description=v.description or "",
                settable=v.causality == "parameter",
            )
            for v in variables
            if v.causality in ("parameter", "calculatedParameter")
        }
        self.outputs: list[str] = [v.name for v in variables if v.causality == "output"]
        self.inputs: list[str] = [v.name for v in variables if v.causality == "input"]
        self.variables: list[str] = [v.name for v in variables]

    @property
    def name(self) -> str:
        return self.model_description.modelName

    def check_parameters(self, values: Mapping[str, float]) -> dict[str, float]:
        """Names known and settable, values finite and inside the declared min/max."""
        checked = {}
        for name, value in values.items():
            info = self.parameters.get(name)
            if info is None:
                close = difflib.get_close_matches(name, self.parameters, n=3)
                hint = f"; did you mean {', '.join(close)}?" if close else ""
                raise ParameterError(f"{self.name} has no parameter {name!r}{hint}")
            if not info.settable:
                raise ParameterError(f"{name} of {self.name} is calculated from other parameters and cannot be set")
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise ParameterError(f"{name} = {value!r} is not a number") from None
            if not math.isfinite(value):
                raise ParameterError(f"{name} = {value} is not finite")
            if (info.min is not None and value < info.min) or (info.max is not None and value > info.max):
                raise ParameterError(
                    f"{name} = {value:g} is outside its declared range [{_fmt(info.min)}, {_fmt(info.max)}]"
                    f" in {self.name}")
            checked[name] = value
        return checked

    def simulate(self, parameters: Mapping[str, float] | None = None, *, stop_time: float | None = None,
                 output_interval: float | None = None, output_times: np.ndarray | None = None,
                 outputs: Sequence[str] | None = None, start_time: float = 0.0,
                 input_time: np.ndarray | None = None, inputs: Mapping[str, np.ndarray] | None = None,
                 check: bool = True) -> Trajectory:
        """Run once from ``start_time``, recording ``outputs`` either on the grid
        start + k * output_interval, continued to the first grid point at or after
        ``stop_time``, or at the given increasing ``output_times`` (for instance, the
        measured samples, so no interpolation stands between model and data).

        Values at a time event are those after it. ``inputs`` are sampled at
        ``input_time`` and interpolated linearly; to make a step, repeat its time with the
        values before and after (fmpy's convention).
        """
        params = self.check_parameters(parameters or {}) if check else dict(parameters or {})
        names = list(outputs) if outputs is not None else self.outputs
        unknown = [n for n in names if n not in self.variables]
        if unknown:
            raise ParameterError(f"{self.name} has no variable(s) {', '.join(unknown)}")
        times = self._output_times(start_time, stop_time, output_interval, output_times)
        signals = self._input_table(input_time, inputs)
        if signals is None:
            return self._run(params, names, start_time, times)
        if output_times is not None:
            raise ParameterError("models with inputs record on a regular grid: give output_interval, not output_times")
        stop_time = float(times[-1])
        output_interval = float(times[1] - times[0]) if times.size > 1 else stop_time - start_time
        if not self._fresh:
            self._instance.reset()
        self._fresh = False
        try:
            result = simulate_fmu(
                self._dir, validate=False, start_time=start_time, stop_time=stop_time, solver="CVode",
                relative_tolerance=self.relative_tolerance, output_interval=output_interval,
                record_events=False, start_values=params, input=signals, output=names,
                timeout=self.timeout, model_description=self.model_description, fmu_instance=self._instance,
            )
        except Exception as e:  # fmpy raises bare Exceptions for FMI errors and CVode failures
            self._recover()
            raise SimulationError(f"{self.name} failed with {_describe(params)}: {e}") from e
        time = np.asarray(result["time"], dtype=float)
        if time.size == 0 or time[-1] < stop_time - 1e-9 * max(1.0, abs(stop_time)):
            self._recover()
            reached = time[-1] if time.size else start_time
            raise SimulationTimeout(
                f"{self.name} stopped at t={reached:g} of {stop_time:g} s after the {self.timeout} s time-out "
                f"with {_describe(params)}")
        return Trajectory(time, {n: np.asarray(result[n], dtype=float) for n in names})

    @staticmethod
    def _output_times(start_time, stop_time, output_interval, output_times) -> np.ndarray:
        if output_times is not None:
            times = np.asarray(output_times, dtype=float)
            if times.ndim != 1 or times.size == 0 or np.any(np.diff(times) <= 0) or times[0] < start_time:
                raise ParameterError("output_times must be increasing and start at or after start_time")
            return times
        if stop_time is None or output_interval is None or not output_interval > 0:
            raise ParameterError("give stop_time and a positive output_interval, or output_times")
        n_points = max(math.ceil((stop_time - start_time) / output_interval - 1e-9), 1)
        return start_time + output_interval * np.arange(n_points + 1)

    def _run(self, params: dict[str, float], names: list[str], start_time: float, times: np.ndarray) -> Trajectory:
        """The model-exchange loop for models without inputs, on fmpy's FMU2Model and its
        SUNDIALS binding (see :mod:`rapid_cosim.integrator`): only what calibration needs
        (parameters, time events, outputs at given times), without fmpy's generic
        per-point recorder and input handling."""
        try:
            values = self._integrate(params, names, start_time, times)
        except SimulationTimeout:
            self._recover()
            raise
        except Exception as e:  # fmpy raises bare Exceptions for FMI errors and CVode failures
            self._recover()
            raise SimulationError(f"{self.name} failed with {_describe(params)}: {e}") from e
        return Trajectory(times, {n: values[:, j] for j, n in enumerate(names)})

    def _integrate(self, params, names, start_time, times) -> np.ndarray:
        fmu = self._instance
        if not self._fresh:
            fmu.reset()
        self._fresh = False
        fmu.setupExperiment(startTime=start_time)
        if params:
            fmu.setReal([self._vr[n] for n in params], list(params.values()))
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        has_event, t_event = self._update_discrete(fmu)
        fmu.enterContinuousTimeMode()
        stop_time = float(times[-1])
        max_step = (stop_time - start_time) / 50.0
        if self._solver is None:
            self._solver = Integrator(fmu, self.model_description.numberOfContinuousStates,
                                      start_time=start_time, max_step=max_step,
                                      relative_tolerance=self.relative_tolerance)
        else:  # a joint fit alternates spans: re-initialise the one solver rather than rebuild it
            if self._solver_span != (start_time, stop_time):
                self._solver.set_max_step(max_step)
            self._solver.reset(start_time)
        self._solver_span = (start_time, stop_time)
        solver = self._solver
        component, m = fmu.component, len(names)
        vrs = (fmi2ValueReference * m)(*[self._vr[n] for n in names])
        out = (fmi2Real * (times.size * m))()  # filled in place, row by row
        row_bytes, base = m * ctypes.sizeof(fmi2Real), ctypes.addressof(out)
        # fmi2GetReal taking the destination as a plain address, to write into ``out`` rows
        get_real = _GET_REAL(ctypes.cast(fmu.dll.fmi2GetReal, ctypes.c_void_p).value)
        reach = (times + 1e-12 * np.maximum(1.0, np.abs(times))).tolist()  # an event this close is "at" t
        deadline = None if self.timeout is None else time_module.perf_counter() + self.timeout
        t = start_time
        for k, tk in enumerate(times.tolist()):
            while has_event and t_event <= reach[k]:
                if t_event > t:
                    t = solver.advance(t_event)
                fmu.enterEventMode()
                has_event, t_event = self._update_discrete(fmu)
                fmu.enterContinuousTimeMode()
                solver.reset(t)
            if tk > t:
                t = solver.advance(tk)
            if get_real(component, vrs, m, base + k * row_bytes) >= 2:
                raise SimulationError(f"{self.name}: evaluating the outputs failed at t={t:g}")
            if deadline is not None and k % 32 == 0 and time_module.perf_counter() > deadline:
                raise SimulationTimeout(
                    f"{self.name} stopped at t={t:g} of {times[-1]:g} s after the {self.timeout} s time-out "
                    f"with {_describe(params)}")
        fmu.terminate()
        return np.frombuffer(out, dtype=float).reshape(times.size, m).copy()

    @staticmethod
    def _update_discrete(fmu) -> tuple[bool, float]:
        needed, defined, t_next = True, False, 0.0
        while needed:
            needed, terminate, _, _, defined, t_next = fmu.newDiscreteStates()
            if terminate:
                raise SimulationError("the model asked to terminate")
        return bool(defined), float(t_next)

    def _input_table(self, input_time, inputs):
        if not inputs:
            if self.inputs:
                # fmpy would silently hold the start values; say so instead.
                raise ParameterError(f"{self.name} has inputs {', '.join(self.inputs)}; give them values")
            return None
        missing = [n for n in self.inputs if n not in inputs]
        extra = [n for n in inputs if n not in self.inputs]
        if missing or extra:
            raise ParameterError(f"{self.name} inputs are {self.inputs}; missing {missing}, unknown {extra}")
        t = np.asarray(input_time, dtype=float)
        table = np.zeros(t.size, dtype=[("time", float)] + [(n, float) for n in self.inputs])
        table["time"] = t
        for n in self.inputs:
            table[n] = np.asarray(inputs[n], dtype=float)
        return table

    def _recover(self) -> None:
        """After a failure the instance may be in any state; a reset brings it back."""
        if self._solver is not None:
            self._solver.close()
        self._solver = None  # its callbacks may point at a replaced instance
        try:
            self._instance.reset()
        except Exception:
            self._instance.freeInstance()
            self._instance = instantiate_fmu(self._dir, self.model_description, fmi_type="ModelExchange")
        self._fresh = True

    def close(self) -> None:
        try:
            self._instance.freeInstance()
        finally:
            self._finalizer()


_GET_REAL = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.POINTER(fmi2ValueReference), ctypes.c_size_t,
                             ctypes.c_void_p)


def _float(value) -> float | None:
    try:
        return None if value is None else float(value)
    except (TypeError, ValueError):
        return None


def _fmt(value: float | None) -> str:
    return "-inf" if value is None else f"{value:g}"


def _describe(params: Mapping[str, float]) -> str:
    return ", ".join(f"{k}={v:.6g}" for k, v in params.items()) or "default parameters"


@dataclass(frozen=True)
class FmuRef:
    """An FMU that can travel to other processes or machines: its bytes and their hash.

    Workers of a dask cluster need not share a file system with the caller; and an
    evaluation is pinned to the FMU's content, the same content an archive keeps.
    """

    name: str
    sha256: str
    content: bytes = field(repr=False)

    @classmethod
    def from_path(cls, path: str | Path, name: str | None = None) -> "FmuRef":
        data = Path(path).read_bytes()
        return cls(name or Path(path).stem, hashlib.sha256(data).hexdigest(), data)


# The package's only global state: per process, the simulators of the FMUs it has loaded.
_CACHE: dict[tuple, Simulator] = {}
_REF_FILES: dict[str, Path] = {}


def _materialise(ref: FmuRef) -> Path:
    path = _REF_FILES.get(ref.sha256)
    if path is None or not path.exists():
        folder = Path(tempfile.gettempdir()) / f"rapid_cosim_fmus_{os.getpid()}"
        folder.mkdir(exist_ok=True)
        path = folder / f"{ref.sha256[:16]}.fmu"
        path.write_bytes(ref.content)
        _REF_FILES[ref.sha256] = path
    return path


def get_simulator(fmu: str | Path | FmuRef, *, timeout: float | None = None) -> Simulator:
    """The process's simulator for ``fmu``: loaded once, again only if the file changed."""
    if isinstance(fmu, FmuRef):
        key: tuple = ("sha256", fmu.sha256)
        path = None
    else:
        path = Path(fmu).resolve()
        stat = path.stat()
        key = (str(path), stat.st_mtime_ns, stat.st_size)
    sim = _CACHE.get(key)
    if sim is None:
        for old in [k for k in _CACHE if k[0] == key[0] and k[0] != "sha256"]:
            _CACHE.pop(old).close()
        sim = _CACHE[key] = Simulator(path if path is not None else _materialise(fmu), timeout=timeout)
    sim.timeout = timeout
    return sim
